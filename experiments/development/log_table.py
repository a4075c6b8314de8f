"""The development log: one table of every round, from the committed development runs.

Reads every study in ``figures/development/*.json`` (what ``experiments.development.screen --json``,
``experiments.development.devset --json`` and ``experiments.development.expert_choice --json`` wrote:
the configurations, the seeds, each variant's paired differences from its baseline per half with
their standard errors, and the rule's verdict at those seeds) and joins it with the titles of the
round files in ``docs/research/rounds/``. One row per study (a variant judged at one seed set);
a round with no committed JSON (rounds 1-16, the probes) gets one row with its verdict only.

Files that hold a level and no study (``default_*``, ``devset_*``: a default measured beside the
peers; ``split_peer_overlaps.json``; a screen without variants) are left out.

``python -m experiments.development.log_table [--out docs/research/log.md]``; without ``--out``
the table goes to standard output. The output depends on nothing but the committed files, so
``tests/test_docs_links.py`` holds it equal to
``docs/research/log.md``.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUNS = ROOT / "figures" / "development"
ROUNDS = ROOT / "docs" / "research" / "rounds"
OUT = ROOT / "docs" / "research" / "log.md"

#: Study files whose name carries no round number: the round file that cites each.
ROUND_OF_FILE = {
    "screen_backward_elimination": 17,
    "screen_leave_one_out": 17,
    "screen_rescreens": 17,
    "screen_scale_prior": 17,
    "check_negatives100_seeds80-84": 31,
    "expert_choice_third_lineage_seeds0-4": 68,
}

#: The variants each round adopted into the default (the round files' verdicts; the changelog
#: docs/research/changelog.md lists the same changes). Every other variant was not adopted.
ADOPTED = {
    (17, "generative_term_under_paper_schedule"),
    (20, "floor4"),
    (31, "negatives100"),
    (36, "brightness"),
    (51, "weak_near10_recognised"),
    (64, "learner2"),
    (76, "experts that agree report their blend (offline, exact)"),
    (77, "the size last recognised while neither expert recognises (offline, exact)"),
    (80, "gradient partner, by error (offline, exact)"),
    (81, "gradient partner, by error (offline, exact)"),
}

#: Rounds with a round file and no committed JSON: their verdict, from the round files
#: (rounds 1-16 were screened on the 12 first targets before runs were saved as JSON).
VERDICT_WITHOUT_JSON = {
    1: "adopted", 2: "adopted", 3: "adopted", 4: "not adopted", 5: "not adopted", 6: "adopted",
    7: "not adopted", 8: "not adopted", 9: "adopted", 10: "not adopted", 11: "not adopted",
    12: "not adopted", 13: "not adopted", 14: "adopted", 15: "not adopted", 16: "not adopted",
    58: "probe", 78: "probe", 79: "probe",
}

#: Rounds that share a file with another (rounds 1-3; 41 with 40; 58 with 57).
SHARED_FILE = {1: "choosing-the-defaults.md", 2: "choosing-the-defaults.md", 3: "choosing-the-defaults.md",
               41: "round-40-recognised-finds.md", 58: "round-57-unopposed-update-waits-after-an-occlusion.md"}


def round_files() -> dict[int, Path]:
    files = {}
    for path in sorted(ROUNDS.glob("round-*.md")):
        files[int(path.name.split("-")[1])] = path
    for number, name in SHARED_FILE.items():
        files[number] = ROUNDS / name
    return files


def title(path: Path) -> str:
    """The round file's first heading without its 'Round N:' prefix and its session stamp."""
    first = path.read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip()
    first = re.sub(r"^Rounds? [0-9]+( and [0-9]+)?:\s*", "", first)
    first = re.sub(r"\s*\([^()]*(session|[0-9]{4}-[0-9]{2}-[0-9]{2})[^()]*\)$", "", first)
    return first[:1].upper() + first[1:]


def seeds_text(seeds: list[int]) -> str:
    """[0, 1, 2, 5, 6] -> '0-2, 5-6'."""
    parts, start, last = [], None, None
    for seed in sorted(seeds):
        if start is None:
            start = last = seed
        elif seed == last + 1:
            last = seed
        else:
            parts.append(f"{start}-{last}" if last > start else f"{start}")
            start = last = seed
    if start is not None:
        parts.append(f"{start}-{last}" if last > start else f"{start}")
    return ", ".join(parts)


