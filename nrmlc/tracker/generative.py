"""A local-patch generative term (*ours*, after SCM's SGM; on by default, off in the paper preset).

SCM (Zhong, Lu, Yang, CVPR 2012; ``demo.m``, ``affineTrainL.m``, ``affinePatch.m`` and
``updateDic.m`` of huchuanlu/12_1) multiplies its discriminative confidence by a
generative similarity built from local patches:

1. cut the 32x32 patch into 6x6 local patches every 2 px (14 x 14 = 196), each l2-normalised;
2. a dictionary of 50 atoms by k-means of the first frame's local patches;
3. code each local patch on the atoms; a local patch whose reconstruction error is
   at least 0.04 counts as occluded, and its code is dropped from both histograms;
4. similarity = histogram intersection of the candidate's |codes| and the template's,
   plus 3e-5 per occluded local patch;
5. every 5 frames, the template histogram is 0.95 of the first frame's and 0.05 of the
   result's, unless more than 0.8 of the result's local patches are occluded.

Here the codes are NRMLC's own approximated LLC on the ``k`` nearest atoms
(:mod:`nrmlc.kernels.local_coding`) in place of SCM's lasso, the k-means runs on the
l2-normalised local patches (SCM's on the raw ones, normalising the atoms after), and the
term enters the log confidence as ``weight * log(similarity)``, only on the candidates whose
code uses a positive template (:class:`GenerativeTerm`, a confidence term of
:meth:`nrmlc.tracker.algorithm.NRMLCTracker.encode`): where none does, the target is hidden or
lost, and a term that still ranks the background would hold the particle cloud there instead of
letting it spread and search. For speed, the candidates' local patches are cut every
``generative_step`` px (4: 49 patches, not 196) and only the ``generative_candidates`` most
confident candidates are coded; the atoms still come from the first frame's 2-px grid.
Evidence: docs/DEVIATIONS.md.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from nrmlc.kernels.local_coding import code_local_patches, match_local_histogram
from nrmlc.tracker.parameter_fields import CheckedParams, bounded
from nrmlc.tracker.records import NO_POSITIVE_ERROR

#: SCM's values (``demo.m`` and ``updateDic.m`` of huchuanlu/12_1).
LOCAL_SIZE = 6
LOCAL_STEP = 2
N_ATOMS = 50
OCCLUSION_ERROR = 0.04
OCCLUDED_BONUS = 3e-5
FIRST_FRAME_SHARE = 0.95
MAX_OCCLUDED_SHARE = 0.8
KMEANS_ITERATIONS = 10


@dataclass(frozen=True)
class GenerativeParams(CheckedParams):
    """The generative term's parameters (:mod:`nrmlc.tracker.generative`).

    Attributes
    ----------
    generative_weight : float
        log h gains this times log(similarity) (0: no term, the paper).
    generative_candidates : int
        Only this many most confident candidates are coded locally (SCM codes all); the others
        get the lowest of their similarities.
    generative_neighbours : int
        The local coder's nearest atoms.
    generative_lam : float
        The local coder's ridge (SCM codes with a lasso).
    generative_interval : int
        The template histogram is updated every this many frames (SCM's ``demo.m``: 5).
    generative_step : int
        The candidates' local patches are cut every this many px (SCM's ``demo.m``: 2).
    """

    generative_weight: float = bounded(10.0, 0, 1000)
    generative_candidates: int = bounded(20, 1, 100_000)
    generative_neighbours: int = bounded(5, 1, N_ATOMS)
    generative_lam: float = bounded(1.0, 0, 1000, low_open=True)
    generative_interval: int = bounded(5, 1, 1_000_000)  # beyond any video: never
    generative_step: int = bounded(4, 1, LOCAL_SIZE)


@functools.lru_cache(maxsize=8)
def _local_index(patch_size: int, step: int) -> np.ndarray:
    """(n_local, LOCAL_SIZE**2) positions in a patch vector of each local patch's pixels."""
    grid = np.arange(patch_size * patch_size).reshape(patch_size, patch_size)
    windows = sliding_window_view(grid, (LOCAL_SIZE, LOCAL_SIZE))[::step, ::step]
    return windows.reshape(-1, LOCAL_SIZE * LOCAL_SIZE)


def local_patches(patches: np.ndarray, patch_size: int, step: int = LOCAL_STEP) -> np.ndarray:
    """(n, patch_size**2) patch vectors -> (n, n_local, LOCAL_SIZE**2) float32 unit rows,
    the local patches every ``step`` px."""
    local = np.take(np.asarray(patches, dtype=np.float32), _local_index(patch_size, step), axis=1)
    norms = np.sqrt(np.einsum("nld,nld->nl", local, local))[:, :, None]
    local /= np.maximum(norms, np.float32(1e-12))
    return local


def kmeans_atoms(rng: np.random.Generator, points: np.ndarray, n_atoms: int) -> np.ndarray:
    """(n_atoms, dim) unit atoms: Lloyd's k-means of ``points`` (n, dim), seeded by ``rng``."""
    points = points.astype(np.float64)
    n_atoms = min(n_atoms, len(points))
    centres = points[rng.choice(len(points), n_atoms, replace=False)].copy()
    for _ in range(KMEANS_ITERATIONS):
        distances = ((points[:, None, :] - centres[None, :, :]) ** 2).sum(axis=2)
        labels = np.argmin(distances, axis=1)
        for atom in range(n_atoms):
            members = labels == atom
            if members.any():
                centres[atom] = points[members].mean(axis=0)
    norms = np.sqrt((centres ** 2).sum(axis=1, keepdims=True))
    return centres / np.maximum(norms, 1e-12)


