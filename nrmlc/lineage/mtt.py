"""MTT: multi-task tracking, the L21 tracker (Zhang, Ghanem, Liu and Ahuja, CVPR 2012; IJCV 2013),
as its authors' code runs it where that code can be read, and as the paper describes it where not.

The state is an affine map from template pixels to image pixels; each frame, 600 particles are
drawn around the last frame's resampled particles and cropped to 32x32 gray patches, each
whitened and scaled to unit norm. All patches are coded together over ten target templates and
the 1024 trivial templates by the ``l2,1`` mixed-norm problem, solved by an accelerated proximal
gradient method (:mod:`nrmlc.lineage.l21`); a particle's likelihood is ``exp(-alpha ||y - D z||^2)``,
the error of its target part alone, and the most likely particle (among those whose template
coefficients do not sum below 0) is the answer. The templates carry weights: each frame the
weights are multiplied by ``exp`` of the answer's coefficients, and when the answer's similarity
to its strongest template falls below ``theta`` it replaces the template of least weight, which
takes the median weight; the weights are then normalised to sum 1 with none above 0.3, and the
templates to unit norm.

Sources, the OTB benchmark's MTT (github.com/jwlim/tracker_benchmark, ``trackers/MTT/``), which
made the benchmark's ``*_MTT.mat`` files. Its tracking loop ``MTT_Tracking.p`` and its solver
``MTL_APG_new.p`` are P-code and cannot be read; the rest is readable and followed:

- parameters: ``paraConfig_MTT.m`` (600 particles, 32x32 template, the ``L21`` tracker with
  ``lambda`` 0.01, ``eta`` 0.01, ``obj_fun_th`` 1e-3, ``iter_maxi`` 100, ``rel_std_afnv``
  (0.005, 0.0005, 0.0005, 0.005, 4, 4), ``m_theta`` 0.6);
- the first state: ``run_MTT.m`` (the box's corners ``(y, x)``, ``(y + h, x)``, ``(y, x + w)``:
  one pixel further than L1-APG's ``- 1``) and ``MTT_Toolbox/corners2afnv.m``;
- the templates: ``MTT_Toolbox/InitTemplates.m`` (ten: the box, then one corner coordinate moved
  by one pixel each, in its order: :data:`~nrmlc.lineage.l1.TEMPLATE_SHIFTS`) and
  ``corner2image.m`` (crop, ``gly_zmuv.m``, divide by the norm);
- frames: gray levels 0..255, not scaled (``InitTemplates.m``: ``double(rgb2gray(img))``);
- the crop: ``Seg_gly_crop.m`` with ``IMGaffine_r.m``, which is L1-APG's crop
  (:func:`~nrmlc.lineage.l1apg.crop_patches`) except that a patch wholly outside the frame is
  zeros, not NaN; the candidates' normalisation: ``gly_zmuv.m`` then ``normalizeTemplates.m``
  (:func:`~nrmlc.lineage.l1apg.whiten`);
- the sampling: ``Seg_draw_sample.m`` (:func:`~nrmlc.lineage.l1apg.draw_states`); the
  resampling: ``Seg_resample.m`` (:func:`~nrmlc.lineage.l1apg.resample_states`);
- the template step: ``images_angle.m`` (no ``eps``, unlike L1-APG's), ``normalizeWeights.m``
  and ``normalizeTemplates.m`` of ``MTT_Toolbox/``, the same files as the L1 tracker's release
  (:func:`~nrmlc.lineage.l1.images_angle`, :func:`~nrmlc.lineage.l1.normalize_weights`);
- boxes: the toolkit's box of an ``L1Aff`` state with ``tmplsize`` 32x32
  (:func:`~nrmlc.workbench.otb_results.l1_affine_boxes`), as ``run_MTT.m`` stores the states; with
  ``run_MTT.m``'s corners, the first state's box is one pixel wider and taller than the given box.

From the paper, because the code is P-code (CVPR 2012 Sec. 3, IJCV 2013 Sec. 3-4):

- the dictionary ``[D, I]`` (target templates and trivial templates, no fixed template, no
  non-negativity), the ``l2,1`` problem over all particles and its APG with the row-wise
  shrinkage (:mod:`nrmlc.lineage.l21`, whose docstring also states how ``obj_fun_th`` is read);
- the likelihood from the target part's reconstruction error and the answer as the most likely
  particle;
- the template update of the L1 tracker (Mei and Ling, ICCV 2009, PAMI 2011), which the paper
  adopts: the weights, the replacement of the least-weighted template by the answer, the median
  weight, the 0.3 cap. ``MTT_Toolbox/`` carries ``normalizeWeights.m``, which only this scheme
  uses, and its ``InitTemplates.m``, ``images_angle.m`` and ``Seg_*.m`` are the L1 tracker's, not
  L1-APG's. One part of that scheme is not taken: the L1 tracker scales each template to its
  weight (norms about 0.1); here the templates keep unit norm (``normalizeTemplates.m``, as
  L1-APG's code does after a replacement). With atoms of norm 0.1, the APG's fixed step ``eta``
  0.01 moves their coefficients by about ``2 eta 0.1^2 = 2e-4`` of the gradient per step, so in
  ``iter_maxi`` steps they hardly leave 0, the trivial templates take every patch and the
  likelihoods no longer tell the particles apart (measured on Car4, frames 151-250 from the
  ground truth: mean overlap 0.39, as a still box; 0.83 with unit-norm templates). The authors'
  tracker, which tracks, cannot be coding with such atoms.

Values neither the paper nor a readable file gives, taken from L1-APG's code
(``trackers/L1APG/L1TrackingBPR_APGup.m``), whose loop descends from the same L1 tracker:
``alpha`` 50 with the squared error; the sampling deviations ``rel_std_afnv`` times
``(1, s, s, 1, s, s)``, ``s`` the RMS of the state's 2x2 part; particles wholly outside the frame
or of constant gray get likelihood 0; a particle whose template coefficients sum below 0 (an
inverted pattern: the coefficients are not sign-constrained here, so the test matters, where in
L1-APG it cannot fire) is not chosen; the tracking starts at the second frame, the first being
the given box. ``m_theta`` (0.6, "[0 1] decide object template update") is read as a threshold
on the cosine similarity: the template step replaces a template when the cosine of
``images_angle`` between the answer and its strongest template is below it (an angle above
53.1 degrees); the L1 tracker's own test was an angle above 60 degrees.

Two guards where MATLAB would hang or stop, not a choice of method: ``normalizeWeights.m`` loops
forever when no weight between 0 and the cap is left to absorb the excess (weights underflowed to
0); :func:`~nrmlc.lineage.l1.normalize_weights` stops after a bounded number of rounds. When no
particle can be chosen, the state stays (MATLAB's ``id_max`` would be undefined). A template
patch of constant gray, which MATLAB divides into NaN, stays 0.

Layout. MATLAB stores a patch column-major; ours are row-major. Every step is invariant to a
permutation of the pixels applied to all vectors alike (means, norms, inner products, the
identity atoms and the ``l2,1`` rows over particles).

Departures, none of them a choice of method: the random numbers (numpy's generator, not
MATLAB's stream) and the gray conversion (OpenCV's, :func:`~nrmlc.lineage.affine.gray_frame`,
which can differ from ``rgb2gray`` by one gray level on some pixels).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import bounded, check_weight_cap
from nrmlc.lineage.l1 import TEMPLATE_SHIFTS, images_angle, normalize_weights, shifted_template_states
from nrmlc.lineage.l1apg import (TINY, TemplateTracker, TemplateTrackerParams, crop_patches, gray_levels, resample_states, whiten)
from nrmlc.lineage.l21 import l21_apg
from nrmlc.lineage.l21 import warm_up as _warm_up_l21


@dataclass(frozen=True)
class MTTParams(TemplateTrackerParams):
    """MTT's parameters (the OTB benchmark's ``paraConfig_MTT.m``; module docstring for the rest;
    the shared fields: :class:`~nrmlc.lineage.l1apg.TemplateTrackerParams`, the templates being
    the first ``n_templates`` of ``InitTemplates.m``'s ten)."""

    n_templates: int = bounded(10, 1, len(TEMPLATE_SHIFTS))
    #: ``lambda``: the weight of the l2,1 norm.
    lam: float = bounded(0.01, 0.0, 1e3)
    #: ``eta``: the APG's step.
    eta: float = bounded(0.01, 0.0, 1e3, low_open=True)
    #: ``obj_fun_th``: the APG stops once a step changes the objective by at most this fraction.
    objective_tolerance: float = bounded(1e-3, 0.0, 1.0)
    #: ``iter_maxi``: the most APG steps per frame.
    max_iter: int = bounded(100, 0, 100_000)
    #: The likelihood's ``alpha``: ``exp(-alpha * error)`` (L1-APG's value).
    alpha: float = bounded(50.0, 0.0, 1e6, low_open=True)
    #: ``m_theta``: a template is replaced when the answer's cosine similarity to its strongest
    #: template is below it.
    theta: float = bounded(0.6, -1.0, 1.0)
    #: ``normalizeWeights.m``'s cap on a template's weight.
    max_weight: float = 0.3
    #: After each template step the templates are scaled to unit norm ('unit', L1-APG's
    #: ``normalizeTemplates.m``) or, as the L1 tracker does, to their weights ('weight').
    template_norm: Literal["unit", "weight"] = "unit"

    def check_group(self) -> None:
        super().check_group()
        check_weight_cap(self, "max_weight")
        if self.template_norm not in ("unit", "weight"):
            raise ParameterError(f"MTTParams.template_norm must be 'unit' or 'weight', got {self.template_norm!r}")


