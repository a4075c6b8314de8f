"""L1-APG: the real-time robust L1 tracker (Bao, Wu, Ling and Ji, CVPR 2012), as its authors' code
runs it.

The state is an affine map from template pixels to image pixels; each frame, 600 particles are
drawn around the last frame's resampled particles and cropped to 32x32 gray patches, each
whitened and scaled to unit norm. A patch is coded over ten target templates, a fixed template
(the first template over ten) and the 1024 trivial templates (the identity) by a few steps of an
accelerated proximal gradient method (:mod:`nrmlc.lineage.apg`); its likelihood is
``exp(-alpha ||y - T a_T - f a_f||^2)``, the error of the target part alone. The coding runs in
the order of a cheap bound, the distance to the templates' span, and stops once the bound falls
below a running threshold. The most likely particle is the answer. When the answer's angle to
its strongest template exceeds a threshold, the trivial coefficients are examined for occlusion:
without one, the weakest template is replaced by the answer; with one (or when no trivial
coefficient reaches the occlusion level, see below), updates pause for five frames and the
trivial coefficients' ridge is switched off.

Every value and step is that of the OTB benchmark's L1-APG (github.com/jwlim/tracker_benchmark,
``trackers/L1APG/``), which made the benchmark's ``*_L1APG.mat`` files:

- parameters: ``paraConfig_L1_APG.m``'s final values (600 particles, 32x32 template, ten
  templates, ``rel_std_afnv`` (0.005, 0.0005, 0.0005, 0.005, 4, 4), ``lambda`` (0.01, 0.001, 1),
  ``angle_threshold`` 30, ``Lip`` 8, ``Maxit`` 5) and ``L1TrackingBPR_APGup.m``'s constants
  (``alpha`` 50, the occlusion level 0.03, a quarter of the template as the largest occlusion,
  five frames without updates after one);
- the first state: ``run_L1APG.m`` (the box's corners ``(y, x)``, ``(y + h - 1, x)``,
  ``(y, x + w - 1)``) and ``corners2affine.m`` (the affine map taking the template's corners
  ``(1, 1)``, ``(rows, 1)``, ``(1, cols)`` to them);
- the templates: ``InitTemplates.m`` (the first at the box, the others at its corners moved by
  Gaussian noise of 0.6 pixels) and ``corner2image.m`` (crop, ``whitening.m``, divide by the norm
  plus ``eps``);
- frames: gray levels 0..255, not scaled (``L1TrackingBPR_APGup.m``: ``im2double`` of a frame
  already converted to double leaves it as it is);
- the crop: ``crop_candidates.m`` with the mex ``IMGaffine_c.c`` (:func:`crop_patches`);
  the sampling: ``draw_sample.m`` (Gaussian noise on ``log a11``, ``a12``, ``a21``, ``log a22``
  and the translation, its deviations ``rel_std_afnv`` times ``(1, s, s, 1, s, s)`` with ``s``
  the RMS of the 2x2 part); ``whitening.m`` and ``normalizeTemplates.m`` (zero mean, unit
  standard deviation plus 1e-14, then the norm plus 1e-14);
- the two stages, the choice, the resampling trigger and the template update:
  ``L1TrackingBPR_APGup.m``'s loop, with ``APGLASSOup.m`` (:func:`~nrmlc.lineage.apg.apg_lasso`),
  ``resample.m`` (:func:`resample_states`) and ``images_angle.m`` (:func:`images_angle`);
- boxes: the toolkit's box of an ``L1Aff`` state with ``tmplsize`` 32x32
  (:func:`~nrmlc.workbench.otb_results.l1_affine_boxes`), as ``run_L1APG.m`` stores the states.

Where the code does something unexpected, it is followed:

- the last particle in the bound's order is never coded (the loop runs while ``n < n_sample``);
- a particle whose patch lies wholly outside the frame is skipped; a patch of constant gray is
  given the bound 0 but, if reached, is coded like any other;
- when no trivial coefficient exceeds the occlusion level, ``max`` of the empty list of regions
  makes the test ``max(areas) < round(0.25 * 1024)`` empty, i.e. false, so the frame counts as
  occluded (no update, the ridge off for five frames); a template is replaced only when some
  region exists and none reaches 256 pixels;
- when no particle can be coded in a frame (all patches outside the frame), the answer is the
  new particle at the index of the previous frame's answer with that frame's coefficients
  (MATLAB keeps ``id_max`` and ``c_max`` from the previous frame); on the first tracked frame,
  where MATLAB stops with an error, the state stays.

Two branches of the code cannot run and are left out: ``sum(c(1:nT)) < 0`` (the coefficients
are projected on ``>= 0``) and ``map_aff + 1e-14`` (overwritten before it is used). The
template means, norms and identifiers kept for display are not kept.

Layout. MATLAB stores a patch column-major; ours are row-major. Every step except the occlusion
map is invariant to a permutation of the pixels applied to all vectors alike (means, norms, inner
products, the identity atoms); the occlusion map reshapes the trivial coefficients back to the
template's rows and columns, as MATLAB's ``reshape`` does with its own order.

Departures, none of them a choice of method:

- the random numbers (numpy's generator, not MATLAB's ``rng(0)`` stream);
- the gray conversion is OpenCV's (:func:`~nrmlc.lineage.affine.gray_frame`), which can differ
  from MATLAB's ``rgb2gray`` by one gray level on some pixels;
- the coding follows ``APGLASSOup.m``'s steps on the structure of the dictionary rather than its
  dense Gram matrix (rounding only), and particles are coded in parallel batches in the bound's
  order; the sequential threshold then decides which of them count, so the result is that of
  the sequential loop.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from scipy import ndimage

from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import LineageParams, bounded, check_affine_sigma, check_patch_arguments, check_template_size
from nrmlc.lineage.affine import EXACT_PARALLEL_FLAGS, gray_frame
from nrmlc.lineage.apg import apg_lasso
from nrmlc.lineage.apg import warm_up as _warm_up_apg
from nrmlc.workbench.otb_results import l1_affine_boxes, matlab_round

#: MATLAB's ``eps``.
EPS = float(np.finfo(np.float64).eps)

#: The constant ``whitening.m`` adds to the standard deviation and ``normalizeTemplates.m`` to the norm.
TINY = 1e-14

#: Particles coded per parallel batch in the bound's order; the threshold may stop the loop inside
#: a batch, so a larger batch wastes more coding and a smaller one runs more, shorter batches.
_BATCH = 48


@dataclass(frozen=True)
class TemplateTrackerParams(LineageParams):
    """What L1-APG, L1 and MTT share: particles, templates and the sampling's deviations (their
    MATLAB's ``sz_T``, ``nT``, ``rel_std_afnv``); each tracker's group sets its own values."""

    n_particles: int = bounded(600, 1, 100_000)
    #: Template rows and columns (``sz_T``).
    template_size: tuple = (32, 32)
    #: Target templates (``nT``).
    n_templates: int = bounded(10, 1, 100)
    #: Relative deviations of the sampling (``rel_std_afnv``): log a11, a12, a21, log a22, then the
    #: row and column translation; all but the first and fourth are multiplied by the state's scale.
    affine_sigma: tuple = (0.005, 0.0005, 0.0005, 0.005, 4.0, 4.0)

    def check_group(self) -> None:
        check_template_size(self)
        check_affine_sigma(self)


@dataclass(frozen=True)
class L1APGParams(TemplateTrackerParams):
    """L1-APG's parameters (the OTB benchmark's ``paraConfig_L1_APG.m`` and ``L1TrackingBPR_APGup.m``)."""

    n_particles: int = bounded(600, 2, 100_000)
    #: ``lambda(1)``: the weight on the target templates' coefficients.
    lambda_template: float = bounded(0.01, 0.0, 1e3)
    #: ``lambda(2)``: the l1 weight on the trivial templates' coefficients.
    lambda_trivial: float = bounded(0.001, 0.0, 1e3)
    #: ``lambda(3)``: the weight of the trivial coefficients' squared norm (switched off after an occlusion).
    mu: float = bounded(1.0, 0.0, 1e3)
    #: ``Lip``: the APG step is its inverse.
    lipschitz: float = bounded(8.0, 0.0, 1e6, low_open=True)
    #: ``Maxit``: APG steps per particle.
    max_iter: int = bounded(5, 0, 10_000)
    #: The likelihood's ``alpha``: ``exp(-alpha * error)``.
    alpha: float = bounded(50.0, 0.0, 1e6, low_open=True)
    #: Degrees between the answer and its strongest template above which the template step runs.
    angle_threshold: float = bounded(30.0, 0.0, 180.0)
    #: Deviation in pixels of the corner noise of the templates after the first (``InitTemplates.m``).
    template_jitter: float = bounded(0.6, 0.0, 1e3)
    #: ``im2bw``'s level on the trivial coefficients.
    occlusion_level: float = bounded(0.03, 0.0, 1e3)
    #: A region of the occlusion map this fraction of the template or larger is an occlusion.
    occlusion_fraction: float = bounded(0.25, 0.0, 1.0, low_open=True)
    #: Frames without template updates after an occlusion (``occlusionNf``).
    occlusion_frames: int = bounded(5, 0, 1_000_000)


def gray_levels(frame: np.ndarray) -> np.ndarray:
    """A BGR or gray uint8 frame as ``L1TrackingBPR_APGup.m`` reads it: ``rgb2gray``, as double,
    not scaled (:func:`~nrmlc.lineage.affine.gray_frame` with scale 1).

    Parameters
    ----------
    frame : (H, W, 3) or (H, W) uint8

    Returns
    -------
    (H, W) float64, C-contiguous
    """
    array = np.asarray(frame)
    if array.dtype != np.uint8 or not (array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 3)):
        raise ParameterError(f"frame must be (H, W) or (H, W, 3) uint8, got shape {array.shape} of {array.dtype}")
    return gray_frame(array, 1.0)


def box_corners(box) -> np.ndarray:
    """``run_L1APG.m``'s ``init_pos`` of a 1-based ``x, y, w, h`` box.

    Returns
    -------
    (2, 3) float64
        Rows: image row, image column; columns: the top-left, bottom-left and top-right pixels.
    """
    x, y, w, h = (float(v) for v in np.asarray(box, dtype=np.float64).ravel())
    return np.array([[y, y + h - 1, y], [x, x, x + w - 1]])


def corners_to_state(corners, template_size) -> np.ndarray:
    """``corners2affine.m``: the affine state taking the template's corners (1, 1), (rows, 1) and
    (1, cols) to ``corners``.

    Parameters
    ----------
    corners : (2, 3) array_like
        Image (row, column) of each corner, one per column.
    template_size : (2,) int
        ``(rows, cols)``.

    Returns
    -------
    (6,) float64
        ``a11, a12, a21, a22, tr, tc``: template pixel ``(r, c)`` goes to image row
        ``a11 r + a12 c + tr`` and column ``a21 r + a22 c + tc``.
    """
    rows, cols = (float(v) for v in template_size)
    image = np.vstack([np.asarray(corners, dtype=np.float64), np.ones(3)])
    template = np.array([[1.0, rows, 1.0], [1.0, 1.0, cols], [1.0, 1.0, 1.0]])
    matrix = np.linalg.solve(template.T, image.T).T  # image = matrix @ template
    return np.array([matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1], matrix[0, 2], matrix[1, 2]])


# Without fastmath: the row and column must be rounded from the same sums as the mex computes,
# ((a11 r + a12 c) + tr), with no fused multiply-add moving a value across a half.
@njit(**EXACT_PARALLEL_FLAGS)
def _crop_patches(frame, states, patches, in_range):
    height, width = frame.shape
    rows, cols = patches.shape[1], patches.shape[2]
    for particle in prange(states.shape[0]):
        a11, a12, a21, a22, tr, tc = states[particle]
        count = 0
        total = 0.0
        patch = patches[particle]
        # Column-major, as the mex sums the in-frame pixels.
        for col in range(cols):
            c = col + 1.0
            for row in range(rows):
                r = row + 1.0
                y = a11 * r + a12 * c + tr
                x = a21 * r + a22 * c + tc
                fy = np.floor(y)
                fx = np.floor(x)
                # round half away from zero, as the mex's own round()
                y = fy if (y - fy < 0.5 and fy >= 0) or (y - fy <= 0.5 and fy < 0) else fy + 1.0
                x = fx if (x - fx < 0.5 and fx >= 0) or (x - fx <= 0.5 and fx < 0) else fx + 1.0
                # The mex's test: the last image column counts as outside (x < width, not <=).
                if 1.0 <= y <= height and 1.0 <= x < width:
                    value = frame[int(y) - 1, int(x) - 1]
                    patch[row, col] = value
                    total += value
                    count += 1
                else:
                    patch[row, col] = np.nan
        in_range[particle] = count > 0
        if count < rows * cols:
            fill = total / count if count > 0 else np.nan
            for row in range(rows):
                for col in range(cols):
                    if np.isnan(patch[row, col]):
                        patch[row, col] = fill


def crop_patches(frame: np.ndarray, states: np.ndarray, template_size, out: np.ndarray | None = None):
    """Every state's patch of ``frame``, as ``crop_candidates.m`` with the mex ``IMGaffine_c.c``.

    Template pixel ``(r, c)`` (1-based) takes the frame's pixel at the rounded (halves away from
    zero) image point of the state, nearest neighbour; pixels whose point falls outside the frame
    (row outside ``1..H`` or column outside ``1..W-1``: the mex excludes the last column) take
    the mean of the patch's pixels inside it; a patch with none inside is NaN and not in range.

    Parameters
    ----------
    frame : (H, W) float64
        Gray frame, C-contiguous, finite.
    states : (n, 6) float64
        ``a11, a12, a21, a22, tr, tc`` (:func:`corners_to_state`), C-contiguous, finite.
    template_size : (2,) int
        ``(rows, cols)``.
    out : (n, rows, cols) float64, optional
        Filled and returned when given.

    Returns
    -------
    patches : (n, rows, cols) float64
    in_range : (n,) bool
    """
    out = check_patch_arguments(frame, states, "states", "a11, a12, a21, a22, tr, tc", template_size, out)
    in_range = np.empty(states.shape[0], dtype=np.bool_)
    _crop_patches(frame, states, out, in_range)
    return out, in_range


def crop_patches_reference(frame, states, template_size):
    """Plain numpy oracle of :func:`crop_patches` (same arguments; tests only), written from
    ``IMGaffine_r.m``, the MATLAB twin of the mex."""
    frame = np.asarray(frame, dtype=np.float64)
    rows, cols = (int(v) for v in template_size)
    r, c = np.meshgrid(np.arange(1, rows + 1, dtype=np.float64), np.arange(1, cols + 1, dtype=np.float64),
                       indexing="ij")
    patches = np.empty((len(states), rows, cols))
    in_range = np.zeros(len(states), dtype=bool)
    for k, (a11, a12, a21, a22, tr, tc) in enumerate(np.asarray(states, dtype=np.float64)):
        y = matlab_round(a11 * r + a12 * c + tr)
        x = matlab_round(a21 * r + a22 * c + tc)
        inside = (y >= 1) & (y <= frame.shape[0]) & (x >= 1) & (x < frame.shape[1])
        if not inside.any():
            patches[k] = np.nan
            continue
        in_range[k] = True
        values = frame[y[inside].astype(np.int64) - 1, x[inside].astype(np.int64) - 1]
        patches[k] = values.mean()
        patches[k][inside] = values
    return patches, in_range


def whiten(patches: np.ndarray):
    """``whitening.m`` then ``normalizeTemplates.m`` on rows, in place.

    Parameters
    ----------
    patches : (n, N) float64

    Returns
    -------
    patches : (n, N) float64
        Zero mean, divided by the standard deviation (``N - 1``) plus 1e-14, then by the norm plus 1e-14.
    mean, std, norm : (n,) float64
        The row means, the deviations (with 1e-14) and the norms (with 1e-14).
    """
    mean = patches.mean(axis=1)
    std = patches.std(axis=1, ddof=1) + TINY
    patches -= mean[:, None]
    patches /= std[:, None]
    norm = np.sqrt(np.einsum("ij,ij->i", patches, patches)) + TINY
    patches /= norm[:, None]
    return patches, mean, std, norm


def draw_states(states: np.ndarray, sigma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``draw_sample.m``: Gaussian noise on ``log a11``, ``a12``, ``a21``, ``log a22``, ``tr``, ``tc``.

    Parameters
    ----------
    states : (n, 6) float64
    sigma : (6,) float64
        The deviations.
    rng : numpy.random.Generator

    Returns
    -------
    (n, 6) float64
    """
    mean = states.copy()
    mean[:, 0] = np.log(mean[:, 0])
    mean[:, 3] = np.log(mean[:, 3])
    drawn = rng.standard_normal(states.shape) * sigma + mean
    drawn[:, 0] = np.exp(drawn[:, 0])
    drawn[:, 3] = np.exp(drawn[:, 3])
    return drawn


