"""Tests for nrmlc.data.synthetic: the deterministic synthetic videos."""
from __future__ import annotations

import pickle
import time

import cv2
import numpy as np
import pytest

from nrmlc.data import Sequence, SyntheticSequence, SyntheticSpec, open_sequence, synthetic_suite, write_otb_sequence
from nrmlc.errors import DataError, ParameterError


@pytest.fixture(scope="module")
def default_sequence() -> SyntheticSequence:
    return SyntheticSequence(SyntheticSpec(name="synth-test", seed=7))


def box_of_changed_pixels(before: np.ndarray, after: np.ndarray) -> tuple[float, float, float, float]:
    """0-based (x0, y0, x1, y1) pixel-centre bounds of where two renders differ."""
    rows, cols = np.nonzero(before != after)
    return cols.min(), rows.min(), cols.max(), rows.max()


# ------------------------------------------------------------------ spec
def test_spec_is_frozen_hashable_picklable():
    spec = SyntheticSpec(name="a", seed=3, n_frames=10)
    assert hash(spec) == hash(SyntheticSpec(name="a", seed=3, n_frames=10))
    assert pickle.loads(pickle.dumps(spec)) == spec
    with pytest.raises(AttributeError):
        spec.seed = 4


@pytest.mark.parametrize("field, value", [("n_frames", 1), ("seed", -1), ("occlusion_fraction", 0.0), ("noise_std", -0.1)])
def test_spec_rejects_bad_values(field, value):
    with pytest.raises(ParameterError, match=f"{field} must be"):
        SyntheticSpec(**{field: value})


def test_target_too_large_for_frame():
    with pytest.raises(ParameterError, match="does not fit"):
        SyntheticSequence(SyntheticSpec(frame_height=40, frame_width=40, target_width=48, target_height=40))


# ------------------------------------------------------------ determinism
def test_same_spec_gives_identical_frames():
    spec = SyntheticSpec(seed=11, n_frames=30)
    first, second = SyntheticSequence(spec), SyntheticSequence(spec)
    for index in [0, 17, 5, 29]:  # any order: the noise is seeded per frame
        np.testing.assert_array_equal(first.frame(index), second.frame(index))
    np.testing.assert_array_equal(first.groundtruth, second.groundtruth)
    np.testing.assert_array_equal(first.true_states, second.true_states)
    np.testing.assert_array_equal(first.frame(3), first.frame(3))


def test_different_seed_gives_different_video():
    first = SyntheticSequence(SyntheticSpec(seed=1, n_frames=20))
    second = SyntheticSequence(SyntheticSpec(seed=2, n_frames=20))
    assert not np.array_equal(first.frame(0), second.frame(0))
    assert not np.allclose(first.groundtruth, second.groundtruth)


def test_pickle_keeps_frames_and_init_box(default_sequence):
    clone = pickle.loads(pickle.dumps(default_sequence.with_init_box([10, 10, 20, 20])))
    np.testing.assert_array_equal(clone.frame(9), default_sequence.frame(9))
    np.testing.assert_array_equal(clone.init_box, [10, 10, 20, 20])


# ---------------------------------------------------------- sequence API
def test_sequence_interface(default_sequence):
    sequence = default_sequence
    spec = sequence.spec
    assert isinstance(sequence, Sequence)
    assert sequence.name == "synth-test" and sequence.path is None
    assert len(sequence) == spec.n_frames == 120
    assert sequence.frame_size == (240, 320)
    assert sequence.groundtruth.shape == (120, 4) and sequence.annotated.all()
    np.testing.assert_array_equal(sequence.init_box, sequence.groundtruth[0])
    frame = sequence.frame(0)
    assert frame.dtype == np.float32 and frame.shape == (240, 320)
    assert 0.0 <= frame.min() and frame.max() <= 1.0
    color = sequence.color_frame(0)
    assert color.dtype == np.uint8 and color.shape == (240, 320, 3)
    assert sum(1 for _ in sequence) == 120


def test_render_is_fast(default_sequence):
    default_sequence.frame(0)  # warm up
    start = time.perf_counter()
    for index in range(40):
        default_sequence.frame(index)
    per_frame = (time.perf_counter() - start) / 40
    # Budget 2 ms (about 0.8 ms measured); the bound is loose because cores are shared.
    assert per_frame < 0.01


# ----------------------------------------------------------- ground truth
def test_groundtruth_matches_true_states(default_sequence):
    states = default_sequence.true_states
    assert states.shape == (120, 6) and states.dtype == np.float64
    centre_x, centre_y, scale, _, aspect, skew = states.T
    width, height = 32 * scale, 32 * scale * aspect
    expected = np.column_stack([centre_x - width / 2 + 1, centre_y - height / 2 + 1, width, height])
    np.testing.assert_allclose(default_sequence.groundtruth, expected, atol=1e-9)
    np.testing.assert_allclose(aspect, 40 / 48)
    assert (skew == 0).all()
    # The box stays inside the frame (1-based: 1 .. width).
    boxes = default_sequence.groundtruth
    assert boxes[:, 0].min() >= 1 and boxes[:, 1].min() >= 1
    assert (boxes[:, 0] + boxes[:, 2]).max() <= 321 and (boxes[:, 1] + boxes[:, 3]).max() <= 241


