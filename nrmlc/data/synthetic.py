"""Deterministic synthetic videos with exact ground truth.

This is the project's embedded default dataset: the tests, the demo and
``make figures`` use it when no real data is given. A
:class:`SyntheticSpec` fixes everything (every random draw comes from
``np.random.default_rng(spec.seed)`` or, for per-frame noise, from a
generator seeded with ``(seed, frame index)``), so the same spec renders
bit-identical frames in any order, in any process.

The scene (frame size 240x320 by default):

- a cluttered background: smooth noise at two scales, a gentle gradient and
  a few textured distractor blobs; static (the camera does not move);
- a target of ~48x40 px with a high-contrast texture (blobs + stripes) that
  follows a curved Lissajous path at a few px/frame, changes scale smoothly
  (1.0 -> 1.3 -> 0.9 -> 1.0 over the video) and rotates by up to ~10 deg;
- a partial-occlusion episode: a textured occluder covers ~40% of the
  target box for ~15% of the frames;
- a global illumination change (gain dip and offset ramp) and mild noise.

Coordinates. The target is rendered with ``cv2.warpAffine``, whose pixel
(i, j) has its centre at the 0-based continuous point (j, i). A target of
current size (w, h) centred at (cx, cy) covers [cx - w/2, cx + w/2] x
[cy - h/2, cy + h/2] before rotation, and its ground-truth box is the
1-based OTB box ``(cx - w/2 + 1, cy - h/2 + 1, w, h)``, i.e. the project's
convention that an OTB box (x, y, w, h) has 0-based centre
(x - 1 + w/2, y - 1 + h/2). The box ignores rotation (centre +/- the
unrotated half sizes). A positive rotation maps the target's x axis to
(cos t, sin t) in image coordinates (x right, y down): clockwise on screen.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from nrmlc.config import PATCH_SIZE
from nrmlc.data.image import native_messages
from nrmlc.data.otb import GROUNDTRUTH_NAME, IMAGE_EXTENSIONS, IMAGE_FOLDER
from nrmlc.data.sequence import Sequence
from nrmlc.errors import DataError, ParameterError
from nrmlc.io import write_bytes, write_boxes

#: Side of the template grid the state's scale refers to (scale = w / 32).
TEMPLATE_SIDE = PATCH_SIZE

#: Target texture resolution, in texels per pixel at scale 1: oversampling
#: keeps the texture sharp when the target grows to 1.3x.
_TEXELS_PER_PIXEL = 2.0

#: Keep the target this many pixels inside the frame at its largest extent.
_BORDER_MARGIN = 2.0
#: Bounds that keep a spec's arrays (per-frame states, static layers) in memory.
MAX_FRAMES = 1_000_000
MAX_SIDE = 8192
MAX_SEQUENCES = 1000


@dataclass(frozen=True)
class SyntheticSpec:
    """Everything that defines a synthetic sequence (frozen, hashable, picklable).

    Attributes
    ----------
    name : sequence name.
    seed : non-negative seed of every random draw.
    n_frames : number of frames (>= 2).
    frame_height, frame_width : frame size in pixels.
    target_width, target_height : target size in pixels at scale 1.
    translation_amplitude_x, translation_amplitude_y : peak distance (px) of
        the target centre from the frame centre along its Lissajous path
        (reduced automatically if the target would leave the frame).
    motion_period : frames per loop of the path (sets the speed: about
        2*pi*amplitude/period px/frame, ~4 px/frame by default).
    scale_peak, scale_trough : the scale goes 1 -> peak -> trough -> 1.
    rotation_amplitude_deg : peak rotation in degrees.
    illumination_amplitude : the global gain dips to ``1 - this`` mid-video.
    occlusion_start, occlusion_duration : start and length of the occlusion
        episode, as fractions of the video (duration 0: no occlusion).
    occlusion_fraction : fraction of the target box the occluder covers.
    noise_std : standard deviation of the per-frame (uniform) noise, in
        intensity units (the frame range is [0, 1]).
    n_distractors : number of textured blobs in the background.
    """

    name: str = "synth"
    seed: int = 0
    n_frames: int = 120
    frame_height: int = 240
    frame_width: int = 320
    target_width: float = 48.0
    target_height: float = 40.0
    translation_amplitude_x: float = 70.0
    translation_amplitude_y: float = 40.0
    motion_period: float = 120.0
    scale_peak: float = 1.3
    scale_trough: float = 0.9
    rotation_amplitude_deg: float = 10.0
    illumination_amplitude: float = 0.25
    occlusion_start: float = 0.55
    occlusion_duration: float = 0.15
    occlusion_fraction: float = 0.4
    noise_std: float = 0.01
    n_distractors: int = 6

    def __post_init__(self) -> None:
        integers = ("seed", "n_frames", "frame_height", "frame_width", "n_distractors")
        for name in integers:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ParameterError(f"SyntheticSpec {self.name!r}: {name} must be an integer, got {value!r}")
        for field_name, value in vars(self).items():
            if field_name != "name" and field_name not in integers and (
                    isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
                    or not np.isfinite(value)):
                raise ParameterError(f"SyntheticSpec {self.name!r}: {field_name} must be a finite number, "
                                     f"got {value!r}")
        checks = [
            (self.seed >= 0, "seed must be >= 0"),
            (2 <= self.n_frames <= MAX_FRAMES, f"n_frames must be in 2..{MAX_FRAMES}"),
            (16 <= self.frame_height <= MAX_SIDE and 16 <= self.frame_width <= MAX_SIDE,
             f"frame size must be 16x16 to {MAX_SIDE}x{MAX_SIDE}"),
            (self.target_width >= 4 and self.target_height >= 4, "target size must be at least 4x4 px"),
            (self.translation_amplitude_x >= 0 and self.translation_amplitude_y >= 0,
             "translation amplitudes must be >= 0"),
            (self.motion_period > 0, "motion_period must be > 0"),
            (self.scale_peak > 0 and self.scale_trough > 0, "scales must be > 0"),
            (0 <= self.rotation_amplitude_deg <= 45, "rotation_amplitude_deg must be in [0, 45]"),
            (0 <= self.illumination_amplitude < 1, "illumination_amplitude must be in [0, 1)"),
            (0 <= self.occlusion_start <= 1 and 0 <= self.occlusion_duration <= 1,
             "occlusion_start and occlusion_duration must be in [0, 1]"),
            (0 < self.occlusion_fraction <= 1, "occlusion_fraction must be in (0, 1]"),
            (self.noise_std >= 0, "noise_std must be >= 0"),
            (self.n_distractors >= 0, "n_distractors must be >= 0"),
        ]
        for ok, message in checks:
            if not ok:
                raise ParameterError(f"SyntheticSpec {self.name!r}: {message}")

    def estimated_bytes(self) -> float:
        """Memory a :class:`SyntheticSequence` of this spec takes while it is built and used: about
        30 float64 per frame (states, boxes, illumination and their intermediates) and a few
        float32 layers of the frame's and the target texture's size."""
        texels = (_TEXELS_PER_PIXEL**2) * self.target_width * self.target_height
        return 256.0 * self.n_frames + 40.0 * self.frame_height * self.frame_width + 64.0 * texels


# ---------------------------------------------------------------- textures
def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> np.ndarray:
    """(H, W) float32 Gaussian-blurred white noise, rescaled to unit std."""
    noise = rng.standard_normal(shape).astype(np.float32)
    noise = cv2.GaussianBlur(noise, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return noise / max(float(noise.std()), 1e-6)


def _target_texture(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """(height, width) float32 in [0.05, 0.95]: blobs + stripes, high contrast."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    angle = rng.uniform(0, math.pi)
    period = rng.uniform(0.25, 0.45) * width
    stripes = np.sin(2 * math.pi * (xx * math.cos(angle) + yy * math.sin(angle)) / period + rng.uniform(0, 2 * math.pi))
    blobs = np.zeros((height, width), np.float32)
    for _ in range(5):
        centre_x, centre_y = rng.uniform(0.1, 0.9) * width, rng.uniform(0.1, 0.9) * height
        sigma = rng.uniform(0.1, 0.22) * width
        sign = 1.0 if rng.random() < 0.5 else -1.0
        blobs += sign * np.exp(-((xx - centre_x) ** 2 + (yy - centre_y) ** 2) / (2 * sigma**2))
    texture = 0.9 * stripes + 1.2 * blobs + 0.3 * _smooth_noise(rng, (height, width), 2.0 * _TEXELS_PER_PIXEL)
    low, high = float(texture.min()), float(texture.max())
    return (0.05 + 0.9 * (texture - low) / max(high - low, 1e-6)).astype(np.float32)