def resample_states(states: np.ndarray, likelihoods: np.ndarray, answer: np.ndarray) -> np.ndarray:
    """``resample.m``: each state repeated ``round(n p_i / sum(p))`` times in order, then padded
    with ``answer`` or cut to ``n`` rows; all ``answer`` when every likelihood is 0.

    Parameters
    ----------
    states : (n, 6) float64
    likelihoods : (n,) float64
    answer : (6,) float64

    Returns
    -------
    (n, 6) float64
    """
    n = len(states)
    total = likelihoods.sum()
    if total == 0:
        return np.repeat(answer[None], n, axis=0)
    counts = matlab_round(n * (likelihoods / total)).astype(np.int64)
    repeated = np.repeat(states, counts, axis=0)
    if len(repeated) < n:
        repeated = np.vstack([repeated, np.repeat(answer[None], n - len(repeated), axis=0)])
    return repeated[:n].copy()


def images_angle(first: np.ndarray, second: np.ndarray) -> float:
    """``images_angle.m``: the angle in degrees between two vectors, or 1 when the sum of their
    difference is below ``eps`` (a signed sum: the code's own test).

    Parameters
    ----------
    first, second : (N,) float64
    """
    if np.sum(first - second) < EPS:
        return 1.0
    first = first / np.sqrt(np.sum(first * first) + EPS)
    second = second / np.sqrt(np.sum(second * second) + EPS)
    return float(np.degrees(np.arccos(np.clip(first @ second, -1.0, 1.0))))


