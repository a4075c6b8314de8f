"""patch_blocks (round 30): each block of the patch unit-norm, the whole unit-norm again."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.data.image import as_gray_frame
from nrmlc.errors import ParameterError
from nrmlc.tracker.algorithm import block_normalised


def _naive(patch: np.ndarray, patch_size: int, blocks: int) -> np.ndarray:
    image = patch.reshape(patch_size, patch_size).astype(np.float64)
    out = np.zeros_like(image)
    side = patch_size // blocks
    for i in range(blocks):
        for j in range(blocks):
            block = image[i * side:(i + 1) * side, j * side:(j + 1) * side]
            norm = np.sqrt((block**2).sum())
            if norm > 1e-12:
                out[i * side:(i + 1) * side, j * side:(j + 1) * side] = block / norm / blocks
    return out.ravel()


def test_against_a_naive_oracle_and_unit_norm():
    rng = np.random.default_rng(0)
    patches = rng.random((4, 32 * 32)).astype(np.float32)
    patches[1, :16] = 0.0                                      # part of a block black
    patches[2].reshape(32, 32)[:8, :8] = 0.0                   # a whole block black (at 4 x 4)
    for blocks in (2, 4):
        got = block_normalised(patches, 32, blocks)
        assert got.dtype == np.float32 and got.shape == patches.shape
        for row, patch in zip(got, patches):
            np.testing.assert_allclose(row, _naive(patch, 32, blocks), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(block_normalised(patches[[0, 1]], 32, 4), axis=1), 1.0, rtol=1e-5)
    assert np.linalg.norm(block_normalised(patches[[2]], 32, 4)) == pytest.approx(np.sqrt(15 / 16), rel=1e-5)


def test_a_light_that_changes_across_the_target_cancels_block_by_block():
    rng = np.random.default_rng(1)
    patch = rng.random((16, 16)).astype(np.float32)
    lit = patch.copy()
    lit[:, 8:] *= 2.5                                          # the right half brighter
    flat, lit_flat = patch.ravel(), lit.ravel()
    np.testing.assert_allclose(block_normalised(lit_flat[None], 16, 2), block_normalised(flat[None], 16, 2),
                               rtol=1e-5)
    unit = [v / np.linalg.norm(v) for v in (flat, lit_flat)]
    assert np.abs(unit[0] - unit[1]).max() > 0.01              # one norm over the patch does not cancel it


def test_the_tracker_codes_block_normalised_patches_and_one_block_is_the_paper():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    plain = NRMLCTracker(seed=0, n_particles=20)
    blocked = NRMLCTracker(seed=0, n_particles=20, patch_blocks=4)
    for tracker in (plain, blocked):
        tracker.init(sequence.raw_frame(0), sequence.init_box)
    frame = as_gray_frame(sequence.raw_frame(1))
    states = np.tile(plain.state, (3, 1))
    np.testing.assert_allclose(blocked.patches(frame, states),
                               block_normalised(plain.patches(frame, states), 32, 4), rtol=1e-6)
    assert np.abs(blocked.patches(frame, states) - plain.patches(frame, states)).max() > 1e-3
    assert TrackerParams().patch_blocks == 1 and TrackerParams.paper().patch_blocks == 1
    with pytest.raises(ParameterError, match="patch_blocks"):
        TrackerParams(patch_blocks=3)
