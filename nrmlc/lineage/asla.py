"""ASLA: the adaptive structural local sparse appearance model (Jia, Lu and Yang, CVPR 2012), as its
authors' code runs it.

The state is an affine warp (:mod:`nrmlc.lineage.affine`); each frame, 600 particles are drawn
around the last answer and warped to 32x32 gray patches. Each patch is cut into nine overlapping
16x16 local patches, and every local patch is coded by a non-negative lasso over the local patches
of 10 target exemplars (:mod:`nrmlc.lineage.lasso`). *Alignment pooling* sums a local patch's
coefficients over the exemplars per position, normalises them, and keeps the weight on its own
position; the candidate whose nine weights add up to the most is the answer. The exemplars are
the first 10 frames' answers (a nearest-neighbour tracker makes them); afterwards, every fifth
answer updates an incremental PCA subspace, and a sparse reconstruction of the answer on that
subspace (with an identity part that absorbs occlusion) replaces a randomly chosen exemplar,
recent ones more likely, the first never.

Every value and step is that of the OTB benchmark's ASLA (github.com/jwlim/tracker_benchmark,
``trackers/ASLA/``), which made the benchmark's ``*_ASLA.mat`` files:

- parameters: ``paraConfig_ASLA.m`` (600 particles, ``affsig`` (4, 4, 0.01, 0, 0.005, 0),
  lasso ``lambda`` 0.01 with ``pos``, 32x32 template, 16x16 local patches at a step of 8) and
  ``run_ASLA.m`` (10 exemplars, a subspace update every 5 frames without forgetting, 10 basis
  vectors);
- the first state: ``run_ASLA.m`` (the box's centre and size, not rounded; scale ``w/32``);
- frames: gray, divided by 255 (``run_ASLA.m``, ``initial_tracking.m``);
- frames 2 to 10: ``initial_tracking.m`` (the candidate nearest to the last exemplar; raw
  clipped patches as exemplars);
- the sampling: ``sampling.m`` (every particle is the last answer plus Gaussian noise in the
  geometric form: no resampling, no weights carried over);
- the local patches: ``img2patch.m``; the normalisations: ``normalizeMat.m`` (divide by the norm
  plus ``eps``); the coding, pooling, choice and update: ``run_ASLA.m``'s loop, with ``sklm.m``
  (:mod:`nrmlc.lineage.subspace`);
- boxes: the OTB toolkit's box of an ``ivtAff`` state with ``tmplsize`` 32x32
  (:func:`~nrmlc.lineage.affine.matrix_to_box`).

Layout. MATLAB stores a patch as a column-major vector; ours are row-major. Every step of ASLA is
invariant to a permutation of the pixels applied to all vectors alike (norms, inner products, the
lasso, the PCA, and the identity atoms of the reconstruction, which are permuted with them), so
the results are the same. The local patches keep ``img2patch.m``'s order (column blocks outer,
row blocks inner).

Departures, none of them a choice of method:

- the random numbers (numpy's generator, not MATLAB's ``randn``/``rand`` stream);
- the lasso is solved by an exact active-set method instead of SPAMS' LARS; both find the unique
  minimiser of the same strictly convex problem, including SPAMS' ``1e-10`` ridge
  (:mod:`nrmlc.lineage.lasso`), so they differ by rounding only;
- the nearest neighbour of ``initial_tracking.m`` is found by an exhaustive search, as VLFeat's
  kd-tree query with its default (unlimited) comparisons finds it;
- the gray conversion is OpenCV's (:func:`~nrmlc.lineage.affine.gray_frame`), which can differ from
  MATLAB's ``rgb2gray`` by one gray level on some pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import LineageParams, bounded, check_affine_sigma, check_integer
from nrmlc.lineage.affine import box_to_geom, geom_to_matrix, gray_frame, matrix_to_box, matrix_to_geom, warp_patches
from nrmlc.lineage.lasso import SPAMS_RIDGE, lasso_nonnegative_gram
from nrmlc.lineage.subspace import Subspace

#: MATLAB's ``eps``, added to the norms by ``normalizeMat.m`` and to the pooled sums by ``run_ASLA.m``.
EPS = float(np.finfo(np.float64).eps)


@dataclass(frozen=True)
class ASLAParams(LineageParams):
    """ASLA's parameters (the OTB benchmark's ``paraConfig_ASLA.m`` and ``run_ASLA.m``)."""

    n_particles: int = bounded(600, 1, 100_000)
    #: Standard deviations of the geometric state's noise: x, y (pixels), scale, rotation, aspect, skew.
    affine_sigma: tuple = (4.0, 4.0, 0.01, 0.0, 0.005, 0.0)
    #: The lasso's l1 weight (both the local coding and the reconstruction).
    lasso_lambda: float = bounded(0.01, 0.0, 1e3, low_open=True)
    #: The diagonal SPAMS adds to the lasso's Gram matrix (:data:`~nrmlc.lineage.lasso.SPAMS_RIDGE`).
    lasso_ridge: float = bounded(SPAMS_RIDGE, 0.0, 1.0)
    #: Side of the square template (``psize`` [32, 32]).
    template_side: int = bounded(32, 2, 256)
    #: Side of a local patch (at most ``template_side``) and the step between local patches.
    patch_side: int = 16
    patch_step: int = bounded(8, 1, 256)
    #: Exemplars in the dictionary (``EXEMPLAR_NUM``), also the frames of the initial tracking.
    n_exemplars: int = bounded(10, 2, 30)
    #: Answers per subspace update.
    batch_size: int = bounded(5, 1, 1000)
    #: Basis vectors kept after an update.
    max_basis: int = bounded(10, 1, 1000)
    #: Forgetting factor of the subspace update.
    forgetting: float = bounded(1.0, 0.0, 1.0, low_open=True)
    #: Frames are gray levels divided by this.
    intensity_scale: float = bounded(255.0, 0.0, 1e6, low_open=True)

    def check_group(self) -> None:
        check_integer(self, "patch_side", 1, self.template_side)
        if (self.template_side - self.patch_side) % self.patch_step:
            raise ParameterError(f"ASLAParams: (template_side - patch_side) must be a multiple of patch_step, got "
                                 f"{self.template_side}, {self.patch_side}, {self.patch_step}")
        check_affine_sigma(self)

    @property
    def patches_per_side(self) -> int:
        return (self.template_side - self.patch_side) // self.patch_step + 1


def patch_indices(template_side: int, patch_side: int, patch_step: int) -> np.ndarray:
    """Where each local patch's pixels lie in a row-major flattened template (``img2patch.m``).

    Returns
    -------
    (n_patches, patch_side**2) int64
        Patches in ``img2patch.m``'s order (column blocks outer, row blocks inner); pixels row-major
        within a patch (module docstring: the order within a patch does not matter).
    """
    blocks = (template_side - patch_side) // patch_step + 1
    offsets = np.arange(patch_side)
    rows = []
    for block_col in range(blocks):
        for block_row in range(blocks):
            top, left = block_row * patch_step, block_col * patch_step
            rows.append(((top + offsets)[:, None] * template_side + (left + offsets)[None, :]).ravel())
    return np.array(rows, dtype=np.int64)


def normalize_rows(data: np.ndarray) -> np.ndarray:
    """``normalizeMat.m`` on rows: each row divided by its norm plus ``eps`` (in place; returned).

    Parameters
    ----------
    data : (..., N) float64
    """
    norms = np.sqrt(np.einsum("...i,...i->...", data, data))
    data /= (norms + EPS)[..., None]
    return data


def replaced_exemplar(uniform: float, n_exemplars: int) -> int:
    """The 0-based exemplar ``run_ASLA.m`` replaces for the uniform draw ``uniform``.

    ``run_ASLA.m`` builds the cumulative weights of ``[0, 2^1, ..., 2^(E-1)]`` and scans
    ``i = 2..E-1`` for the interval ``[c(i-1), c(i))`` holding the draw, then takes ``i = E`` when
    the draw is at least ``c(E-1)``. Since ``c(1) = 0`` the first exemplar is never replaced, and
    exemplar ``i`` (1-based, ``i >= 2``) is replaced with probability ``2^(i-1) / (2^E - 2)``.

    Parameters
    ----------
    uniform : float
        In [0, 1).
    n_exemplars : int
        ``E``, at least 2.

    Returns
    -------
    int
        In ``1..E-1`` (0-based).
    """
    weights = np.concatenate([[0.0], 2.0 ** np.arange(1, n_exemplars)])
    cumulative = np.cumsum(weights / weights.sum())
    chosen = n_exemplars - 1  # MATLAB's loop variable after a loop without a break
    for i in range(2, n_exemplars):
        if cumulative[i - 2] <= uniform < cumulative[i - 1]:
            chosen = i
            break
    if uniform >= cumulative[n_exemplars - 2]:
        chosen = n_exemplars
    return chosen - 1


def subspace_coefficients(centred: np.ndarray, basis: np.ndarray, lam: float, ridge: float) -> np.ndarray:
    """The basis part of ``mexLasso(centred, [basis, I])`` (``run_ASLA.m``'s reconstruction): the
    identity atoms take up what the subspace cannot explain (occlusion), and are dropped.

    Parameters
    ----------
    centred : (N,) float64
        The answer's normalised patch minus the subspace's mean.
    basis : (N, k) float64
    lam, ridge : float
        The lasso's l1 weight and Gram ridge.

    Returns
    -------
    (k,) float64
    """
    k, size = basis.shape[1], basis.shape[0]
    # The Gram matrix of [basis, I] is written down rather than multiplied out (1034^2 x 1024 flops).
    gram = np.empty((k + size, k + size))
    gram[:k, :k] = basis.T @ basis
    gram[:k, :k] = 0.5 * (gram[:k, :k] + gram[:k, :k].T)
    gram[:k, k:] = basis.T
    gram[k:, :k] = basis
    gram[k:, k:] = np.eye(size)
    gram[np.diag_indices_from(gram)] += ridge
    correlations = np.concatenate([basis.T @ centred, centred])[None]
    return lasso_nonnegative_gram(gram, correlations, lam)[0, :k]


class ASLATracker:
    """ASLA with ``init(frame, box)`` and ``update(frame) -> box`` (boxes 1-based ``x, y, w, h``).

    Parameters
    ----------
    params : ASLAParams, optional
    seed : int
        Seeds the particles' noise and the exemplar replacement.
    """

    name = "ASLA"

    def __init__(self, params: ASLAParams | None = None, seed: int = 0) -> None:
        self.params = params or ASLAParams()
        self.rng = np.random.default_rng(seed)
        p = self.params
        self._patch_index = patch_indices(p.template_side, p.patch_side, p.patch_step)
        self._patches = np.empty((p.n_particles, p.template_side, p.template_side))

    def init(self, frame: np.ndarray, box) -> None:
        """Start on ``frame`` ((H, W, 3) BGR or (H, W) uint8) at ``box``."""
        p = self.params
        gray = gray_frame(frame, p.intensity_scale)
        self.estimate = geom_to_matrix(box_to_geom(box, p.template_side, round_centre=False))
        first = warp_patches(gray, self.estimate[None].copy(), (p.template_side, p.template_side))[0]
        # initial_tracking.m: exemplars are the raw patches clipped at 0, not normalised.
        self.exemplars = [np.maximum(first.ravel(), 0.0)]
        self.templates = None  # (E, N) normalised templates, once the exemplars are collected
        self.subspace = None
        self.batch = []

    def _candidates(self, gray: np.ndarray):
        """Particles around the last answer (``sampling.m``) and their clipped patches, (n, N)."""
        p = self.params
        n = p.n_particles
        particles = matrix_to_geom(self.estimate)[None] + self.rng.standard_normal((n, 6)) * np.asarray(p.affine_sigma)
        patches = warp_patches(gray, np.ascontiguousarray(geom_to_matrix(particles)),
                               (p.template_side, p.template_side), out=self._patches)
        candidates = patches.reshape(n, -1)
        np.maximum(candidates, 0.0, out=candidates)  # candidates .* (candidates > 0)
        return particles, candidates

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Track into ``frame``; the new box, (4,) float64."""
        p = self.params
        gray = gray_frame(frame, p.intensity_scale)
        particles, candidates = self._candidates(gray)
        if self.templates is None:
            best = self._nearest_to_last_exemplar(candidates)
            self.exemplars.append(candidates[best].copy())
            if len(self.exemplars) == p.n_exemplars:
                self._start_model()
        else:
            normalize_rows(candidates)
            best = self._structural_choice(candidates)
            self._update_templates(candidates[best].copy())
        self.estimate = geom_to_matrix(particles[best])
        return matrix_to_box(self.estimate, (p.template_side, p.template_side))[0]

    def _nearest_to_last_exemplar(self, candidates: np.ndarray) -> int:
        """``initial_tracking.m``: the candidate nearest (Euclidean) to the last exemplar."""
        difference = candidates - self.exemplars[-1]
        return int(np.argmin(np.einsum("ij,ij->i", difference, difference)))

    def _start_model(self) -> None:
        """``run_ASLA.m`` after the initial tracking: normalised templates, their local-patch
        dictionary and the first subspace (``sklm.m`` on all exemplars, every basis vector kept)."""
        self.templates = normalize_rows(np.stack(self.exemplars))
        self.exemplars = None
        self._build_dictionary()
        self.subspace = Subspace(self.templates.mean(axis=0))
        self.subspace.update(self.templates.T)

    def _build_dictionary(self) -> None:
        """The local patches of the templates, normalised, as rows ``exemplar * n_patches + patch``,
        and their Gram matrix with SPAMS' ridge."""
        p = self.params
        dictionary = normalize_rows(self.templates[:, self._patch_index].reshape(-1, p.patch_side ** 2))
        gram = dictionary @ dictionary.T
        gram = 0.5 * (gram + gram.T)
        gram[np.diag_indices_from(gram)] += p.lasso_ridge
        self._dictionary, self._gram = dictionary, gram

    def _structural_choice(self, candidates: np.ndarray) -> int:
        """The candidate with the largest alignment-pooled confidence (``run_ASLA.m``).

        Parameters
        ----------
        candidates : (n, N) float64
            Normalised candidate patches.
        """
        p = self.params
        n_patches = self._patch_index.shape[0]
        local = normalize_rows(candidates[:, self._patch_index])  # (n, n_patches, patch_side**2)
        correlations = local.reshape(-1, local.shape[2]) @ self._dictionary.T
        coefficients = lasso_nonnegative_gram(self._gram, correlations, p.lasso_lambda)
        # rows: (candidate, its local patch j); columns: (exemplar, dictionary patch position k)
        coefficients = coefficients.reshape(len(candidates), n_patches, p.n_exemplars, n_patches)
        merged = np.abs(coefficients).sum(axis=2)  # (n, j, k)
        merged /= merged.sum(axis=2, keepdims=True) + EPS
        confidence = np.einsum("njj->n", merged)  # the weight of each local patch on its own position
        return int(np.argmax(confidence))  # the first of equals, as MATLAB's stable sort

    def _update_templates(self, answer: np.ndarray) -> None:
        """``run_ASLA.m``'s template update: every ``batch_size`` answers, the subspace learns them;
        the answer's sparse reconstruction replaces a random exemplar.

        Parameters
        ----------
        answer : (N,) float64
            The normalised patch of this frame's answer.
        """
        p = self.params
        self.batch.append(answer)
        if len(self.batch) < p.batch_size:
            return
        self.subspace.update(np.stack(self.batch, axis=1), p.forgetting)
        self.subspace.truncate(p.max_basis)
        self.batch = []
        basis, mean = self.subspace.basis, self.subspace.mean
        coefficients = subspace_coefficients(answer - mean, basis, p.lasso_lambda, p.lasso_ridge)
        reconstruction = basis @ coefficients + mean
        replaced = replaced_exemplar(self.rng.random(), p.n_exemplars)
        self.templates = np.vstack([np.delete(self.templates, replaced, axis=0),
                                    normalize_rows(reconstruction[None].copy())])
        self._build_dictionary()
