"""``figures/REPORT.md``: every experiment's section, with a header saying what was run.

:func:`write_report` takes the dicts the scripts' ``main`` return
(``title``, ``figures``, ``markdown``) and writes one markdown file, atomically,
beside the figures (so the image links are relative file names).
"""
from __future__ import annotations

import datetime
import platform

from experiments.grid import params_differences
from experiments.sequence_sets import paper_name
from nrmlc import io
from nrmlc.workbench.version import code_version

REPORT_NAME = "REPORT.md"


def package_versions() -> dict:
    """Versions of Python and of the packages that can change a number in the report."""
    import cv2
    import matplotlib
    import numba
    import numpy
    import scipy

    return {"Python": platform.python_version(), "numpy": numpy.__version__, "numba": numba.__version__,
            "OpenCV": cv2.__version__, "SciPy": scipy.__version__, "matplotlib": matplotlib.__version__}


def header(context, seconds: float | None = None, grid: dict | None = None) -> str:
    """The report's opening: data, sequences, seeds, parameters, code version, date."""
    sequences = context.sequences()
    listed = ", ".join(
        f"{s.name}{'' if paper_name(s.name) in (None, s.name) else ' (' + paper_name(s.name) + ')'}"
        f" [{context.n_frames(s)}{'' if context.n_frames(s) == len(s) else '/' + str(len(s))}]" for s in sequences)
    paper_given = [s.name for s in sequences if paper_name(s.name) is not None]
    changed = params_differences(context.base_params)
    lines = [
        "# NRMLC: experiments report",
        "",
        f"- Data: {context.data_label}",
        f"- Sequences ({len(sequences)}, [frames tracked]): {listed}",
        f"- Of the paper's 12 sequences given: {', '.join(paper_given) if paper_given else 'none'}",
        f"- Seeds: Tables I/II and Fig. 3 {list(context.seeds)}; λ sweep and per-sequence motion "
        f"{list(context.sweep_seeds)}; ablations and re-centring {list(context.ablation_seeds)}",
        f"- Frame cap: {context.max_frames if context.max_frames else 'none (every frame)'}",
        f"- Tracker parameters: the 'default' preset{'' if not changed else ' except ' + str(changed)} "
        f"(Tables I/II, Figs. 3/4, ablations); the 'paper' preset for the checks of the paper's own claims "
        f"(Theorem 1, Figs. 1/2, statistics, occlusion)",
        f"- Code version (hash of the sources that decide the boxes): `{code_version()}`; packages: "
        + ", ".join(f"{name} {version}" for name, version in package_versions().items()),
        f"- Date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}; {platform.machine()}",
    ]
    if grid:
        lines.append(f"- Grid: {grid.get('runs', 0)} NRMLC runs, {grid.get('frames', 0)} frames "
                     f"({grid.get('missing_frames', 0)} computed in this invocation)"
                     + (f"; {grid['peer_runs']} live peer runs (OpenCV, the lineage)" if grid.get("peer_runs") else ""))
    if seconds is not None:
        lines.append(f"- Wall time of this invocation: {seconds / 60:.1f} min")
    return "\n".join(lines)


def write_report(context, sections: list[dict], notes: list[str] | None = None, seconds: float | None = None,
                 grid: dict | None = None):
    """Write ``<figures>/REPORT.md``.

    Parameters
    ----------
    context : experiments.grid.Context
    sections : list of dict
        Each with ``title``, ``figures`` (PNG names in the figures folder) and ``markdown``.
    notes : list of str, optional
        Skipped or failed scripts, and the like (listed under the header).
    seconds : float, optional
        Wall time, for the header.
    grid : dict, optional
        Run counts for the header (``runs``, ``frames``, ``missing_frames``, ``peer_runs``).

    Returns
    -------
    Path of the report.
    """
    parts = [header(context, seconds, grid)]
    if notes:
        parts.append("\n".join(["## Notes", ""] + [f"- {note}" for note in notes]))
    contents = ["## Contents", ""] + [f"{i}. {s['title']}" for i, s in enumerate(sections, 1)]
    parts.append("\n".join(contents))
    for section in sections:
        body = [f"## {section['title']}", ""]
        for figure in section.get("figures", []):
            body += [f"![{section['title']}]({figure})", ""]
        body.append(section.get("markdown", "").rstrip())
        parts.append("\n".join(body))
    path = context.output(REPORT_NAME.rsplit(".", 1)[0], ".md")
    io.write_text(path, "\n\n".join(parts) + "\n")
    return path
