"""The local-patch generative term (``generative_weight``, nrmlc/tracker/generative.py)."""
from __future__ import annotations

import numpy as np
import pytest

from nrmlc import TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError

from experiments.instrumented import RecordingTracker
from nrmlc.tracker.generative import (FIRST_FRAME_SHARE, N_ATOMS, LocalHistogramModel, kmeans_atoms,
                                      local_patches)

SETTINGS = dict(n_particles=150, generative_weight=10.0, generative_candidates=40)


def _unit_patch(rng, size=32):
    """A smooth random image (as a target is at 32x32), as a unit patch vector."""
    rows, columns = np.indices((size, size)) / size
    phase = rng.uniform(0, 2 * np.pi, 4)
    image = (2 + np.sin(5 * rows + phase[0]) * np.cos(4 * columns + phase[1])
             + 0.5 * np.sin(9 * columns + phase[2]) + 0.5 * np.cos(7 * rows + phase[3]))
    patch = image.reshape(-1).astype(np.float32)
    return patch / np.linalg.norm(patch)


def test_local_patches_are_scms_grid_of_unit_6x6_patches():
    patch = np.arange(32 * 32, dtype=np.float32) + 1
    local = local_patches(patch[None] / np.linalg.norm(patch), 32)
    assert local.shape == (1, 14 * 14, 36)
    np.testing.assert_allclose(np.linalg.norm(local, axis=2), 1.0, rtol=1e-6)
    # The second patch starts 2 px to the right, the 15th 2 rows down.
    image = patch.reshape(32, 32)
    for index, (row, column) in ((1, (0, 2)), (14, (2, 0)), (195, (26, 26))):
        expected = image[row:row + 6, column:column + 6].reshape(-1)
        np.testing.assert_allclose(local[0, index], expected / np.linalg.norm(expected), rtol=1e-6)


def test_a_coarser_grid_cuts_fewer_patches_but_keeps_the_dense_grids_atoms():
    patch = _unit_patch(np.random.default_rng(6))
    dense, coarse = local_patches(patch[None], 32), local_patches(patch[None], 32, step=4)
    assert coarse.shape == (1, 7 * 7, 36)
    # Every 4 px is every other patch of the 2-px grid, in both directions.
    np.testing.assert_array_equal(coarse[0], dense[0].reshape(14, 14, 36)[::2, ::2].reshape(49, 36))
    model = LocalHistogramModel(np.random.default_rng(7), patch, 32, 5, 1.0, step=4)
    np.testing.assert_array_equal(model.atoms, LocalHistogramModel(np.random.default_rng(7), patch, 32, 5, 1.0).atoms)
    assert model.atoms.shape == (N_ATOMS, 36) and model.histogram.shape == (49, N_ATOMS)
    assert model.similarity(patch[None])["similarity"][0] == pytest.approx(1.0)


def test_kmeans_is_seeded_and_gives_unit_atoms():
    points = local_patches(_unit_patch(np.random.default_rng(0))[None], 32)[0]
    atoms = kmeans_atoms(np.random.default_rng(1), points, N_ATOMS)
    assert atoms.shape == (N_ATOMS, 36)
    np.testing.assert_allclose(np.linalg.norm(atoms, axis=1), 1.0)
    np.testing.assert_array_equal(atoms, kmeans_atoms(np.random.default_rng(1), points, N_ATOMS))
    assert kmeans_atoms(np.random.default_rng(1), points[:7], N_ATOMS).shape == (7, 36)


def test_occluded_patches_drop_out_of_both_histograms_and_another_target_scores_lower():
    rng = np.random.default_rng(2)
    target = _unit_patch(rng)
    model = LocalHistogramModel(np.random.default_rng(3), target, 32, 5, 1.0)
    occluded = target.reshape(32, 32).copy()
    # A high-contrast stripe pattern over the left half: far from every atom of the target.
    occluded[:, :16] = np.where(np.indices((32, 16)).sum(axis=0) % 2, 0.0, 1.0)
    occluded = occluded.reshape(-1) / np.linalg.norm(occluded)
    other = _unit_patch(rng)
    result = model.similarity(np.stack([target, occluded, other]))
    assert result["similarity"][0] == pytest.approx(1.0)
    assert result["occluded_share"][0] == 0.0
    # SCM's robustness: the occluded local patches leave both histograms, so the visible
    # rest of the target still matches in full (plus the bonus per occluded patch) ...
    assert 0.3 < result["occluded_share"][1] < 0.6
    assert result["similarity"][1] == pytest.approx(1.0 + 3e-5 * 196 * result["occluded_share"][1])
    # ... while a different image, visible throughout, matches less.
    assert result["occluded_share"][2] < 0.1 and result["similarity"][2] < 0.9