class LocalHistogramModel:
    """SCM's generative model on NRMLC's coder (see the module docstring)."""

    def __init__(self, rng: np.random.Generator, target_patch: np.ndarray, patch_size: int,
                 neighbours: int, lam: float, step: int = LOCAL_STEP) -> None:
        self.patch_size = patch_size
        self.step = step
        # The atoms always come from SCM's dense grid, whatever grid the candidates are cut on.
        self.atoms = kmeans_atoms(rng, local_patches(target_patch[None, :], patch_size)[0], N_ATOMS)
        self.gram = np.ascontiguousarray(self.atoms @ self.atoms.T)
        self.neighbours = min(neighbours, len(self.atoms))
        self.lam = lam
        indices, codes, _ = self._code(local_patches(target_patch[None, :], patch_size, step))
        self.first_histogram = self._dense(indices[0], np.abs(codes[0]))
        self.histogram = self.first_histogram.copy()

    def _code(self, local: np.ndarray) -> tuple:
        """(n, n_local, dim) -> neighbours (n, n_local, k), codes (n, n_local, k), errors (n, n_local)."""
        return code_local_patches(local, self.atoms, self.gram, self.neighbours, self.lam)

    def _dense(self, indices: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(n_local, k) atom indices and values -> (n_local, n_atoms) histogram."""
        histogram = np.zeros((len(indices), len(self.atoms)))
        np.put_along_axis(histogram, indices, values, axis=1)
        return histogram

    def similarity(self, patches: np.ndarray) -> dict:
        """SCM's similarity of each candidate patch (n, patch_size**2) to the template histogram.

        Returns
        -------
        dict with ``similarity (n,)``, ``occluded_share (n,)``, ``neighbours (n, n_local, k)``
        and ``codes (n, n_local, k)``.
        """
        matched = match_local_histogram(local_patches(patches, self.patch_size, self.step), self.atoms, self.gram,
                                        self.neighbours, self.lam, self.histogram, OCCLUSION_ERROR)
        n_occluded = matched["n_occluded"]
        return dict(similarity=matched["overlap"] + OCCLUDED_BONUS * n_occluded,
                    occluded_share=n_occluded / matched["errors"].shape[1], neighbours=matched["neighbours"],
                    codes=matched["codes"])

    def update(self, neighbours: np.ndarray, codes: np.ndarray, occluded_share: float) -> None:
        """SCM's ``updateDic.m``: the first frame's histogram mixed with the result's
        (``neighbours``, ``codes``: (n_local, k)), unless the result is mostly occluded."""
        if occluded_share <= MAX_OCCLUDED_SHARE:
            self.histogram = (FIRST_FRAME_SHARE * self.first_histogram
                              + (1 - FIRST_FRAME_SHARE) * self._dense(neighbours, np.abs(codes)))
        else:
            self.histogram = self.first_histogram.copy()


class GenerativeTerm:
    """The generative term as a confidence term of the tracker: made from the first frame's target
    patch, it adds ``generative_weight * log(similarity)`` to the candidates' log h and updates its
    template histogram from the estimates.

    Parameters
    ----------
    rng : numpy.random.Generator
        The tracker's generator (seeds the k-means of the atoms).
    target_patch : (patch_size**2,) float32
        The first frame's target, as a unit patch vector.
    params : GenerativeParams
        With ``patch_size`` (a :class:`nrmlc.tracker.params.TrackerParams`).
    """

    def __init__(self, rng: np.random.Generator, target_patch: np.ndarray, params) -> None:
        self.params = params
        self.model = LocalHistogramModel(rng, target_patch, params.patch_size, params.generative_neighbours,
                                         params.generative_lam, params.generative_step)

    def add_to(self, candidates: np.ndarray, log_confidence: np.ndarray,
               error_positive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The candidates' similarity (n,) and their log h (n,) with the term added.

        The term counts only where the positives take part in the code (eps_pos below
        :data:`NO_POSITIVE_ERROR`); elsewhere a candidate gets the lowest term of those, so that a
        flat discriminative likelihood (the target hidden or lost) lets the cloud spread.
        """
        top = np.argsort(-log_confidence, kind="stable")[:self.params.generative_candidates]
        local = self.model.similarity(candidates[top])["similarity"]
        similarity = np.full(len(candidates), local.min())
        similarity[top] = local
        term = self.params.generative_weight * np.log(np.maximum(similarity, 1e-300))
        recognised = error_positive < NO_POSITIVE_ERROR
        floor = term[recognised].min() if recognised.any() else 0.0
        return similarity, log_confidence + np.where(recognised, term, floor)

    def learn(self, frame_index: int, estimate_patch: np.ndarray) -> None:
        """Every ``generative_interval`` frames, mix the estimate's (1, patch_size**2) local codes
        into the template histogram (coded again alone: keeping every candidate's local codes cost
        more than this)."""
        if (frame_index + 1) % self.params.generative_interval == 0:
            local = self.model.similarity(estimate_patch)
            self.model.update(local["neighbours"][0], local["codes"][0], float(local["occluded_share"][0]))