def test_first_frame_target_fills_its_box(default_sequence):
    """Frame 0 is unrotated at scale 1: the pixels the target changes are exactly its box."""
    centre_x, centre_y, scale, rotation, _, _ = default_sequence.true_states[0]
    assert scale == pytest.approx(48 / 32) and rotation == 0
    x0, y0, x1, y1 = box_of_changed_pixels(
        default_sequence.render(0, draw_target=False), default_sequence.render(0)
    )
    # Box edges (0-based continuous) at centre +/- size/2; edge pixels are partly covered.
    assert abs(x0 - (centre_x - 24)) <= 1 and abs(x1 - (centre_x + 24)) <= 1
    assert abs(y0 - (centre_y - 20)) <= 1 and abs(y1 - (centre_y + 20)) <= 1


def test_rendered_target_centred_on_true_centre(default_sequence):
    """Under rotation and scale the target stays centred on true_states[:, :2]."""
    unoccluded = np.flatnonzero(~default_sequence.occluded)
    for index in unoccluded[::15]:
        x0, y0, x1, y1 = box_of_changed_pixels(
            default_sequence.render(index, draw_target=False), default_sequence.render(index)
        )
        centre_x, centre_y = default_sequence.true_states[index, :2]
        assert abs((x0 + x1) / 2 - centre_x) <= 0.6
        assert abs((y0 + y1) / 2 - centre_y) <= 0.6


def test_target_stands_out_from_background(default_sequence):
    x, y, w, h = np.round(default_sequence.groundtruth[0]).astype(int) - [1, 1, 0, 0]
    frame = default_sequence.frame(0)
    target = frame[y:y + h, x:x + w]
    assert target.std() > 1.5 * frame.std()


# ---------------------------------------------------------------- motion
def test_target_moves_scales_and_rotates(default_sequence):
    states = default_sequence.true_states
    speed = np.hypot(*np.diff(states[:, :2], axis=0).T)
    assert 1.0 < speed.mean() < 6.0 and speed.max() < 8.0
    assert np.ptp(states[:, 0]) > 60 and np.ptp(states[:, 1]) > 30
    width = states[:, 2] * 32
    assert width[0] == pytest.approx(48)
    assert width.max() == pytest.approx(48 * 1.3, rel=0.01) and width.min() == pytest.approx(48 * 0.9, rel=0.01)
    assert np.abs(np.diff(width)).max() < 1.0  # smooth
    rotation_deg = np.degrees(states[:, 3])
    assert 8 < np.abs(rotation_deg).max() <= 10


def test_illumination_changes(default_sequence):
    means = [default_sequence.frame(index).mean() for index in (0, 60)]
    assert means[0] - means[1] > 0.05  # the gain dips mid-video


def test_occlusion_episode(default_sequence):
    occluded = default_sequence.occluded
    assert occluded.dtype == bool and occluded.shape == (120,)
    episode = np.flatnonzero(occluded)
    assert 0.1 <= len(episode) / 120 <= 0.2
    assert np.array_equal(episode, np.arange(episode[0], episode[-1] + 1))  # one contiguous episode
    for index in episode[[0, len(episode) // 2, -1]]:
        changed = default_sequence.render(index, draw_occluder=False) != default_sequence.render(index)
        x, y, w, h = default_sequence.groundtruth[index]
        inside = changed[int(round(y - 1)):int(round(y - 1 + h)), int(round(x - 1)):int(round(x - 1 + w))]
        assert 0.3 <= inside.mean() <= 0.5  # ~40% of the box (a few pixels match by chance)
    assert not np.array_equal(default_sequence.render(0, draw_occluder=False), default_sequence.render(5))


# ----------------------------------------------------------------- suite
def test_synthetic_suite():
    suite = synthetic_suite(n_frames=10, size=(120, 160), n_sequences=4, seed=0)
    assert [s.name for s in suite] == ["synth-01", "synth-02", "synth-03", "synth-04"]
    assert len({s.spec.seed for s in suite}) == 4
    for sequence in suite:
        assert len(sequence) == 10 and sequence.frame_size == (120, 160)
        boxes = sequence.groundtruth
        assert boxes[:, 0].min() >= 1 and (boxes[:, 0] + boxes[:, 2]).max() <= 161
    again = synthetic_suite(n_frames=10, size=(120, 160), n_sequences=4, seed=0)
    assert [s.spec for s in again] == [s.spec for s in suite]
    assert synthetic_suite(n_frames=10, size=(120, 160), seed=1)[0].spec.seed != suite[0].spec.seed


# ------------------------------------------------------------ OTB export
def test_write_otb_sequence_round_trip(tmp_path):
    sequence = SyntheticSequence(SyntheticSpec(name="small", n_frames=5, frame_height=60, frame_width=80,
                                               target_width=16, target_height=12))
    folder = write_otb_sequence(sequence, tmp_path / "small")
    assert sorted(p.name for p in (folder / "img").iterdir()) == [f"000{i}.png" for i in range(1, 6)]
    reopened = open_sequence(folder)
    assert reopened.name == "small" and len(reopened) == 5
    for index in range(5):
        np.testing.assert_array_equal(reopened.frame(index), sequence.frame(index))
    np.testing.assert_allclose(reopened.groundtruth, sequence.groundtruth, atol=1e-4)

    write_otb_sequence(sequence, folder)  # rewriting the same frames is fine
    cv2.imwrite(str(folder / "img" / "0099.png"), np.zeros((60, 80), np.uint8))
    with pytest.raises(DataError, match="already holds other frames"):
        write_otb_sequence(sequence, folder)
