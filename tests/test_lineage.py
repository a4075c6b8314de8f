"""The lineage's shared parts (affine states, IVT's warp and L1-APG's crop, incremental PCA), IVT,
and how the workbench and the command line reach them."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numba
import numpy as np
import pytest

from nrmlc.data import synthetic_suite
from nrmlc.errors import ParameterError
from nrmlc.lineage import TRACKERS
from nrmlc.lineage.blocks import MAX_BLOCKS, problem_blocks
from nrmlc.lineage.affine import (box_to_geom, geom_to_matrix, matrix_to_box, matrix_to_geom, warp_patches,
                                  warp_patches_reference)
from nrmlc.lineage.ivt import IVTParams, IVTTracker
from nrmlc.lineage.l1apg import crop_patches, crop_patches_reference
from nrmlc.lineage.subspace import Subspace
from nrmlc.workbench.metrics import evaluate
from nrmlc.workbench.trackers import ImportedTracker, track_init_update


# --------------------------------------------------------------------------- affine states and IVT's warp


def random_geoms(rng, n):
    return np.column_stack([rng.uniform(0, 100, n), rng.uniform(0, 80, n), rng.uniform(0.3, 3, n),
                            rng.uniform(-1.2, 1.2, n), rng.uniform(0.4, 2.5, n), rng.uniform(-0.4, 0.4, n)])


def test_matrix_of_a_rotation_without_skew():
    s, th, r = 1.7, 0.3, 0.8
    q = geom_to_matrix([5.0, 6.0, s, th, r, 0.0])
    np.testing.assert_allclose(q, [5, 6, s * np.cos(th), -s * r * np.sin(th), s * np.sin(th), s * r * np.cos(th)])


def test_geometric_and_matrix_forms_round_trip():
    rng = np.random.default_rng(1)
    for geom in random_geoms(rng, 200):
        matrix = geom_to_matrix(geom)
        np.testing.assert_allclose(geom_to_matrix(matrix_to_geom(matrix)), matrix, atol=1e-9)


@pytest.mark.parametrize("box", [(10, 20, 32, 40), (3, 4, 17, 9), (100, 50, 64, 64)])
def test_a_box_survives_state_and_back(box):
    # The OTB toolkit's corners of the state of an integer box are the box (IVT rounds the centre,
    # which for an odd size moves it by half a pixel: the box shifts by at most one).
    geom = box_to_geom(box, 32, round_centre=False)
    np.testing.assert_allclose(matrix_to_box(geom_to_matrix(geom), (32, 32))[0], box, atol=1e-9)
    rounded = matrix_to_box(geom_to_matrix(box_to_geom(box, 32, round_centre=True)), (32, 32))[0]
    assert np.abs(rounded - np.asarray(box)).max() <= 1


def test_warp_matches_its_reference_inside_across_and_outside_the_frame():
    rng = np.random.default_rng(2)
    frame = rng.random((40, 50))
    geoms = random_geoms(rng, 60)
    geoms[:20, :2] = rng.uniform(-20, 70, (20, 2))   # partly or wholly off the frame
    geoms[20:30, :2] = rng.uniform(-1, 1, (10, 2))  # coordinates in (-1, 0): C's (int) truncates towards 0
    matrices = np.ascontiguousarray(geom_to_matrix(geoms))
    got = warp_patches(frame, matrices, (12, 16))
    np.testing.assert_allclose(got, warp_patches_reference(frame, matrices, (12, 16)), rtol=1e-12, atol=1e-12)
    assert (got[:20] == 0).any() and (got[:20] != 0).any()


def test_an_unscaled_warp_copies_pixels():
    frame = np.arange(30 * 40, dtype=np.float64).reshape(30, 40)
    patch = warp_patches(frame, np.array([[20.0, 15.0, 1, 0, 0, 1]]), (8, 6))[0]
    # template point (u, v) = (col + 1 - 3, row + 1 - 4) -> 1-based (20 + u, 15 + v) -> 0-based minus one
    np.testing.assert_array_equal(patch, frame[15 - 4: 15 + 4, 20 - 3: 20 + 3])


# --------------------------------------------------------------------------- L1-APG's crop (IMGaffine_c)


def random_crop_states(rng, n):
    """``n`` states (a11, a12, a21, a22, tr, tc) of the crop, moved across and around a 40 x 50 frame."""
    return np.column_stack([rng.uniform(0.3, 3, n), rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n),
                            rng.uniform(0.3, 3, n), rng.uniform(-10, 40, n), rng.uniform(-10, 50, n)])


def test_crop_matches_its_reference_inside_across_and_outside_the_frame():
    rng = np.random.default_rng(10)
    frame = rng.integers(0, 256, (40, 50)).astype(np.float64)
    states = random_crop_states(rng, 80)
    states[:10, 4:] = [[200.0, 10.0]] * 10                      # wholly outside
    states[10:20] = [0.5, 0.0, 0.0, 0.5, -3.0, 20.25]          # rows on halves, some negative: MATLAB's round
    states[20:30] = [1.0, 0.0, 0.0, 1.0, 3.0, 50.0 - 10.0]     # up to the last column, which the mex excludes
    states = np.ascontiguousarray(states)
    patches, in_range = crop_patches(frame, states, (12, 10))
    expected, expected_in_range = crop_patches_reference(frame, states, (12, 10))
    np.testing.assert_array_equal(in_range, expected_in_range)
    np.testing.assert_allclose(patches, expected, rtol=1e-13, atol=0)  # NaN where both are NaN
    assert not in_range[:10].any() and np.isnan(patches[:10]).all()
    assert in_range[10:30].all()


def test_crop_of_a_translation_copies_pixels_and_fills_with_the_mean():
    frame = np.arange(30 * 40, dtype=np.float64).reshape(30, 40)
    # template (r, c) -> image (r + 5, c + 28), 1-based: columns 29..40, the last one outside
    patches, in_range = crop_patches(frame, np.array([[1.0, 0, 0, 1.0, 5.0, 28.0]]), (8, 12))
    inside = frame[5:13, 28:39]
    np.testing.assert_array_equal(patches[0, :, :11], inside)
    np.testing.assert_allclose(patches[0, :, 11], inside.mean(), rtol=1e-15)
    assert in_range[0]


def test_crop_rounds_halves_away_from_zero():
    frame = np.arange(20 * 20, dtype=np.float64).reshape(20, 20)
    # row 0.5 r + 2: r = 1 -> 2.5 -> 3, r = 3 -> 3.5 -> 4 (numpy's round would give 2 and 4)
    patches, _ = crop_patches(frame, np.array([[0.5, 0, 0, 1.0, 2.0, 0.0]]), (4, 2))
    np.testing.assert_array_equal(patches[0, :, 0], frame[[2, 2, 3, 3], 0])


# --------------------------------------------------------------------------- both the warp and the crop


def _warp_inputs(rng):
    return rng.random((60, 80)), np.ascontiguousarray(geom_to_matrix(random_geoms(rng, 101)))


def _crop_inputs(rng):
    return rng.random((60, 80)) * 255, np.ascontiguousarray(random_crop_states(rng, 101))


@pytest.mark.parametrize("patches", [warp_patches, crop_patches], ids=["warp", "crop"])
@pytest.mark.parametrize("states, message", [(np.zeros((3, 5)), "6 columns"), (np.full((2, 6), np.nan), "finite"),
                                             (np.zeros((2, 6), dtype=np.float32), "dtype")])
def test_warp_and_crop_refuse_bad_states(patches, states, message):
    with pytest.raises(ParameterError, match=message):
        patches(np.zeros((10, 10)), states, (4, 4))


@pytest.mark.parametrize("patches", [warp_patches, crop_patches], ids=["warp", "crop"])
def test_warp_and_crop_refuse_a_bad_frame_or_buffer(patches):
    frame, states = np.zeros((10, 10)), np.zeros((2, 6))
    states[:, [0, 3] if patches is crop_patches else [2, 5]] = 1.0
    with pytest.raises(ParameterError, match="frame must be finite"):
        patches(np.full((10, 10), np.inf), states, (4, 4))
    with pytest.raises(ParameterError, match=r"shape \(2, 4, 3\)"):
        patches(frame, states, (4, 3), out=np.empty((2, 3, 4)))
    with pytest.raises(ParameterError, match="C-contiguous float64"):
        patches(frame, states, (4, 3), out=np.empty((2, 4, 3), dtype=np.float32))
    given = np.empty((2, 4, 3))
    got = patches(frame, states, (4, 3), out=given)
    assert (got[0] if patches is crop_patches else got) is given


@pytest.mark.parametrize("patches, seed, inputs", [(warp_patches, 3, _warp_inputs), (crop_patches, 11, _crop_inputs)],
                         ids=["warp", "crop"])
def test_warp_and_crop_are_the_same_for_any_thread_count(patches, seed, inputs):
    frame, states = inputs(np.random.default_rng(seed))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = patches(frame, states, (32, 32))
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = patches(frame, states, (32, 32))
    finally:
        numba.set_num_threads(before)
    # assert_equal goes into the crop's (patches, in_range) pair, each array compared exactly
    np.testing.assert_equal(one, many)


# --------------------------------------------------------------------------- incremental PCA


def test_incremental_pca_without_forgetting_is_batch_pca():
    # sklm.m with ff = 1 and nothing cut is exact: the mean and singular values of all batches
    # together (Levy and Lindenbaum 2000; Ross et al. 2008, Sec. 3.1).
    rng = np.random.default_rng(4)
    batches = [rng.random((50, 5)) @ np.diag([3, 2, 1, 1, 0.5]) for _ in range(4)]
    subspace = Subspace(np.zeros(50))
    for batch in batches:
        subspace.update(batch, forgetting=1.0)
    data = np.hstack(batches)
    np.testing.assert_allclose(subspace.mean, data.mean(axis=1), atol=1e-12)
    expected = np.linalg.svd(data - data.mean(axis=1, keepdims=True), compute_uv=False)
    np.testing.assert_allclose(subspace.singular_values, expected[: subspace.singular_values.size], rtol=1e-9)
    np.testing.assert_allclose(subspace.basis.T @ subspace.basis, np.eye(subspace.basis.shape[1]), atol=1e-10)


def test_forgetting_weights_the_mean_towards_new_batches():
    subspace = Subspace(np.zeros(3))
    subspace.update(np.zeros((3, 5)) + [[1], [1], [1]], forgetting=0.5)
    subspace.update(np.zeros((3, 5)) + [[3], [3], [3]], forgetting=0.5)
    # (ff n0 mu0 + n mu1) / (n + ff n0) = (0.5*5*1 + 5*3) / 7.5
    np.testing.assert_allclose(subspace.mean, (2.5 + 15) / 7.5)
    assert subspace.n_samples == 7.5


def test_residuals_are_distances_to_the_affine_subspace():
    rng = np.random.default_rng(5)
    subspace = Subspace(np.zeros(20))
    subspace.update(rng.random((20, 6)))
    subspace.truncate(3)
    patches = rng.random((7, 20))
    centred = patches - subspace.mean
    projected = centred @ subspace.basis @ subspace.basis.T
    np.testing.assert_allclose(subspace.residuals(patches), ((centred - projected) ** 2).sum(axis=1))


# --------------------------------------------------------------------------- IVT, the workbench, the command line


@pytest.fixture(scope="module")
def sequence():
    return synthetic_suite(n_frames=40, size=(120, 160), n_sequences=1, seed=3)[0]


def run_ivt(sequence, seed):
    tracker = IVTTracker(seed=seed)
    tracker.init(sequence.color_frame(0), sequence.init_box)
    return np.array([sequence.init_box] + [tracker.update(sequence.color_frame(i)) for i in range(1, len(sequence))])


def test_ivt_follows_a_moving_target_that_a_still_box_loses(sequence):
    boxes = run_ivt(sequence, 0)
    still = np.repeat(sequence.init_box[None], len(sequence), axis=0)
    tracked = evaluate(boxes, sequence.groundtruth).mean_overlap
    assert tracked > 0.6
    assert tracked > evaluate(still, sequence.groundtruth).mean_overlap + 0.2


def test_ivt_is_reproducible_by_seed(sequence):
    np.testing.assert_array_equal(run_ivt(sequence, 7), run_ivt(sequence, 7))
    assert not np.array_equal(run_ivt(sequence, 7), run_ivt(sequence, 8))


@pytest.mark.parametrize("field, value", [("n_particles", 0), ("condenssig", 0.0), ("forgetting", 1.5),
                                          ("batch_size", 0), ("affine_sigma", (1, 2, 3)), ("max_basis", 0),
                                          ("intensity_scale", 0.0), ("template_size", (32, 1))])
def test_ivt_parameters_out_of_range_are_refused(field, value):
    with pytest.raises(ParameterError, match=f"IVTParams.{field}"):
        IVTParams(**{field: value})


def test_lineage_trackers_are_reached_by_short_name(sequence):
    entry = ImportedTracker("IVT")
    assert entry.name == "IVT" and entry.spec == TRACKERS["ivt"]
    boxes, seconds = track_init_update(entry.spec, sequence, 7, 12)
    np.testing.assert_array_equal(boxes, run_ivt(sequence, 7)[:12])
    assert seconds > 0


def test_a_lineage_runs_key_covers_the_files_it_shares(sequence, tmp_path, monkeypatch):
    from nrmlc.workbench import trackers

    first = ImportedTracker("ivt").source
    original = trackers.Path.read_bytes

    def edited(path):
        data = original(path)
        return data + b"\n# edited\n" if path.name == "subspace.py" else data

    monkeypatch.setattr(trackers.Path, "read_bytes", edited)
    assert ImportedTracker("ivt").source != first


def test_a_lineage_runs_key_leaves_out_the_files_it_does_not_import(monkeypatch):
    from nrmlc.workbench import trackers

    before = {name: ImportedTracker(name).source for name in ("ivt", "asla")}
    original = trackers.Path.read_bytes

    def edited(path):
        data = original(path)
        return data + b"\n# edited\n" if path.name == "lasso.py" else data

    monkeypatch.setattr(trackers.Path, "read_bytes", edited)
    assert ImportedTracker("ivt").source == before["ivt"]  # IVT does not use the lasso
    assert ImportedTracker("asla").source != before["asla"]
    files = {Path(p).relative_to(Path(trackers.__file__).parents[1]).as_posix()
             for p in trackers.nrmlc_imports("nrmlc.lineage.asla")}
    assert {"lineage/asla.py", "lineage/affine.py", "lineage/lasso.py", "lineage/subspace.py",
            "kernels/checks.py", "config.py"} <= files
    assert "lineage/ivt.py" not in files and "lineage/__init__.py" not in files


@pytest.fixture(scope="module")
def sequence_folder(tmp_path_factory, sequence):
    from nrmlc.data import write_otb_sequence

    root = tmp_path_factory.mktemp("lineage-data")
    write_otb_sequence(synthetic_suite(n_frames=10, size=(120, 160), n_sequences=1, seed=3)[0], root / "synth-01")
    return root


def test_track_with_a_lineage_tracker_writes_its_boxes(sequence_folder, tmp_path, capsys):
    from nrmlc.cli import main
    from nrmlc.data import open_sequence, read_box_file

    code = main(["track", str(sequence_folder / "synth-01"), "--out", str(tmp_path / "ivt.txt"), "--tracker", "ivt",
                 "--seed", "4"])
    assert code == 0
    assert "mean overlap" in capsys.readouterr().err
    sequence = open_sequence(sequence_folder / "synth-01")
    np.testing.assert_allclose(read_box_file(tmp_path / "ivt.txt"), run_ivt(sequence, 4), atol=1e-3)


@pytest.mark.parametrize("extra", [["--param", "lam=1"], ["--particles", "10"], ["--preset", "paper"]])
def test_track_refuses_nrmlc_options_with_another_tracker(sequence_folder, tmp_path, capsys, extra):
    from nrmlc.cli import main

    code = main(["track", str(sequence_folder / "synth-01"), "--out", str(tmp_path / "x.txt"), "--tracker", "ivt",
                 *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and extra[0] in err
    assert not (tmp_path / "x.txt").exists()


def test_benchmark_runs_a_lineage_tracker_once_per_seed(sequence_folder, tmp_path, capsys):
    from nrmlc.cli import main

    argv = ["benchmark", str(sequence_folder), "--out", str(tmp_path / "IVT"), "--tracker", "ivt", "--seeds", "0-1",
            "--cache", str(tmp_path / "cache"), "--jobs", "1"]
    assert main(argv) == 0
    assert len(list((tmp_path / "cache" / "imported").glob("*.npz"))) == 2
    first = (tmp_path / "IVT" / "synth-01.txt").read_text()
    assert main([*argv[:3], str(tmp_path / "Again"), *argv[4:]]) == 0  # from the cache
    assert (tmp_path / "Again" / "synth-01.txt").read_text() == first
    assert len(list((tmp_path / "cache" / "imported").glob("*.npz"))) == 2


@pytest.mark.parametrize("shape", [(20, 20, 2), (20, 20, 4), (20,), (2, 20, 20, 3)])
def test_gray_frame_refuses_what_is_not_a_gray_or_bgr_frame(shape):
    from nrmlc.lineage.affine import gray_frame

    with pytest.raises(ParameterError, match=r"frame must be \(H, W\) or \(H, W, 3\)"):
        gray_frame(np.zeros(shape, dtype=np.uint8), 255.0)
    assert gray_frame(np.full((4, 5, 3), 51, dtype=np.uint8), 255.0) == pytest.approx(np.full((4, 5), 0.2))


# --------------------------------------------------------------------------- every lineage group's bounds


def _bounded_fields():
    from nrmlc.lineage.asla import ASLAParams
    from nrmlc.lineage.l1 import L1Params
    from nrmlc.lineage.l1apg import L1APGParams, TemplateTrackerParams
    from nrmlc.lineage.mtt import MTTParams

    for group in (IVTParams, ASLAParams, TemplateTrackerParams, L1APGParams, L1Params, MTTParams):
        for field in dataclasses.fields(group):
            if "low" in field.metadata:
                yield pytest.param(group, field, id=f"{group.__name__}.{field.name}")


def _refused_here(group, field, value) -> bool:
    """Whether ``group`` refuses ``field=value`` naming that field (another field's tie may refuse
    an edge value too: that is not this field's bound)."""
    try:
        group(**{field.name: value})
    except ParameterError as error:
        return f"{group.__name__}.{field.name} must" in str(error)
    return False


@pytest.mark.parametrize("group, field", list(_bounded_fields()))
def test_lineage_groups_enforce_each_bound_at_its_edge(group, field):
    low, high, low_open = field.metadata["low"], field.metadata["high"], field.metadata["low_open"]
    if field.type == "int":
        inside, outside = [low, high], [low - 1, high + 1, 1.5, True]
    else:
        inside = [high] + ([] if low_open else [low])
        outside = [np.nextafter(low, -np.inf), np.nextafter(high, np.inf), np.nan, "1"] + ([low] if low_open else [])
    assert not any(_refused_here(group, field, value) for value in inside)
    assert all(_refused_here(group, field, value) for value in outside)


@pytest.mark.parametrize("n", [1, 2, 63, 64, 65, 127, 128, 129, 5400])
def test_problem_blocks_cover_the_problems_with_no_block_empty(n):
    n_blocks, block_size = problem_blocks(n)
    assert 1 <= n_blocks <= MAX_BLOCKS
    assert (n_blocks - 1) * block_size < n <= n_blocks * block_size
