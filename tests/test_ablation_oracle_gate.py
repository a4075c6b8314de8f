"""Tests for experiments/paper/ablation_oracle_gate.py: the gated tracker against the plain one, and the
gate's decisions where the answer is known."""
from __future__ import annotations

import numpy as np
import pytest

from experiments.paper.ablation_oracle_gate import OracleGateRun, OracleGateTracker, oracle_gate_tracker
from nrmlc.data import synthetic_suite
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.params import TrackerParams

N = 30
# Updates every frame, so that the gate decides on every frame of these short sequences.
PARAMS = TrackerParams(n_particles=100, update_interval=1)


@pytest.fixture(scope="module")
def sequence():
    return synthetic_suite(n_frames=N, n_sequences=1)[0]


def track(tracker, sequence):
    tracker.init(sequence.frame(0), sequence.init_box)
    boxes, updates, errors = [], [], []
    for index in range(1, N):
        boxes.append(tracker.update(sequence.frame(index)))
        updates.append(tracker.last.updated_positive)
        errors.append(tracker.last.error_positive)
    return np.array(boxes), np.array(updates), np.array(errors)


def test_rule_gate_is_the_plain_tracker(sequence):
    plain = track(NRMLCTracker(seed=3, params=PARAMS), sequence)
    gated = track(OracleGateTracker(sequence.groundtruth, "rule", seed=3, params=PARAMS), sequence)
    for a, b in zip(plain, gated):
        np.testing.assert_array_equal(a, b)


def test_truth_gate_follows_the_overlap(sequence):
    truth = np.asarray(sequence.groundtruth, dtype=np.float64)
    far = truth + np.array([1000.0, 1000.0, 0.0, 0.0])
    # The truth 1000 px away: never on the target, so the oracle alone never updates and
    # "rule and truth" never does either; "rule or truth" is then the rule.
    assert not track(OracleGateTracker(far, "truth", seed=1, params=PARAMS), sequence)[1].any()
    assert not track(OracleGateTracker(far, "rule and truth", seed=1, params=PARAMS), sequence)[1].any()
    rule = track(OracleGateTracker(far, "rule", seed=1, params=PARAMS), sequence)
    either = track(OracleGateTracker(far, "rule or truth", seed=1, params=PARAMS), sequence)
    np.testing.assert_array_equal(rule[0], either[0])
    assert rule[1].any()
    # No ground truth at all (NaN rows): every gate keeps the rule.
    unknown = np.full_like(truth, np.nan)
    np.testing.assert_array_equal(track(OracleGateTracker(unknown, "truth", seed=1, params=PARAMS), sequence)[0],
                                  rule[0])


def test_truth_gate_updates_on_the_target_and_keeps_the_diagnostics(sequence):
    # A rule that refuses every result (threshold 1e-6), and the plain tracker's own boxes as the
    # "truth": the two runs are the same up to frame 1, where the box is at IoU 1, so the oracle
    # accepts the update the rule refuses; the recorded eps_pos* stay the tracker's own.
    strict = PARAMS.replace(update_error_threshold=1e-6)
    boxes, updates, _ = track(NRMLCTracker(seed=2, params=strict), sequence)
    assert not updates.any()
    own = np.vstack([sequence.init_box, boxes])
    _, gated_updates, errors = track(OracleGateTracker(own, "truth", seed=2, params=strict), sequence)
    assert gated_updates[0] and gated_updates.sum() > 1
    assert np.isfinite(errors).all() and (errors > 1e-6).all()


def test_job_key_names_the_gate(sequence):
    a = OracleGateRun(sequence, PARAMS, 0, "truth")
    b = OracleGateRun(sequence, PARAMS, 0, "rule or truth")
    assert a.key("v") != b.key("v") and a.key("v") == OracleGateRun(sequence, PARAMS, 0, "truth").key("v")
    arrays = OracleGateRun(sequence, PARAMS, 0, "truth", n_frames=10).execute()
    assert arrays["boxes"].shape == (10, 4) and arrays["updated_positive"].shape == (10,)


def test_a_second_expert_learns_under_the_same_gate():
    tracker = oracle_gate_tracker(np.zeros((3, 4)), "truth", 1, PARAMS)
    assert PARAMS.second_expert != "off" and all(isinstance(e, OracleGateTracker) for e in tracker.experts)
    assert [e.gate for e in tracker.experts] == ["truth", "truth"]
    assert tracker.experts[1].params == PARAMS.partner_params()