def test_the_template_histogram_stays_anchored_to_the_first_frame():
    rng = np.random.default_rng(4)
    model = LocalHistogramModel(np.random.default_rng(5), _unit_patch(rng), 32, 5, 1.0)
    first = model.first_histogram.copy()
    result = model.similarity(_unit_patch(rng)[None])
    neighbours, codes = result["neighbours"][0], result["codes"][0]
    model.update(neighbours, codes, occluded_share=0.1)
    recent = np.zeros_like(first)
    np.put_along_axis(recent, neighbours, np.abs(codes), axis=1)
    np.testing.assert_allclose(model.histogram, FIRST_FRAME_SHARE * first + (1 - FIRST_FRAME_SHARE) * recent)
    model.update(neighbours, codes, occluded_share=0.1)  # not cumulative: always from the first frame's
    np.testing.assert_allclose(model.histogram, FIRST_FRAME_SHARE * first + (1 - FIRST_FRAME_SHARE) * recent)
    model.update(neighbours, codes, occluded_share=0.9)  # mostly occluded: back to the first frame's
    np.testing.assert_array_equal(model.histogram, first)


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="g", seed=3, n_frames=25))


def _boxes(sequence, seed=0, **changes):
    tracker = RecordingTracker(seed=seed, **{**SETTINGS, **changes})
    tracker.init(sequence.frame(0), sequence.init_box)
    return tracker, np.array([tracker.update(sequence.frame(i)) for i in range(1, len(sequence))])


def test_the_term_changes_the_ranking_by_its_weight(sequence):
    tracker, boxes = _boxes(sequence)
    coded = tracker.last_coding
    similarity = coded.similarity
    top = np.argsort(-similarity)[:SETTINGS["generative_candidates"]]
    assert np.all(similarity <= 1.0 + 1e-9) and np.all(similarity[top] >= similarity.min())
    plain = -tracker.params.alpha * (coded.error_positive - coded.error_negative)
    recognised = coded.error_positive < 0.99
    assert recognised.mean() > 0.5
    np.testing.assert_allclose(coded.log_confidence[recognised],
                               plain[recognised] + 10.0 * np.log(similarity[recognised]))
    assert not np.array_equal(boxes, _boxes(sequence, generative_weight=0.0)[1])
    np.testing.assert_array_equal(boxes, _boxes(sequence)[1])  # seeded


def test_where_no_positive_takes_part_the_term_does_not_rank(sequence):
    """Candidates coded on negatives alone (the target hidden or lost) keep the discriminative
    ranking, so the cloud spreads to search as without the term."""
    tracker, _ = _boxes(sequence)
    coded = tracker.encode(tracker.negative_templates)
    negatives = tracker.negative_templates[coded.error_positive >= 0.99][:30]
    assert len(negatives) == 30
    coded = tracker.encode(negatives)
    np.testing.assert_array_equal(coded.log_confidence,
                                  -tracker.params.alpha * (coded.error_positive - coded.error_negative))
    assert np.ptp(coded.similarity) > 0  # the similarity differs, yet does not rank them
    mixed = tracker.encode(np.vstack([negatives, tracker.positive_templates[:5]]))
    recognised = mixed.error_positive < 0.99
    plain = -tracker.params.alpha * (mixed.error_positive - mixed.error_negative)
    term = mixed.log_confidence - plain
    # The others get the lowest term among the recognised ones.
    np.testing.assert_allclose(term[~recognised], term[recognised].min())


def test_off_is_the_tracker_without_the_term(sequence):
    tracker, boxes = _boxes(sequence, generative_weight=0.0)
    assert tracker.generative is None and tracker.last_coding.similarity is None
    np.testing.assert_array_equal(boxes, _boxes(sequence, generative_weight=0.0, generative_candidates=7,
                                                generative_neighbours=2)[1])


def test_the_paper_preset_has_no_generative_term():
    assert TrackerParams.paper().generative_weight == 0.0


@pytest.mark.parametrize("changes, name", [
    (dict(generative_weight=-1.0), "generative_weight"),
    (dict(generative_candidates=0), "generative_candidates"),
    (dict(generative_neighbours=N_ATOMS + 1), "generative_neighbours"),
    (dict(generative_lam=0.0), "generative_lam"),
    (dict(generative_interval=0), "generative_interval"),
    (dict(generative_step=0), "generative_step"),
    (dict(generative_step=7), "generative_step"),
    (dict(generative_weight=1.0, patch_size=5), "patch_size"),
])
def test_bad_values_name_the_parameter(changes, name):
    with pytest.raises(ParameterError, match=name):
        TrackerParams(**changes)
