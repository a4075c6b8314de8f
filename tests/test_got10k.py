"""NRMLC in the real got10k toolkit (``got10k`` on PyPI, with ``six``): its ``Tracker.track``
loop (PIL RGB frames) and its ``ExperimentOTB`` run and report on a tiny local OTB root.

``ExperimentOTB`` always constructs ``OTB(root, version, download=True)``, which downloads
every sequence of the version whose folder is missing. The tiny root therefore holds an
empty folder for each of the other sequence names of OTB-2013: got10k then sees a complete
download and lists only the folders that have a ``groundtruth*.txt``. Its download function
is replaced by one that fails the test, so nothing is ever fetched.
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")  # got10k's report() draws with pyplot

from got10k.datasets import OTB  # noqa: E402
from got10k.experiments import ExperimentOTB  # noqa: E402
from got10k.trackers import Tracker  # noqa: E402
from PIL import Image  # noqa: E402

from nrmlc.cli import main  # noqa: E402
from nrmlc.workbench.score import compare  # noqa: E402
from nrmlc.data import synthetic_suite  # noqa: E402
from nrmlc.io import write_boxes  # noqa: E402
from nrmlc.workbench.metrics import overlaps  # noqa: E402
from nrmlc.workbench.toolkits import LineageGot10k, NRMLCGot10k  # noqa: E402
from nrmlc.tracker.experts import make_tracker  # noqa: E402

FAST = dict(n_particles=50, n_positive=10, n_negative=20, max_positive=20)
FAST_CLI = [item for name, value in FAST.items() for item in ("--param", f"{name}={value}")]
N_FRAMES = 10
#: Two OTB-2013 names for the synthetic sequences (got10k lists only its version's names).
NAMES = ("Car4", "Deer")


@pytest.fixture(scope="module")
def otb_root(tmp_path_factory) -> Path:
    """An OTB-2013 root: two synthetic sequences (img/%04d.jpg + groundtruth_rect.txt), empty folders for the rest."""
    root = tmp_path_factory.mktemp("OTB")
    for name in OTB._OTB__otb13_seqs:  # got10k's own list for version 2013
        (root / name).mkdir()
    suite = synthetic_suite(n_frames=N_FRAMES, size=(72, 96), n_sequences=len(NAMES), seed=1)
    for name, sequence in zip(NAMES, suite):
        (root / name / "img").mkdir()
        for index in range(len(sequence)):
            cv2.imwrite(str(root / name / "img" / f"{index + 1:04d}.jpg"), sequence.color_frame(index),
                        [cv2.IMWRITE_JPEG_QUALITY, 95])
        write_boxes(root / name / "groundtruth_rect.txt", sequence.groundtruth)
    return root


@pytest.fixture(autouse=True)
def no_download(monkeypatch):
    import got10k.datasets.otb as otb_module

    def refuse(url, filename):
        raise AssertionError(f"got10k tried to download {url}")

    monkeypatch.setattr(otb_module, "download", refuse)


def _files_and_truth(root: Path, name: str):
    files = sorted(str(p) for p in (root / name / "img").glob("*.jpg"))
    truth = np.loadtxt(root / name / "groundtruth_rect.txt", delimiter=",")
    return files, truth


def test_adapter_is_a_got10k_tracker():
    tracker = NRMLCGot10k(seed=3, name="Mine", **FAST)
    assert isinstance(tracker, Tracker)
    assert tracker.name == "Mine" and tracker.is_deterministic
    assert tracker.tracker.seed == 3 and tracker.tracker.params.n_particles == 50


def test_got10k_track_loop_with_pil_frames(otb_root):
    """got10k's own loop: PIL RGB images in, boxes out; it follows the target and is deterministic."""
    files, truth = _files_and_truth(otb_root, NAMES[0])
    boxes, times = NRMLCGot10k(seed=0, **FAST).track(files, truth[0])
    assert boxes.shape == (N_FRAMES, 4) and np.isfinite(boxes).all()
    np.testing.assert_array_equal(boxes[0], truth[0])
    assert (times[1:] > 0).all()
    assert overlaps(boxes, truth)[1:].mean() > 0.63, boxes  # measured 0.74: a loss of 0.1 fails
    again, _ = NRMLCGot10k(seed=0, **FAST).track(files, truth[0])
    np.testing.assert_array_equal(again, boxes)
    # The same as feeding make_tracker's tracker the gray image PIL makes of each RGB frame.
    tracker = make_tracker(seed=0, **FAST)
    gray = [np.asarray(Image.open(f).convert("RGB").convert("L")) for f in files]
    tracker.init(gray[0], truth[0])
    manual = np.array([truth[0]] + [tracker.update(g) for g in gray[1:]])
    np.testing.assert_array_equal(manual, boxes)