def box_corners(box) -> np.ndarray:
    """``run_MTT.m``'s ``init_pos`` of a 1-based ``x, y, w, h`` box.

    Returns
    -------
    (2, 3) float64
        Rows: image row, image column; columns: the top-left, bottom-left and top-right corners
        ``(y, x)``, ``(y + h, x)``, ``(y, x + w)``.
    """
    x, y, w, h = (float(v) for v in np.asarray(box, dtype=np.float64).ravel())
    return np.array([[y, y + h, y], [x, x, x + w]])


class MTTTracker(TemplateTracker):
    """MTT (the L21 tracker) with ``init(frame, box)`` and ``update(frame) -> box`` (boxes 1-based
    ``x, y, w, h``); :class:`~nrmlc.lineage.l1apg.TemplateTracker`'s parameters, ``MTTParams``; the
    seed draws the particles' noise."""

    name = "MTT"
    params_class = MTTParams
    warm_up = staticmethod(_warm_up_l21)
    #: APG steps of the last frame.
    last_steps = 0

    def init(self, frame: np.ndarray, box) -> None:
        """Start on ``frame`` ((H, W, 3) BGR or (H, W) uint8) at ``box``."""
        p = self.params
        box, gray = self._start(frame, box)
        corners = box_corners(box)
        states = shifted_template_states(corners, p.n_templates, p.template_size)
        patches, in_range = crop_patches(gray, states, p.template_size)
        patches[~in_range] = 0.0  # IMGaffine_r.m's zeros
        templates = patches.reshape(p.n_templates, -1)
        # corner2image.m: gly_zmuv.m, then the norm (no constant added); a constant patch, which
        # MATLAB turns into NaN, stays 0.
        templates -= templates.mean(axis=1, keepdims=True)
        templates /= templates.std(axis=1, ddof=1, keepdims=True) + TINY
        norms = np.sqrt(np.einsum("ij,ij->i", templates, templates))
        templates /= np.where(norms > 0, norms, 1.0)[:, None]
        self.templates = np.ascontiguousarray(templates)
        self.weights = np.ones(p.n_templates)
        self.state = states[0]
        self.samples = np.repeat(self.state[None], p.n_particles, axis=0)

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Track into ``frame``; the new box, (4,) float64."""
        p = self.params
        gray = gray_levels(frame)
        self._draw_particles()
        patches, in_range = crop_patches(gray, self.samples, p.template_size, out=self._patches)
        patches[~in_range] = 0.0
        candidates, _, _, _ = whiten(patches.reshape(p.n_particles, -1))
        coefficients, _, self.last_steps = l21_apg(self.templates, candidates, p.lam, p.eta,
                                                   p.objective_tolerance, p.max_iter)
        likelihoods, usable = self._likelihoods(candidates, coefficients, in_range)
        eligible = usable & (coefficients.sum(axis=1) >= 0)
        if not eligible.any():
            self.samples = resample_states(self.samples, likelihoods, self.state)
            return self.box()
        best = int(np.argmax(np.where(eligible, likelihoods, -np.inf)))
        self.state = self.samples[best].copy()
        self.samples = resample_states(self.samples, likelihoods, self.state)
        self._update_templates(candidates[best].copy(), coefficients[best])
        return self.box()

    def _likelihoods(self, candidates: np.ndarray, coefficients: np.ndarray, in_range: np.ndarray):
        """``exp(-alpha ||y - D z||^2)`` per particle; 0 for those outside the frame or of constant gray.

        Parameters
        ----------
        candidates : (n, N) float64
        coefficients : (n, k) float64
        in_range : (n,) bool

        Returns
        -------
        likelihoods : (n,) float64
        usable : (n,) bool
            The particles in the frame and not of constant gray.
        """
        residual = candidates - coefficients @ self.templates
        errors = np.einsum("ij,ij->i", residual, residual)
        usable = in_range & (np.abs(candidates).sum(axis=1) != 0)
        return np.where(usable, np.exp(-self.params.alpha * errors), 0.0), usable

    def _update_templates(self, answer: np.ndarray, coefficients: np.ndarray) -> None:
        """The L1 tracker's template step (module docstring).

        Parameters
        ----------
        answer : (N,) float64
            The answer's whitened, unit-norm patch.
        coefficients : (k,) float64
            Its template coefficients.
        """
        p = self.params
        weights = self.weights * np.exp(coefficients)
        strongest = int(np.argmax(coefficients))
        angle = images_angle(answer, self.templates[strongest])
        if np.cos(np.radians(angle)) < p.theta:
            weakest = int(np.argmin(weights))
            weights[weakest] = 0.0
            weights[weakest] = np.median(weights)
            self.templates[weakest] = answer
        self.weights = normalize_weights(weights, p.max_weight)
        # Unit norm by default, not the weight (module docstring: with eta 0.01 weighted atoms barely move).
        norms = np.sqrt(np.einsum("ij,ij->i", self.templates, self.templates)) + TINY
        templates = self.templates / norms[:, None]
        if p.template_norm == "weight":
            templates *= self.weights[:, None]
        self.templates = np.ascontiguousarray(templates)