def _occluder_texture(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """(height, width) float32: dark diagonal bars, unlike the target and background."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    bars = np.sin(2 * math.pi * (xx + yy) / rng.uniform(6.0, 10.0))
    return (0.2 + 0.1 * bars + 0.03 * _smooth_noise(rng, (height, width), 1.0)).astype(np.float32)


def _background(rng: np.random.Generator, height: int, width: int, n_distractors: int) -> np.ndarray:
    """(height, width) float32 cluttered background, mostly in [0.2, 0.7]."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    angle = rng.uniform(0, 2 * math.pi)
    gradient = 0.1 * (xx / width * math.cos(angle) + yy / height * math.sin(angle))
    fine = _smooth_noise(rng, (height, width), 1.5)
    background = 0.45 + 0.08 * _smooth_noise(rng, (height, width), 12.0) + 0.04 * fine + gradient
    # Distractors: textured ellipses of target-like size, so that clutter competes with the target.
    for _ in range(n_distractors):
        mask = np.zeros((height, width), np.uint8)
        centre = (int(rng.integers(0, width)), int(rng.integers(0, height)))
        axes = (int(rng.integers(6, 24)), int(rng.integers(6, 24)))
        cv2.ellipse(mask, centre, axes, float(rng.uniform(0, 180)), 0, 360, 255, -1, cv2.LINE_AA)
        alpha = mask.astype(np.float32) / 255.0
        value = rng.uniform(0.15, 0.8) + 0.12 * np.sin(xx / rng.uniform(2.0, 5.0) + yy / rng.uniform(2.0, 5.0))
        background = background * (1 - alpha) + value * alpha
    return np.ascontiguousarray(background, dtype=np.float32)


def _smooth_keyframes(u: np.ndarray, knots: list[tuple[float, float]]) -> np.ndarray:
    """Cosine interpolation through ``(u, value)`` knots: smooth, flat at each knot."""
    out = np.empty_like(u)
    for (u0, v0), (u1, v1) in zip(knots[:-1], knots[1:]):
        inside = (u >= u0) & (u <= u1)
        phase = (u[inside] - u0) / (u1 - u0)
        out[inside] = v0 + (v1 - v0) * (1 - np.cos(math.pi * phase)) / 2
    return out


# ---------------------------------------------------------------- sequence
class SyntheticSequence(Sequence):
    """A :class:`~nrmlc.data.Sequence` rendered on demand from a :class:`SyntheticSpec`.

    Parameters
    ----------
    spec : the scene description.
    init_box : optional (4,) override of the initial box.

    Attributes
    ----------
    spec : SyntheticSpec
    true_states : (n_frames, 6) float64
        ``[cx, cy, scale, rotation_rad, aspect, skew]`` per frame: 0-based
        continuous centre, ``scale = w / 32`` (32x32 template grid),
        ``aspect = h / w``, skew 0.
    occluded : (n_frames,) bool, True during the occlusion episode.
    illumination : (n_frames, 2) float64 global ``gain, offset`` per frame.

    Notes
    -----
    Only the static layers (background, textures: ~0.3 MB at 240x320) are
    kept; frames are rendered when read (~1 ms each at 240x320).
    """

    def __init__(self, spec: SyntheticSpec, init_box=None) -> None:
        self.spec = spec
        rng = np.random.default_rng(spec.seed)
        height, width = spec.frame_height, spec.frame_width
        n_frames = spec.n_frames
        frames = np.arange(n_frames, dtype=np.float64)
        progress = frames / (n_frames - 1)  # 0 -> 1 over the video

        # Scale, rotation and illumination follow the video's length; the path
        # follows motion_period so that the speed (px/frame) does not depend on it.
        scale = _smooth_keyframes(
            progress, [(0.0, 1.0), (0.35, spec.scale_peak), (0.75, spec.scale_trough), (1.0, 1.0)]
        )
        max_rotation = math.radians(spec.rotation_amplitude_deg)
        rotation = max_rotation * np.sin(3 * math.pi * progress) * (1.0 if rng.random() < 0.5 else -1.0)
        gain = 1.0 - spec.illumination_amplitude * np.sin(math.pi * progress)
        offset = 0.2 * spec.illumination_amplitude * (progress - 0.5)

        # Largest half extent of the rotated target: the path must keep it inside the frame.
        max_scale = max(1.0, spec.scale_peak, spec.scale_trough)
        cos_r, sin_r = math.cos(max_rotation), math.sin(max_rotation)
        half_x = max_scale * (spec.target_width * cos_r + spec.target_height * sin_r) / 2
        half_y = max_scale * (spec.target_width * sin_r + spec.target_height * cos_r) / 2
        room_x = width / 2 - half_x - _BORDER_MARGIN
        room_y = height / 2 - half_y - _BORDER_MARGIN
        if room_x < 0 or room_y < 0:
            raise ParameterError(
                f"SyntheticSpec {spec.name!r}: a {spec.target_width:g}x{spec.target_height:g} target "
                f"(scale up to {max_scale:g}) does not fit in a {width}x{height} frame"
            )
        amplitude_x = min(spec.translation_amplitude_x, room_x)
        amplitude_y = min(spec.translation_amplitude_y, room_y)
        path_phase = 2 * math.pi * frames / spec.motion_period
        centre_x = (width - 1) / 2 + amplitude_x * np.sin(path_phase + rng.uniform(0, 2 * math.pi))
        centre_y = (height - 1) / 2 + amplitude_y * np.sin(2 * path_phase + rng.uniform(0, 2 * math.pi))

        box_width = spec.target_width * scale
        box_height = spec.target_height * scale
        self.true_states = np.column_stack([
            centre_x, centre_y, box_width / TEMPLATE_SIDE, rotation,
            np.full(n_frames, spec.target_height / spec.target_width), np.zeros(n_frames),
        ])
        groundtruth = np.column_stack([
            centre_x - box_width / 2 + 1, centre_y - box_height / 2 + 1, box_width, box_height,
        ])
        self.illumination = np.column_stack([gain, offset])

        self.occluded = np.zeros(n_frames, dtype=bool)
        if spec.occlusion_duration > 0:
            start = min(int(round(spec.occlusion_start * n_frames)), n_frames - 1)
            length = max(1, int(round(spec.occlusion_duration * n_frames)))
            self.occluded[start:start + length] = True
        self._occluder_side = int(rng.integers(0, 4))  # 0 left, 1 right, 2 top, 3 bottom

        texture_height = int(round(_TEXELS_PER_PIXEL * spec.target_height))
        texture_width = int(round(_TEXELS_PER_PIXEL * spec.target_width))
        # Two layers warped in one call: texture and coverage (alpha). Outside
        # the texture both are 0, so the warped texture is premultiplied by alpha.
        self._target_layers = np.dstack([
            _target_texture(rng, texture_height, texture_width),
            np.ones((texture_height, texture_width), np.float32),
        ])
        occluder_side_px = int(math.ceil(1.6 * max_scale * max(spec.target_width, spec.target_height))) + 4
        self._occluder = _occluder_texture(rng, occluder_side_px, occluder_side_px)
        self._background = _background(rng, height, width, spec.n_distractors)

        super().__init__(spec.name, None, groundtruth, n_frames=n_frames, init_box=init_box)

    def _content_identity(self) -> str:
        return f"synthetic:{self.spec!r}"

    def __reduce__(self):
        # Pickle the spec, not the rendered layers: they are rebuilt identically.
        return (_rebuild_synthetic, (self.spec, self._init_box_override))

    def __copy__(self) -> "SyntheticSequence":
        clone = object.__new__(type(self))
        clone.__dict__.update(self.__dict__)
        return clone

    def _read_image(self, index: int) -> np.ndarray:
        return self.render(index)

    def _target_affine(self, index: int) -> np.ndarray:
        """(2, 3) affine map from texture coordinates to 0-based frame coordinates."""
        centre_x, centre_y, scale, rotation, aspect, _ = self.true_states[index]
        box_width = scale * TEMPLATE_SIDE
        box_height = aspect * box_width
        texture_height, texture_width = self._target_layers.shape[:2]
        cos_r, sin_r = math.cos(rotation), math.sin(rotation)
        linear = np.array([[cos_r, -sin_r], [sin_r, cos_r]]) @ np.diag(
            [box_width / texture_width, box_height / texture_height]
        )
        texture_centre = np.array([(texture_width - 1) / 2, (texture_height - 1) / 2])
        translation = np.array([centre_x, centre_y]) - linear @ texture_centre
        return np.column_stack([linear, translation])

    def _occluder_rect(self, index: int) -> tuple[int, int, int, int]:
        """``(x0, y0, x1, y1)`` pixel bounds (end exclusive) of the occluder in frame ``index``.

        It covers ``occlusion_fraction`` of the target box on one side and
        sticks out beyond the box, like a larger object in front.
        """
        centre_x, centre_y, scale, _, aspect, _ = self.true_states[index]
        w = scale * TEMPLATE_SIDE
        h = aspect * w
        left, top, right, bottom = centre_x - w / 2, centre_y - h / 2, centre_x + w / 2, centre_y + h / 2
        fraction = self.spec.occlusion_fraction
        if self._occluder_side == 0:
            left, right = left - 0.3 * w, left + fraction * w
        elif self._occluder_side == 1:
            left, right = right - fraction * w, right + 0.3 * w
        elif self._occluder_side == 2:
            top, bottom = top - 0.3 * h, top + fraction * h
        else:
            top, bottom = bottom - fraction * h, bottom + 0.3 * h
        height, width = self.spec.frame_height, self.spec.frame_width
        # A pixel belongs to the rectangle when its centre does (pixel i spans [i - 0.5, i + 0.5]).
        x0, x1 = (int(np.clip(math.floor(v + 0.5), 0, width)) for v in (left, right))
        y0, y1 = (int(np.clip(math.floor(v + 0.5), 0, height)) for v in (top, bottom))
        return x0, y0, x1, y1

    def render(self, index: int, draw_target: bool = True, draw_occluder: bool = True) -> np.ndarray:
        """Render frame ``index`` as (H, W) uint8 gray.

        ``draw_target=False`` / ``draw_occluder=False`` leave the target or
        the occluder out (with the same illumination and noise), which lets
        tests locate exactly what each layer changes.
        """
        spec = self.spec
        height, width = spec.frame_height, spec.frame_width
        image = self._background.copy()

        if draw_target:
            affine = self._target_affine(index)
            texture_height, texture_width = self._target_layers.shape[:2]
            corners = np.array([[-0.5, -0.5, 1], [texture_width - 0.5, -0.5, 1],
                                [-0.5, texture_height - 0.5, 1], [texture_width - 0.5, texture_height - 0.5, 1]])
            mapped = corners @ affine.T
            # Warp into the target's bounding region only: far cheaper than the whole frame.
            x0 = max(int(math.floor(mapped[:, 0].min())) - 1, 0)
            y0 = max(int(math.floor(mapped[:, 1].min())) - 1, 0)
            x1 = min(int(math.ceil(mapped[:, 0].max())) + 2, width)
            y1 = min(int(math.ceil(mapped[:, 1].max())) + 2, height)
            shifted = affine.copy()
            shifted[:, 2] -= (x0, y0)
            layers = cv2.warpAffine(
                self._target_layers, shifted, (x1 - x0, y1 - y0),
                flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0,
            )
            region = image[y0:y1, x0:x1]
            region *= 1.0 - layers[:, :, 1]
            region += layers[:, :, 0]

        if draw_occluder and self.occluded[index]:
            x0, y0, x1, y1 = self._occluder_rect(index)
            image[y0:y1, x0:x1] = self._occluder[: y1 - y0, : x1 - x0]

        gain, offset = self.illumination[index]
        image *= np.float32(gain)
        image += np.float32(offset)
        if spec.noise_std > 0:
            # Seeded per frame: frames are identical whatever order they are read in.
            # Uniform rather than Gaussian noise: 5x cheaper to draw, same std.
            noise_rng = np.random.default_rng([spec.seed, 1, index])
            noise = noise_rng.random((height, width), dtype=np.float32)
            noise -= 0.5
            image += np.float32(spec.noise_std * math.sqrt(12.0)) * noise
        image *= 255.0
        image += 0.5
        np.clip(image, 0.0, 255.0, out=image)
        return image.astype(np.uint8)


def _rebuild_synthetic(spec: SyntheticSpec, init_box) -> SyntheticSequence:
    return SyntheticSequence(spec, init_box=init_box)


# Target sizes (w, h) cycled through by synthetic_suite, so the suite mixes aspects.
_SUITE_TARGET_SIZES = ((48.0, 40.0), (40.0, 52.0), (56.0, 36.0))


def synthetic_suite(
    n_frames: int = 120,
    size: tuple[int, int] = (240, 320),
    n_sequences: int = 3,
    seed: int = 0,
) -> list[SyntheticSequence]:
    """A small fixed set of synthetic sequences named ``synth-01``, ``synth-02``, ...

    Parameters
    ----------
    n_frames : frames per sequence.
    size : ``(height, width)`` of the frames. The target size and motion
        amplitudes scale with ``min(height / 240, width / 320)``, so a smaller
        frame shows the same scene, smaller.
    n_sequences : how many sequences.
    seed : suite seed; each sequence gets its own seed derived from it.

    Returns
    -------
    list of SyntheticSequence

    Raises
    ------
    ParameterError
        For a value out of range, or when the sequences together would need
        more memory than is available (they are all held at once; see
        :func:`suite_specs` to build them one at a time).
    """
    from nrmlc.resources import available_memory, gigabytes

    specs = suite_specs(n_frames, size, n_sequences, seed)
    need = sum(spec.estimated_bytes() for spec in specs)
    limit = available_memory()
    if limit is not None and need > limit:
        raise ParameterError(f"synthetic_suite: {n_sequences} sequences of {n_frames} frames need about "
                             f"{gigabytes(need)} of memory together, {gigabytes(limit)} is available")
    return [SyntheticSequence(spec) for spec in specs]


def suite_specs(
    n_frames: int = 120,
    size: tuple[int, int] = (240, 320),
    n_sequences: int = 3,
    seed: int = 0,
) -> list[SyntheticSpec]:
    """The specs of :func:`synthetic_suite` (same arguments), without building any sequence:
    for callers that build and write them one at a time (``nrmlc synth``)."""
    for name, value, low, high in (("n_sequences", n_sequences, 1, MAX_SEQUENCES),
                                   ("n_frames", n_frames, 2, MAX_FRAMES), ("seed", seed, 0, 2**63 - 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ParameterError(f"synthetic_suite: {name} must be an integer in {low}..{high}, got {value!r}")
    if isinstance(size, (str, bytes)) or len(size) != 2 or any(
            isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in size):
        raise ParameterError(f"synthetic_suite: size must be two integers (height, width), got {size!r}")
    height, width = (int(v) for v in size)
    zoom = min(height / 240.0, width / 320.0)
    sequences = []
    for k in range(n_sequences):
        target_width, target_height = _SUITE_TARGET_SIZES[k % len(_SUITE_TARGET_SIZES)]
        spec = SyntheticSpec(
            name=f"synth-{k + 1:02d}",
            seed=int(np.random.SeedSequence([seed, k]).generate_state(1)[0]),
            n_frames=n_frames,
            frame_height=height,
            frame_width=width,
            target_width=target_width * zoom,
            target_height=target_height * zoom,
            translation_amplitude_x=SyntheticSpec.translation_amplitude_x * zoom,
            translation_amplitude_y=SyntheticSpec.translation_amplitude_y * zoom,
            motion_period=SyntheticSpec.motion_period,
        )
        sequences.append(spec)
    return sequences


def check_otb_destination(folder: str | os.PathLike, n_frames: int) -> None:
    """Refuse, before anything is written, a folder :func:`write_otb_sequence` must not replace.

    Nothing there, or an earlier sequence of the same length as this function
    writes them (``img/0001.png ...`` and ``groundtruth_rect.txt``, nothing
    else), may be replaced; anything else is the user's and is refused.

    Raises
    ------
    DataError
        Naming the folder or the first file that is not ours.
    """
    folder = Path(folder)
    if not os.path.lexists(folder):
        return
    if folder.is_symlink():
        raise DataError(f"{folder}: is a symbolic link (it would be replaced by a folder); write to its target "
                        f"or choose another --out")
    if not folder.is_dir():
        raise DataError(f"{folder}: exists and is not a folder; choose another --out")
    image_folder = folder / IMAGE_FOLDER
    ours = {f"{index + 1:04d}.png" for index in range(n_frames)}
    for entry in sorted(folder.iterdir()):
        if entry.name == IMAGE_FOLDER and entry.is_dir() and not entry.is_symlink():
            continue
        if entry.name == GROUNDTRUTH_NAME and entry.is_file() and not entry.is_symlink():
            continue
        raise DataError(f"{entry}: not part of a sequence this writer made; use an empty folder "
                        f"(nothing was written)")
    if image_folder.is_dir():
        for entry in sorted(image_folder.iterdir()):
            if entry.name in ours and entry.is_file() and not entry.is_symlink():
                continue
            what = "already holds other frames" if entry.suffix.lower() in IMAGE_EXTENSIONS else "holds other files"
            raise DataError(f"{image_folder}: {what} ({entry.name}, ...); use an empty folder (nothing was written)")


def write_otb_sequence(sequence: Sequence, folder: str | os.PathLike) -> Path:
    """Write any sequence as an OTB folder (lossless PNG frames + ground truth), all or nothing.

    Writes ``folder/img/0001.png, ...`` (the frames as stored: gray or colour,
    8 or 16 bit) and ``folder/groundtruth_rect.txt`` (unannotated frames as
    ``0,0,0,0``; exact values). Everything goes to a hidden temporary folder
    beside ``folder`` first, which is renamed into place once complete (an
    earlier sequence there is moved aside in the same breath, then removed):
    an error, a full disk or an interrupt leaves the earlier folder as it was
    and no temporary folder. Reading the folder back with
    :func:`~nrmlc.data.open_sequence` gives identical frames.

    Returns
    -------
    Path of the folder.

    Raises
    ------
    DataError
        If ``folder`` holds anything but an earlier sequence of the same length
        (:func:`check_otb_destination`), checked before anything is written.
    OutputError
        If a file cannot be written (the message names it).
    """
    import shutil
    import tempfile

    from nrmlc.errors import OutputError
    from nrmlc.io import _signals_held, cut_to_bytes

    folder = Path(folder)
    check_otb_destination(folder, len(sequence))
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".tmp-{cut_to_bytes(folder.name, 64)}-", dir=folder.parent))
    except OSError as exc:
        raise OutputError(f"{folder}: cannot write ({exc.strerror or exc})") from None
    old = None
    try:
        os.chmod(staging, 0o777 & ~_umask())
        image_folder = staging / IMAGE_FOLDER
        for index in range(len(sequence)):
            name = f"{index + 1:04d}.png"
            with native_messages():
                ok, encoded = cv2.imencode(".png", sequence.raw_frame(index))
            if not ok:
                raise DataError(f"{folder / IMAGE_FOLDER / name}: PNG encoding failed")
            write_bytes(image_folder / name, encoded)
        write_boxes(staging / GROUNDTRUTH_NAME, np.nan_to_num(sequence.groundtruth, nan=0.0))
        with _signals_held():
            if os.path.lexists(folder):
                old = Path(tempfile.mkdtemp(prefix=f".tmp-{cut_to_bytes(folder.name, 64)}-old-", dir=folder.parent))
                os.replace(folder, old / "sequence")
            try:
                os.replace(staging, folder)
            except OSError:
                if old is not None:
                    os.replace(old / "sequence", folder)  # put the earlier one back
                raise
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        if isinstance(exc, OutputError):
            raise
        raise OutputError(f"{folder}: cannot write ({exc.strerror or exc}); the earlier folder, if any, is kept") \
            from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    return folder


def _umask() -> int:
    from nrmlc.io import _current_umask

    return _current_umask()


__all__ = ["SyntheticSpec", "SyntheticSequence", "synthetic_suite", "suite_specs", "write_otb_sequence",
           "check_otb_destination"]
