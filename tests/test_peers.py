"""experiments.peers: the live OpenCV trackers."""
import numpy as np
import pytest

from experiments.peers import LiveSpec, _run_live_here, live_trackers, run_live
from nrmlc.data import synthetic_suite


def test_a_live_run_gives_the_same_boxes_whatever_ran_before_it():
    sequence = synthetic_suite(n_frames=30, n_sequences=1)[0]
    spec = LiveSpec(sequence, "MIL", None)
    first = run_live(spec)["boxes"]
    _run_live_here(spec)  # leaves OpenCV's MIL state behind in this process
    again = run_live(spec)["boxes"]
    np.testing.assert_array_equal(first, again)
    assert np.isfinite(first).all() and first.shape == (30, 4)


def test_kcf_moves_to_its_peak_on_every_frame_as_published():
    """OpenCV's default KCF reports a failure (and stops) on most frames of a synthetic scene
    with OpenCV 5.0.0; with LIVE_PARAMETERS' threshold 0 it reports none."""
    if "KCF" not in live_trackers():
        pytest.skip("KCF needs opencv-contrib-python-headless")
    sequence = synthetic_suite(n_frames=30, n_sequences=1)[0]
    boxes = _run_live_here(LiveSpec(sequence, "KCF", None))["boxes"]
    assert np.isfinite(boxes).all() and boxes.shape == (30, 4)


def test_the_ipp_code_path_is_in_the_key(monkeypatch):
    """CSRT's boxes follow IPP's CPU dispatch, so runs made on another IPP path are not reused."""
    from experiments import peers

    spec = LiveSpec(synthetic_suite(n_frames=5, n_sequences=1)[0], "CSRT", None)
    monkeypatch.setattr(peers, "opencv_ipp", lambda: "ippIP AVX2 (l9)")
    avx2 = spec.key("v")
    monkeypatch.setattr(peers, "opencv_ipp", lambda: "ippIP AVX-512F/CD/BW/DQ/VL (k0)")
    assert spec.key("v") != avx2


def test_opencv_ipp_avx2_holds_ipp_at_its_avx2_path():
    """What ``make figures PORTABLE=1`` sets: IPP's AVX2 path on any CPU with AVX2."""
    import os
    import subprocess
    import sys

    code = "from experiments.peers import opencv_ipp; print(opencv_ipp())"
    plain = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    if plain.strip() == "off":
        pytest.skip("this OpenCV has no IPP")
    held = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env={**os.environ, "OPENCV_IPP": "avx2"}).stdout
    assert "AVX2 (l9)" in held


def test_each_lineage_tracker_runs_its_seeds_and_mtt_only_its_first():
    from types import SimpleNamespace

    from experiments import peers

    context = SimpleNamespace(seeds=[3, 4, 5], max_frames=5)
    sequence = synthetic_suite(n_frames=6, n_sequences=1)[0]
    assert peers.lineage_seeds("ivt", context) == [3, 4, 5] and peers.lineage_seeds("mtt", context) == [3]
    specs = peers.lineage_specs(context, [sequence])
    assert len(specs) == 3 * (len(peers.LINEAGE_LIVE) - 1) + 1
    assert [spec.seed for spec in specs if "mtt" in repr(spec).lower()] == [3]
