"""A local-patch generative term (*ours*, after SCM's SGM; off by default).

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
code uses a positive template (``NRMLCTracker.encode``): where none does, the target is
hidden or lost, and a term that still ranks the background would hold the particle cloud
there instead of letting it spread and search (on the development sequence Jogging-2 it lost
the jogger behind the pole in 4 of 5 runs; docs/FINDINGS.md, round 13).
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from nrmlc.kernels.local_coding import code_local_patches

#: SCM's values (``demo.m`` and ``updateDic.m`` of huchuanlu/12_1).
LOCAL_SIZE = 6
LOCAL_STEP = 2
N_ATOMS = 50
OCCLUSION_ERROR = 0.04
OCCLUDED_BONUS = 3e-5
FIRST_FRAME_SHARE = 0.95
MAX_OCCLUDED_SHARE = 0.8
KMEANS_ITERATIONS = 10


def local_patches(patches: np.ndarray, patch_size: int) -> np.ndarray:
    """(n, patch_size**2) patch vectors -> (n, n_local, LOCAL_SIZE**2) float32 unit rows."""
    n = len(patches)
    images = patches.reshape(n, patch_size, patch_size)
    windows = sliding_window_view(images, (LOCAL_SIZE, LOCAL_SIZE), axis=(1, 2))[:, ::LOCAL_STEP, ::LOCAL_STEP]
    local = np.ascontiguousarray(windows.reshape(n, -1, LOCAL_SIZE * LOCAL_SIZE), dtype=np.float32)
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
                 neighbours: int, lam: float) -> None:
        self.patch_size = patch_size
        first = local_patches(target_patch[None, :], patch_size)[0]
        self.atoms = kmeans_atoms(rng, first, N_ATOMS)
        self.gram = np.ascontiguousarray(self.atoms @ self.atoms.T)
        self.neighbours = min(neighbours, len(self.atoms))
        self.lam = lam
        indices, codes, _ = self._code(first[None])
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
        indices, codes, errors = self._code(local_patches(patches, self.patch_size))
        visible = errors < OCCLUSION_ERROR                                  # (n, n_local)
        candidate = np.abs(codes) * visible[:, :, None]                     # (n, n_local, k)
        template = np.take_along_axis(self.histogram[None], indices, axis=2) * visible[:, :, None]
        candidate_sum = candidate.sum(axis=(1, 2))
        template_sum = (self.histogram.sum(axis=1)[None, :] * visible).sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            # Only the candidate's own atoms can contribute to the intersection.
            overlap = np.minimum(candidate / candidate_sum[:, None, None],
                                 template / template_sum[:, None, None]).sum(axis=(1, 2))
        overlap = np.where(candidate_sum > 0, np.nan_to_num(overlap), 0.0)
        n_occluded = (~visible).sum(axis=1)
        return dict(similarity=overlap + OCCLUDED_BONUS * n_occluded,
                    occluded_share=n_occluded / visible.shape[1], neighbours=indices, codes=codes)

    def update(self, neighbours: np.ndarray, codes: np.ndarray, occluded_share: float) -> None:
        """SCM's ``updateDic.m``: the first frame's histogram mixed with the result's
        (``neighbours``, ``codes``: (n_local, k)), unless the result is mostly occluded."""
        if occluded_share <= MAX_OCCLUDED_SHARE:
            self.histogram = (FIRST_FRAME_SHARE * self.first_histogram
                              + (1 - FIRST_FRAME_SHARE) * self._dense(neighbours, np.abs(codes)))
        else:
            self.histogram = self.first_histogram.copy()