def gain(differences: dict, group: str) -> str:
    entry = differences.get(group)
    if not isinstance(entry, dict) or "mean" not in entry:
        return ""
    if entry.get("standard_error") is None:  # one seed: no error
        return f"{entry['mean']:+.4f}"
    return f"{entry['mean']:+.4f} ± {entry['standard_error']:.4f}"


def studies(path: Path):
    """(name, seeds, differences, rule verdict or None) of every study in one JSON file."""
    data = json.loads(path.read_text(encoding="utf-8"))

    def of_screen(screen: dict):
        for variant in screen.get("variants", []):
            rule = variant.get("adopted")
            yield variant["name"], screen["seeds"], variant["differences"], rule

    if "screens" in data:
        for screen in data["screens"]:
            yield from of_screen(screen)
    elif "judged" in data:
        yield from of_screen(data["judged"])
        for label in sorted(data["confirmations"]):
            yield from of_screen(data["confirmations"][label])
    elif "variants" in data:
        yield from of_screen(data)
    elif "verdict" in data and "differences" in data:  # a pooled judgement
        yield "pooled", data["seeds"], data["differences"], bool(data["verdict"][0])
    elif "rule" in data and "groups" in data:  # an offline study (round 70)
        yield data["rule"], data["seeds"], data["groups"], None
    elif "config" in data and data.get("differences"):  # experiments.development.devset with a baseline
        verdict = data.get("adopted") or {}
        yield "check", data["seeds"], data["differences"], verdict.get("adopted")


def round_of(stem: str) -> int | None:
    if stem in ROUND_OF_FILE:
        return ROUND_OF_FILE[stem]
    match = re.search(r"round([0-9]+)", stem)
    return int(match.group(1)) if match else None


def rows() -> list[tuple]:
    found = []
    for path in sorted(RUNS.glob("*.json")):
        if path.stem.startswith(("default_", "devset_", "split_")):
            continue
        number = round_of(path.stem)
        if number is None:
            continue
        for index, (name, seeds, differences, rule) in enumerate(studies(path)):
            verdict = "adopted" if (number, name) in ADOPTED else "not adopted"
            found.append((number, min(seeds), len(seeds), path.name, index, name, seeds, differences, rule, verdict))
    found.sort(key=lambda row: row[:5])
    return found


def table() -> str:
    files = round_files()
    by_round: dict[int, list[tuple]] = {}
    for row in rows():
        by_round.setdefault(row[0], []).append(row)
    for number in VERDICT_WITHOUT_JSON:
        by_round.setdefault(number, [])
    lines = [
        "# The development log",
        "",
        "Generated by `python -m experiments.development.log_table --out docs/research/log.md` from the",
        "committed runs in [`figures/development/`](../../figures/development/) and the titles of the",
        "[round files](rounds/); do not edit it by hand (`tests/test_docs_links.py` checks it equals the",
        "script's output). One row per study: a variant judged against its baseline at one seed set.",
        "The gains are paired differences of mean overlap (variant minus baseline) ± their standard",
        "error over the seeds, on the choosing half A, the confirming half B and the synthetic suite",
        "([protocol](protocol.md)); a leave-one-out row (`loo_...`) is the default without one",
        "extension, so a negative gain there means the extension holds. *rule* is the rule of the",
        "time at those seeds (passes / fails; blank where the file holds none); *verdict* is what the",
        "round decided for the default. Rounds 1-16 screened the 12 first targets before runs were",
        "kept as JSON, and the probes judged no row: their gains are in the round files.",
        "",
        "| round | title | study | seeds | A gain | B gain | synthetic | rule | verdict | file |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for number in sorted(by_round):
        path = files.get(number)
        link = f"[{title(path)}](rounds/{path.name})" if path else ""
        studies_of_round = by_round[number]
        if not studies_of_round:
            lines.append(f"| {number} | {link} | | | | | | | {VERDICT_WITHOUT_JSON.get(number, '')} | |")
            continue
        for position, row in enumerate(studies_of_round):
            _, _, _, file_name, _, name, seeds, differences, rule, verdict = row
            rule_text = "" if rule is None else ("passes" if rule else "fails")
            head = f"| {number} | {link} " if position == 0 else "| | "
            lines.append(
                f"{head}| {name} | {seeds_text(seeds)} | {gain(differences, 'A')} | {gain(differences, 'B')} "
                f"| {gain(differences, 'synthetic suite')} | {rule_text} | {verdict} | `{file_name}` |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the table here (default: standard output)")
    args = parser.parse_args(argv)
    text = table()
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
