"""IVT: incremental visual tracking (Ross, Lim, Lin and Yang, IJCV 2008), as its authors' code runs it.

The state is an affine warp (:mod:`nrmlc.lineage.affine`); a particle filter (condensation)
proposes 600 warps around the previous particles; each candidate's 32x32 gray patch is scored by
its squared distance to an incremental PCA subspace of the target's past patches
(:mod:`nrmlc.lineage.subspace`), ``exp(-d^2 / condenssig)``; the best candidate is the answer,
and every five answers update the subspace with a forgetting factor.

Every value and step is that of the OTB benchmark's IVT (github.com/jwlim/tracker_benchmark,
``trackers/IVT/``), which made the benchmark's ``*_IVT.mat`` files:

- parameters: ``paraConfig_ivt.m`` (600 particles, ``condenssig`` 0.75, forgetting 0.95, batch 5,
  ``affsig`` (4, 4, 0.01, 0, 0.005, 0)) and ``run_IVT.m``'s defaults (32x32 template, 16 basis
  vectors, the plain L2 error);
- the first state: ``run_IVT.m`` (the box's centre and size rounded, scale ``w/32``);
- frames: gray, divided by 256 (``run_IVT.m``);
- a step: ``estwarp_condens.m`` (resample by the last weights, add noise in the geometric form,
  warp, project out the basis, weigh); the update: ``run_IVT.m``'s loop and ``sklm.m``.

One departure (docs/DEVIATIONS.md#lineage-trackers): the weights are normalised in log space.
MATLAB's ``exp`` underflows to 0 for every particle when all errors exceed about 560 x
``condenssig``, and its weights then become NaN; ours keep their order. Where any weight is
representable the two are equal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nrmlc.lineage.checks import LineageParams, bounded, check_affine_sigma, check_template_size
from nrmlc.lineage.affine import box_to_geom, geom_to_matrix, gray_frame, matrix_to_box, matrix_to_geom, warm_up, warp_patches
from nrmlc.lineage.subspace import Subspace


@dataclass(frozen=True)
class IVTParams(LineageParams):
    """IVT's parameters (the OTB benchmark's ``paraConfig_ivt.m`` and ``run_IVT.m``)."""

    n_particles: int = bounded(600, 1, 100_000)
    #: The error's temperature: weight ``exp(-||residual||^2 / condenssig)``.
    condenssig: float = bounded(0.75, 0.0, 1e6, low_open=True)
    #: Forgetting factor of the subspace update.
    forgetting: float = bounded(0.95, 0.0, 1.0, low_open=True)
    #: Answers per subspace update.
    batch_size: int = bounded(5, 1, 1000)
    #: Standard deviations of the geometric state's noise: x, y (pixels), scale, rotation, aspect, skew.
    affine_sigma: tuple = (4.0, 4.0, 0.01, 0.0, 0.005, 0.0)
    #: Template rows and columns.
    template_size: tuple = (32, 32)
    max_basis: int = bounded(16, 1, 1000)
    #: Frames are gray levels divided by this.
    intensity_scale: float = bounded(256.0, 0.0, 1e6, low_open=True)

    def check_group(self) -> None:
        check_affine_sigma(self)
        check_template_size(self)


class IVTTracker:
    """IVT with ``init(frame, box)`` and ``update(frame) -> box`` (boxes 1-based ``x, y, w, h``).

    Parameters
    ----------
    params : IVTParams, optional
    seed : int
        Seeds the particle filter's noise and resampling.
    """

    name = "IVT"

    def __init__(self, params: IVTParams | None = None, seed: int = 0) -> None:
        self.params = params or IVTParams()
        self.rng = np.random.default_rng(seed)
        warm_up()

    def init(self, frame: np.ndarray, box) -> None:
        """Start on ``frame`` ((H, W, 3) BGR or (H, W) uint8) at ``box``."""
        p = self.params
        gray = gray_frame(frame, p.intensity_scale)
        self.estimate = geom_to_matrix(box_to_geom(box, p.template_size[1], round_centre=True))
        first = warp_patches(gray, self.estimate[None].copy(), p.template_size)[0]
        self.subspace = Subspace(first.ravel())
        self.particles = None  # geometric states; the first step starts them all at the estimate
        self.weights = None
        self.batch = []
        self._patches = np.empty((p.n_particles,) + tuple(p.template_size))

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Track into ``frame``; the new box, (4,) float64."""
        p = self.params
        gray = gray_frame(frame, p.intensity_scale)
        n = p.n_particles
        if self.particles is None:
            particles = np.repeat(matrix_to_geom(self.estimate)[None], n, axis=0)
        else:
            cumulative = np.cumsum(self.weights)
            chosen = np.searchsorted(cumulative, self.rng.random(n), side="left")
            particles = self.particles[np.minimum(chosen, n - 1)]
        particles = particles + self.rng.standard_normal((n, 6)) * np.asarray(p.affine_sigma)
        patches = warp_patches(gray, np.ascontiguousarray(geom_to_matrix(particles)), p.template_size,
                               out=self._patches)
        errors = self.subspace.residuals(patches.reshape(n, -1))
        log_weights = -errors / p.condenssig
        weights = np.exp(log_weights - log_weights.max())
        self.weights = weights / weights.sum()
        self.particles = particles
        best = int(np.argmax(self.weights))
        self.estimate = geom_to_matrix(particles[best])
        self.batch.append(patches[best].ravel().copy())
        if len(self.batch) >= p.batch_size:
            self.subspace.update(np.stack(self.batch, axis=1), p.forgetting)
            self.subspace.truncate(p.max_basis)
            self.batch = []
        return matrix_to_box(self.estimate, p.template_size[::-1])[0]