def largest_occluded_region(trivial: np.ndarray, level: float) -> int | None:
    """``L1TrackingBPR_APGup.m``'s occlusion map: the trivial coefficients above ``level``
    (``im2bw`` of a double image), closed by a 3x3 cross (``imclose``: outside the map counts as
    0 for the dilation and 1 for the erosion), and the area of its largest 8-connected region
    (``bwconncomp``, ``regionprops``).

    Parameters
    ----------
    trivial : (rows, cols) float64
    level : float

    Returns
    -------
    int or None
        None when the map is empty.
    """
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
    mask = np.asarray(trivial) > level
    closed = ndimage.binary_erosion(ndimage.binary_dilation(mask, structure=cross, border_value=0),
                                    structure=cross, border_value=1)
    labels, count = ndimage.label(closed, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        return None
    return int(np.bincount(labels.ravel())[1:].max())


class TemplateTracker:
    """What L1-APG, L1 and MTT set up alike: parameters, a seeded generator, compiled kernels
    (their solver's and the crop's, loaded before the first frame) and the crop's buffer.

    Parameters
    ----------
    params : TemplateTrackerParams, optional
        Of the subclass's :attr:`params_class` (default: its defaults).
    seed : int
        Seeds every random draw of the run.
    """

    params_class = TemplateTrackerParams

    def __init__(self, params: TemplateTrackerParams | None = None, seed: int = 0) -> None:
        self.params = params or self.params_class()
        self.rng = np.random.default_rng(seed)
        self.warm_up()
        crop_patches(np.zeros((2, 2)), np.zeros((1, 6)), (1, 1))
        p = self.params
        self._patches = np.empty((p.n_particles,) + tuple(p.template_size))

    @staticmethod
    def warm_up() -> None:
        """Load the solver's compiled kernels."""

    def _start(self, frame: np.ndarray, box) -> tuple[np.ndarray, np.ndarray]:
        """What every ``init`` begins with: ``box`` checked, as (4,) float64, and ``frame``'s gray levels."""
        box = np.asarray(box, dtype=np.float64).ravel()
        if box.size != 4 or not np.isfinite(box).all() or box[2] < 2 or box[3] < 2:
            raise ParameterError(f"box must be 4 finite numbers x, y, w, h with w, h >= 2, got {box.tolist()}")
        return box, gray_levels(frame)

    def _draw_particles(self) -> None:
        """Move every particle by the affine noise (``rel_std_afnv``), the shear and translation
        deviations scaled by the state's scale."""
        scale = np.sqrt(np.sum(self.state[:4] ** 2) / 2)
        sigma = np.asarray(self.params.affine_sigma, dtype=np.float64) * np.array([1.0, scale, scale, 1.0, scale, scale])
        self.samples = draw_states(self.samples, sigma, self.rng)

    def box(self) -> np.ndarray:
        """The toolkit's box of the current state (``L1Aff``, ``tmplsize`` the template size), (4,) float64."""
        return l1_affine_boxes(self.state[None], self.params.template_size)[0]


class L1APGTracker(TemplateTracker):
    """L1-APG with ``init(frame, box)`` and ``update(frame) -> box`` (boxes 1-based ``x, y, w, h``);
    :class:`TemplateTracker`'s parameters, ``L1APGParams``; the seed draws the templates' corner
    noise and the particles' noise."""

    name = "L1APG"
    params_class = L1APGParams
    warm_up = staticmethod(_warm_up_apg)

    def init(self, frame: np.ndarray, box) -> None:
        """Start on ``frame`` ((H, W, 3) BGR or (H, W) uint8) at ``box``."""
        p = self.params
        box, gray = self._start(frame, box)
        corners = box_corners(box)
        states = [corners_to_state(corners, p.template_size)]
        for _ in range(1, p.n_templates):
            states.append(corners_to_state(corners + self.rng.standard_normal((2, 3)) * p.template_jitter,
                                           p.template_size))
        patches, _ = crop_patches(gray, np.array(states), p.template_size)
        templates = patches.reshape(p.n_templates, -1)
        # corner2image.m: whitening, then the norm plus eps (not normalizeTemplates' 1e-14).
        templates -= templates.mean(axis=1, keepdims=True)
        templates /= templates.std(axis=1, ddof=1, keepdims=True) + TINY
        templates /= np.sqrt(np.einsum("ij,ij->i", templates, templates))[:, None] + EPS
        self.templates = templates
        self.fixed = templates[0] / p.n_templates
        self._set_dictionary()
        self.state = states[0]
        self.samples = np.repeat(self.state[None], p.n_particles, axis=0)
        self.occlusion_countdown = 0
        self.mu = p.mu
        self._previous_choice = None  # MATLAB's id_max and c_max, kept across frames

    def _set_dictionary(self) -> None:
        """The target atoms ``[T; f]`` and an orthonormal basis of their span (``Temp1`` is
        ``[T, f] pinv([T, f])``, the projector on it, with ``pinv``'s rank tolerance)."""
        self.targets = np.ascontiguousarray(np.vstack([self.templates, self.fixed[None]]))
        _, singular, right = np.linalg.svd(self.targets, full_matrices=False)
        tolerance = max(self.targets.shape) * np.spacing(singular.max())
        self._span = right[singular > tolerance]

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Track into ``frame``; the new box, (4,) float64."""
        p = self.params
        gray = gray_levels(frame)
        self._draw_particles()
        patches, in_range = crop_patches(gray, self.samples, p.template_size, out=self._patches)
        candidates = patches.reshape(p.n_particles, -1)
        with np.errstate(invalid="ignore"):
            candidates, _, _, _ = whiten(candidates)
        choice, likelihoods = self._code(candidates, in_range)
        if choice is None:
            choice = self._previous_choice
            if choice is None:
                return self.box()
        best, target_coefficients, trivial_coefficients = choice
        self._previous_choice = choice
        self.state = self.samples[best].copy()
        self.samples = resample_states(self.samples, likelihoods, self.state)
        self._update_templates(candidates[best], target_coefficients[:p.n_templates], trivial_coefficients)
        return self.box()

    def _code(self, candidates: np.ndarray, in_range: np.ndarray):
        """``L1TrackingBPR_APGup.m``'s two stages: the bound, then the coding in its order until
        the threshold stops it.

        Parameters
        ----------
        candidates : (n, N) float64
            Whitened, normalised patches (NaN rows: wholly outside the frame).
        in_range : (n,) bool

        Returns
        -------
        choice : (int, (k,) float64, (N,) float64) or None
            The most likely particle and its coefficients, None when none was coded.
        likelihoods : (n,) float64
            0 for the particles not coded.
        """
        p = self.params
        n = len(candidates)
        bound = np.zeros(n)
        usable = in_range & (np.abs(candidates).sum(axis=1) != 0)
        if usable.any():
            kept = candidates[usable]
            residual = kept - (kept @ self._span.T) @ self._span
            bound[usable] = np.exp(-p.alpha * np.einsum("ij,ij->i", residual, residual))
        order = np.argsort(-bound, kind="stable")  # MATLAB's sort 'descend' keeps ties in order
        sorted_bound = bound[order]
        undefined = np.isnan(candidates).any(axis=1)
        likelihoods = np.zeros(n)
        threshold = 0.0
        best_likelihood = -np.inf
        choice = None
        position = 0
        last = n - 1  # MATLAB's loop runs while n < n_sample: the last in order is never coded
        lambdas = (p.lambda_template, p.lambda_trivial, self.mu)
        while position < last and sorted_bound[position] >= threshold:
            # The threshold only grows, so what fails it now fails it later: the batch stops there.
            stop = position
            while stop < last and stop - position < _BATCH and sorted_bound[stop] >= threshold:
                stop += 1
            batch = order[position:stop]
            coded = batch[~undefined[batch]]
            target, trivial = apg_lasso(self.targets, np.ascontiguousarray(candidates[coded]), lambdas,
                                        p.lipschitz, p.max_iter)
            error = candidates[coded] - target @ self.targets
            errors = np.einsum("ij,ij->i", error, error)
            row = 0
            for k in range(position, stop):
                if not sorted_bound[k] >= threshold:
                    return choice, likelihoods
                index = order[k]
                if undefined[index]:
                    continue
                likelihood = np.exp(-p.alpha * errors[row])
                likelihoods[index] = likelihood
                threshold += likelihood / (2 * n - 1)
                if likelihood > best_likelihood:
                    best_likelihood = likelihood
                    choice = (int(index), target[row].copy(), trivial[row].copy())
                row += 1
            position = stop
        return choice, likelihoods

    def _update_templates(self, answer: np.ndarray, template_coefficients: np.ndarray,
                          trivial_coefficients: np.ndarray) -> None:
        """``L1TrackingBPR_APGup.m``'s template step (module docstring).

        Parameters
        ----------
        answer : (N,) float64
            The answer's whitened, normalised patch.
        template_coefficients : (nT,) float64
        trivial_coefficients : (N,) float64
        """
        p = self.params
        strongest = int(np.argmax(template_coefficients))
        angle = images_angle(answer, self.templates[strongest])
        self.occlusion_countdown -= 1
        if angle > p.angle_threshold and self.occlusion_countdown < 0:
            largest = largest_occluded_region(trivial_coefficients.reshape(p.template_size), p.occlusion_level)
            limit = matlab_round(p.occlusion_fraction * p.template_size[0] * p.template_size[1])
            if largest is not None and largest < limit:
                weakest = int(np.argmin(template_coefficients))
                self.templates[weakest] = answer
                self.templates /= (np.sqrt(np.einsum("ij,ij->i", self.templates, self.templates)) + TINY)[:, None]
                self._set_dictionary()
            else:
                self.occlusion_countdown = p.occlusion_frames
                self.mu = 0.0
        elif self.occlusion_countdown < 0:
            self.mu = p.mu
