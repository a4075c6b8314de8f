"""Tests that kill the mutants `make mutate` found alive in nrmlc/workbench/metrics.py
(docs/research/mutation.md)."""
from __future__ import annotations

import numpy as np

from nrmlc.workbench.metrics import evaluate_files, success_auc


def test_success_auc_uses_the_thresholds_given():
    # overlaps 0.3 and 0.6 at the single threshold 0.5: one of two frames succeeds.
    assert success_auc([0.3, 0.6], thresholds=[0.5]) == 0.5
    assert success_auc([0.3, 0.6], thresholds=[0.0, 0.5]) == 0.75


def test_evaluate_files_passes_skip_first_on(tmp_path):
    truth = tmp_path / "groundtruth_rect.txt"
    result = tmp_path / "result.txt"
    np.savetxt(truth, [[1, 1, 10, 10], [2, 2, 10, 10], [3, 3, 10, 10]], fmt="%d", delimiter=",")
    np.savetxt(result, [[1, 1, 10, 10], [50, 50, 10, 10], [3, 3, 10, 10]], fmt="%d", delimiter=",")
    assert evaluate_files(result, truth, skip_first=False).n_frames == 3
    assert evaluate_files(result, truth).n_frames == 2
    assert evaluate_files(result, truth, skip_first=False).mean_overlap == 2 / 3