def test_a_lineage_tracker_runs_in_got10k_as_track_runs_it(otb_root):
    """got10k's loop with a lineage tracker: RGB in, the boxes of the tracker fed the same frames in
    BGR order, and each init starts again from the seed."""
    from nrmlc.errors import ParameterError
    from nrmlc.lineage.ivt import IVTTracker

    files, truth = _files_and_truth(otb_root, NAMES[0])
    adapter = LineageGot10k("IVT", seed=2)
    assert isinstance(adapter, Tracker) and adapter.name == "IVT"
    boxes, _ = adapter.track(files, truth[0])
    again, _ = adapter.track(files, truth[0])  # the same object, a second sequence run
    np.testing.assert_array_equal(again, boxes)
    tracker = IVTTracker(seed=2)
    bgr = [np.asarray(Image.open(f).convert("RGB"))[:, :, ::-1].copy() for f in files]
    tracker.init(bgr[0], truth[0])
    np.testing.assert_array_equal(boxes, np.array([truth[0]] + [tracker.update(b) for b in bgr[1:]]))
    # The synthetic frames are gray: the reordering itself, on a coloured pixel and a PIL image.
    from nrmlc.workbench.toolkits import _bgr

    rgb = np.array([[[10, 20, 30], [40, 50, 60]]], dtype=np.uint8)
    np.testing.assert_array_equal(_bgr(rgb), rgb[:, :, ::-1])
    np.testing.assert_array_equal(_bgr(Image.fromarray(rgb)), rgb[:, :, ::-1])
    np.testing.assert_array_equal(_bgr(rgb[:, :, 0]), rgb[:, :, 0])
    np.testing.assert_array_equal(boxes[0], truth[0])
    assert overlaps(boxes, truth)[1:4].mean() > 0.6  # IVT follows its first frames (0.72-0.85 here)
    with pytest.raises(ParameterError, match="'kcf' is not a lineage tracker"):
        LineageGot10k("kcf")


def test_experiment_otb_runs_offline_and_agrees_with_nrmlc_evaluate(otb_root, tmp_path, capsys):
    results, reports = tmp_path / "results", tmp_path / "reports"
    experiment = ExperimentOTB(str(otb_root), version=2013, result_dir=str(results), report_dir=str(reports))
    assert list(experiment.dataset.seq_names) == sorted(NAMES)
    experiment.run(NRMLCGot10k(seed=0, **FAST))
    folder = results / "OTB2013" / "NRMLC"
    assert sorted(p.name for p in folder.glob("*.txt")) == [f"{n}.txt" for n in sorted(NAMES)]
    performance = experiment.report(["NRMLC"])["NRMLC"]
    assert (reports / "OTB2013" / "NRMLC" / "success_plots.png").is_file()

    # got10k's scores are OTB's (frame 1 included); nrmlc's evaluate gives the same on its result folder.
    comparison = compare([folder], otb_root, skip_first=False)
    ours = comparison.trackers[0]
    for name in NAMES:
        theirs = performance["seq_wise"][name]
        assert ours.evaluations[name].success_auc == pytest.approx(theirs["success_score"], abs=1e-9)
        assert ours.evaluations[name].precision_20 == pytest.approx(theirs["precision_score"], abs=1e-9)
    assert ours.summary()["success_auc"] == pytest.approx(performance["overall"]["success_score"], abs=1e-9)
    assert ours.summary()["success_auc"] > 0.6  # it tracked (measured 0.70: a loss of 0.1 fails)

    # A second run finds the results and skips every sequence (got10k's own resume).
    capsys.readouterr()
    experiment.run(NRMLCGot10k(seed=0, **FAST))
    assert capsys.readouterr().out.count("Found results, skipping") == len(NAMES)


def test_benchmark_folder_is_what_got10k_reports_read(otb_root, tmp_path, capsys):
    """``nrmlc benchmark --out <result_dir>/OTB2013/<name>`` is a tracker got10k's report() can score."""
    results = tmp_path / "results"
    out = results / "OTB2013" / "NRMLC-bench"
    code = main(["benchmark", str(otb_root), "--out", str(out), "--cache", str(tmp_path / "cache"), "--jobs", "1",
                 *FAST_CLI])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    experiment = ExperimentOTB(str(otb_root), version=2013, result_dir=str(results), report_dir=str(tmp_path / "r"))
    performance = experiment.report(["NRMLC-bench"])["NRMLC-bench"]
    for name in NAMES:
        # got10k scores frame 1 too (overlap 1 there): convert our frame-1-excluded AUC to its convention.
        auc = summary["per_sequence"][name]["success_auc"]
        n = N_FRAMES - 1
        thresholds = np.linspace(0, 1, 21)
        with_first = (auc * 21 * n + np.count_nonzero(1.0 > thresholds)) / (21 * (n + 1))
        assert performance["seq_wise"][name]["success_score"] == pytest.approx(with_first, abs=1e-9)
