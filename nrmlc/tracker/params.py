"""Tracker parameters: the paper's group and, beside it, each addition's group, joined in one
frozen, checked :class:`TrackerParams`; the named presets (``default``, ``paper``).

Each field declares its kind and range beside its default (:mod:`nrmlc.tracker.parameter_fields`);
only the checks that tie fields together are written out. ``nrmlc params`` lists them all.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
import re
import typing
from dataclasses import dataclass
from typing import Literal

import numpy as np

from nrmlc.config import PATCH_SIZE
from nrmlc.errors import ParameterError
from nrmlc.tracker.brightness import BrightnessParams
from nrmlc.tracker.experts import ExpertParams
from nrmlc.tracker.eyes import EyesParams
from nrmlc.tracker.generative import LOCAL_SIZE, N_ATOMS, GenerativeParams
from nrmlc.tracker.motion_floor import MotionFloorParams
from nrmlc.tracker.motion_floor import translation_sigmas as _translation_sigmas
from nrmlc.tracker.parameter_fields import CheckedParams, bounded, fail, field_kinds, range_text
from nrmlc.tracker.redetect import RedetectionParams

#: Largest local dictionary the compiled solvers accept.
MAX_DICTIONARY_SIZE = 16
#: Resource limits: 100,000 particles are 400 MB of patches; 10,000 templates a 800 MB Gram.
MAX_PARTICLES = 100_000
MAX_TEMPLATES = 10_000
#: Template radii and offsets beyond this (template pixels, i.e. 1000x the target) are nonsense.
MAX_RADIUS = 1000.0
#: Per-frame motion std beyond these is not a motion model: 1000 px (or template px), an e-fold of
#: scale or aspect, pi rad.
MAX_MOTION_SIGMA = (1000.0, 1000.0, 1.0, math.pi, 1.0, math.pi)
#: Ridges beyond this leave the coding a constant (the Gram's entries are at most k): nothing to tune.
MAX_RIDGE = 1e6
#: Algorithm 1 settles in a few rounds (paper: T = 3); beyond this is only time.
MAX_ITERATIONS = 100
#: alpha (eps_pos - eps_neg), eps in [0, 4], beyond 4e6 is a hard arg-max already.
MAX_ALPHA = 1e6
#: Where the parameters measured and removed are listed, with their evidence.
REMOVED_PARAMETERS = "docs/research/README.md#parameters-measured-and-removed"


@dataclass(frozen=True)
class PaperParams(CheckedParams):
    """The paper's quantities and switches (Sec. 2-4), and the values the lineage's code gives
    where the paper is silent. The defaults are the paper's where it gives a value; the others are
    chosen on the development sequences (docs/research/protocol.md) and marked *ours*; departures
    from the paper, with their switch back: docs/DEVIATIONS.md.

    Attributes
    ----------
    n_particles : int
        Particles per frame, N (paper: not given; the lineage uses 600). *Ours*: 450.
    motion_sigmas : tuple of 6 float
        Std of the Gaussian motion model for ``[cx, cy, log scale, rotation rad, log aspect,
        skew rad]``; cx, cy in the unit ``translation_noise`` names. *Ours*: 2 template pixels
        (1/16 of the target) for the translation; the lineage's ``[4, 4, 0.01, 0, 0.005, 0]`` has
        4 image pixels. Scale and aspect are perturbed multiplicatively.
    propagation : {'condensation', 'best'}
        'condensation' is eq. (1) as IVT's ``estwarp_condens.m`` implements it: the particles are
        resampled in proportion to h, then diffused. 'best' draws all particles around the
        previous estimate. Either way the estimate is the most confident particle.
    translation_noise : {'relative', 'pixels'}
        'pixels': ``motion_sigmas[0:2]`` are image pixels. 'relative' (L1APG's ``draw_sample``):
        template pixels, i.e. multiplied by the target's size ``sqrt((w^2 + h^2) / 2) / patch_size``.
    n_positive, n_negative : int
        Initial template counts p and n (paper: 50 and 150; *ours*: n = 100; SCM's ``demo.m``: 200).
    template_sampling : {'scm', 'annulus'}
        Where template centres are drawn. 'scm' follows SCM's ``affineTrainG.m`` / ``updateDic.m``:
        positives from N(0, ``positive_sigma`` px) about the target; negatives from
        N(0, (w, h) px), pushed out of a zone about the target. 'annulus' is Sec. 3 as printed:
        positives within ``positive_radius``, negatives in ``positive_radius < d < negative_radius``.
    positive_radius, negative_radius : float
        r and s of Sec. 3 under 'annulus', in template pixels (the paper gives neither; *ours*:
        2 and 16).
    positive_sigma : float
        Std (image pixels) of the positive template centres under 'scm' (SCM: 1).
    negative_push : float
        Under 'scm', the half-width of the zone negatives are pushed out of at initialisation, as a
        fraction of the target's width (height) (SCM: 1/4); at updates 4/5 of it, as SCM's 1/5.
    patch_size : int
        Templates and candidates are patch_size x patch_size (paper: 32).
    dictionary_sizes : tuple of int
        k_1..k_m of the multiple local dictionaries (paper: 5, 8, 10).
    coding : {'regularized', 'constrained', 'plain'}
        'regularized' solves eq. (allcr)/(allcw) with ``lam``/``beta`` (the paper); 'constrained'
        solves eq. (allcn)/(multillc) exactly (c >= 0, sum 1); 'plain' solves eq. (allc), only sum
        to one (lambda = beta = 0).
    lam, beta : float
        l2 weights for the coefficients c and the dictionary weights w (paper: 1, 0.1).
    n_iterations : int
        T of Algorithm 1 (paper: 3).
    alpha : float
        Confidence scale in h = exp(-alpha (eps_pos - eps_neg)). Under condensation it is the
        likelihood's sharpness. Paper: 2.5; *ours*: 25 (2.5 leaves the weights nearly uniform).
    confidence : {'corrected', 'literal'}
        'corrected': h = exp(-alpha (eps_pos - eps_neg)); 'literal': the printed
        h = 1 / exp(-alpha (eps_pos - eps_neg)) (docs/DEVIATIONS.md).
    update_interval : int
        Templates are updated every this many frames (paper: 5).
    max_positive : int
        Cap on positive templates; beyond it the closest one is replaced (paper: 100).
    update_error_threshold : float
        A result joins the positives only if eps_pos* is below this (paper: 0.1); eps is a squared
        error between unit vectors, in [0, 4].
    occlusion_detection : bool
        Block positive updates while the target is judged occluded.
    occlusion_max_negative : int
        Occluded when LEN(neg*) exceeds this (Algorithm 2: update iff LEN <= 2).
    coefficient_tolerance : float
        A template is used by the best candidate when its coefficient's magnitude exceeds this.
    """

    # -- motion model and particles (Sec. 2, eq. 1)
    n_particles: int = bounded(450, 1, MAX_PARTICLES)
    motion_sigmas: tuple[float, ...] = (2.0, 2.0, 0.01, 0.0, 0.005, 0.0)
    propagation: Literal["condensation", "best"] = "condensation"
    translation_noise: Literal["relative", "pixels"] = "relative"
    # -- templates (Sec. 3)
    n_positive: int = bounded(50, 1, MAX_TEMPLATES)
    n_negative: int = bounded(100, 0, MAX_TEMPLATES)
    template_sampling: Literal["scm", "annulus"] = "scm"
    positive_radius: float = bounded(2.0, 0, MAX_RADIUS)
    negative_radius: float = bounded(16.0, 0, MAX_RADIUS, low_open=True)
    positive_sigma: float = bounded(1.0, 0, MAX_RADIUS)
    negative_push: float = bounded(0.25, 0, 2)
    patch_size: int = bounded(PATCH_SIZE, 4)
    # -- coding (Algorithm 1)
    dictionary_sizes: tuple[int, ...] = (5, 8, 10)
    coding: Literal["regularized", "constrained", "plain"] = "regularized"
    lam: float = bounded(1.0, 0, MAX_RIDGE)
    beta: float = bounded(0.1, 0, MAX_RIDGE)
    n_iterations: int = bounded(3, 0, MAX_ITERATIONS)
    # -- confidence (Algorithm 2, step 2.4)
    alpha: float = bounded(25.0, 0, MAX_ALPHA, low_open=True)
    confidence: Literal["corrected", "literal"] = "corrected"
    # -- template updates and occlusion (Algorithm 2, step 2.5)
    update_interval: int = bounded(5, 1, 1_000_000)  # beyond any video: never
    max_positive: int = bounded(100, 1, MAX_TEMPLATES)
    update_error_threshold: float = bounded(0.1, 0, 4)
    occlusion_detection: bool = True
    occlusion_max_negative: int = bounded(2, 0, MAX_TEMPLATES)
    coefficient_tolerance: float = bounded(1e-6, 0, 1)

    def check_group(self) -> None:
        if len(self.motion_sigmas) != 6 or any(not math.isfinite(v) or v < 0 for v in self.motion_sigmas):
            fail("motion_sigmas", f"must be 6 finite non-negative numbers, got {self.motion_sigmas}")
        if any(v > MAX_MOTION_SIGMA[i] for i, v in enumerate(self.motion_sigmas)):
            fail("motion_sigmas", f"each must be at most {MAX_MOTION_SIGMA} (translation px or template px, "
                                  f"log scale, rad, log aspect, rad), got {self.motion_sigmas}")
        if self.max_positive + self.n_negative > MAX_TEMPLATES:
            fail("n_negative" if self.n_negative > self.max_positive else "max_positive",
                 f"max_positive + n_negative must be at most {MAX_TEMPLATES} (the template Gram is "
                 f"their square), got {self.max_positive} + {self.n_negative}")
        if self.positive_radius >= self.negative_radius:
            fail("negative_radius", f"must be larger than positive_radius ({self.positive_radius:g}), "
                                    f"got {self.negative_radius:g}")
        if not self.dictionary_sizes:
            fail("dictionary_sizes", "needs at least one dictionary size")
        n_templates = self.n_positive + self.n_negative
        for k in self.dictionary_sizes:
            if k < 1 or k > MAX_DICTIONARY_SIZE:
                fail("dictionary_sizes", f"each k must be in 1..{MAX_DICTIONARY_SIZE}, got {k}")
            if k > n_templates:
                fail("dictionary_sizes", f"k = {k} is larger than the template count {n_templates}")
        if self.max_positive < self.n_positive:
            fail("max_positive", f"must be >= n_positive ({self.n_positive}), got {self.max_positive}")

    @property
    def k_max(self) -> int:
        return max(self.dictionary_sizes)

    @property
    def ridges(self) -> tuple[float, float]:
        """(ridge on c, ridge on w) actually used by the coding mode."""
        return (self.lam, self.beta) if self.coding == "regularized" else (0.0, 0.0)


#: Each group of :class:`TrackerParams`: the paper's, then the additions' (in the order they act).
GROUPS: dict[str, type] = {"paper": PaperParams, "brightness": BrightnessParams, "eyes": EyesParams,
                           "motion floor": MotionFloorParams, "re-detection": RedetectionParams,
                           "generative term": GenerativeParams, "experts": ExpertParams}

#: The fields in the order of the algorithm's stages (the order :meth:`TrackerParams.as_dict` gives).
STAGE_ORDER: tuple[str, ...] = (
    "n_particles", "motion_sigmas", "propagation", "translation_noise", "translation_floor",
    "n_positive", "n_negative", "template_sampling", "positive_radius", "negative_radius", "positive_sigma",
    "negative_push", "patch_size", "brightness", "eyes",
    "dictionary_sizes", "coding", "lam", "beta", "n_iterations",
    "alpha", "confidence",
    "update_interval", "max_positive", "update_error_threshold", "occlusion_detection", "occlusion_max_negative",
    "coefficient_tolerance",
    "redetect_count", "redetect_factor", "redetect_accept", "redetect_trigger", "redetect_weak_radius",
    "redetect_weak_accept",
    "generative_weight", "generative_candidates", "generative_neighbours", "generative_lam", "generative_interval",
    "generative_step",
    "second_expert", "partner_eyes", "expert_memory", "expert_blend_iou", "unrecognised_size_share",
    "unrecognised_gate",
)


@dataclass(frozen=True)
class TrackerParams(ExpertParams, GenerativeParams, RedetectionParams, MotionFloorParams, EyesParams,
                    BrightnessParams, PaperParams):
    """All parameters of the NRMLC tracker: :class:`PaperParams` and the additions' groups
    (:data:`GROUPS`), one flat set of fields, validated on construction.

    ``TrackerParams(n_particles=300)``, ``params.replace(lam=0.5)``, ``TrackerParams.preset('paper')``
    and the CLI's ``--param NAME=VALUE`` all take the fields by name.
    """

    def check_group(self) -> None:
        if self.generative_weight > 0 and self.patch_size < LOCAL_SIZE:
            fail("patch_size", f"must be >= {LOCAL_SIZE} (the local patches) when generative_weight > 0, "
                               f"got {self.patch_size}")
        self._check_memory()

    def replace(self, **changes) -> "TrackerParams":
        """A copy with some fields changed (validated)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise unknown_parameter(sorted(unknown)[0])
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """Every field by name, in the order of the algorithm's stages."""
        return {name: getattr(self, name) for name in STAGE_ORDER}

    @classmethod
    def preset(cls, name: str, **changes) -> "TrackerParams":
        """A named configuration (see :data:`PRESETS`), with some fields changed."""
        if name not in PRESETS:
            raise ParameterError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
        return cls().replace(**{**PRESETS[name], **changes})

    @classmethod
    def paper(cls, **changes) -> "TrackerParams":
        """The paper as printed: no addition beyond it (:data:`PRESETS` ``'paper'``)."""
        return cls.preset("paper", **changes)

    @classmethod
    def choices(cls, name: str) -> tuple:
        """The values a switch can take: a ``Literal`` field's choices (default first), or
        (True, False) for a flag; () for a numeric field."""
        kind = field_kinds(cls).get(name)
        if kind is None:
            raise unknown_parameter(name)
        if kind is bool:
            return (True, False)
        return typing.get_args(kind) if typing.get_origin(kind) is Literal else ()

    def translation_sigmas(self, sizes: np.ndarray) -> np.ndarray:
        """The per-frame translation std (n, 2) in image pixels (:func:`nrmlc.tracker.motion_floor.translation_sigmas`)."""
        return _translation_sigmas(self, sizes)

    def memory_terms(self) -> dict[str, float]:
        """Bytes the largest per-frame arrays take, by the parameters that size them (an estimate
        with the copies a frame makes; the frame itself and the interpreter come on top)."""
        candidates = self.n_particles + self.redetect_count
        vector = self.patch_size**2
        templates = self.max_positive + self.n_negative
        local = ((self.patch_size - LOCAL_SIZE) // self.generative_step + 1) ** 2
        atoms_grid = ((self.patch_size - LOCAL_SIZE) // 2 + 1) ** 2
        k = self.k_max
        terms = {
            # warped patches (float32), their centred copy, the particles' patches kept for the update
            "n_particles, redetect_count, patch_size": 3.0 * candidates * vector * 4,
            # [T_pos, T_neg] and its two halves (float32)
            "max_positive, n_negative, patch_size": 3.0 * templates * vector * 4,
            # candidate-template products (float64 and a float32 copy) and the scattered codes
            "n_particles, redetect_count, max_positive, n_negative": 3.0 * candidates * templates * 8,
            # the template Gram and the one it is updated from
            "max_positive, n_negative": 3.0 * templates**2 * 8,
            # the solvers' work arrays per candidate
            "n_particles, redetect_count, dictionary_sizes": (candidates * (len(self.dictionary_sizes) + 4) * k * k
                                                              * 8 * 4),
        }
        if self.generative_weight > 0:
            terms["generative_candidates, patch_size, generative_step"] = (
                self.generative_candidates * local
                * (N_ATOMS * 4 + LOCAL_SIZE**2 * 4 + self.generative_neighbours * 24))
            terms["patch_size"] = atoms_grid * LOCAL_SIZE**2 * 8 * 3  # the local atoms' source patches
        return terms

    def estimated_bytes(self) -> float:
        """Estimated peak memory of the tracker these parameters describe (see :meth:`memory_terms`;
        a second expert doubles it)."""
        return float(sum(self.memory_terms().values())) * (1 if self.second_expert == "off" else 2)

    def _check_memory(self) -> None:
        # The combination matters (particles x templates, particles x patch side^2): each value may be
        # in range while their product is not. Checked against the smallest limit that applies (the RAM,
        # a container's, ulimit -v's), before any work.
        from nrmlc.resources import gigabytes, memory_ceiling

        ceiling = memory_ceiling()
        need = self.estimated_bytes()
        if ceiling is not None and need > ceiling[0]:
            terms = self.memory_terms()
            names = max(terms, key=terms.get).split(", ")
            values = ", ".join(f"{name}={getattr(self, name)!r}" for name in names)
            fail(names[-1], f"with {values} a tracker needs about {gigabytes(need)}, more than {ceiling[1]}")


#: Named configurations. 'default' is the tuned tracker (every value chosen on the development
#: sequences). 'paper' is the paper as printed where it says something (Sec. 3's annulus templates,
#: eq. (1)'s posterior propagation) with every addition switched off; the values it leaves
#: unstated are the default's, but for the particle count: the lineage's 600, since the default's
#: smaller count only pays for the generative term, which the preset does not have.
PRESETS: dict[str, dict] = {
    "default": {},
    "paper": dict(template_sampling="annulus", propagation="condensation", alpha=2.5,
                  update_interval=5, update_error_threshold=0.1, n_particles=600, n_negative=150,
                  brightness="raw", translation_floor=0.0,
                  redetect_count=0, redetect_trigger=0.99, redetect_weak_radius=100.0, redetect_weak_accept=1.0,
                  generative_weight=0.0,
                  second_expert="off", expert_blend_iou=1.0, unrecognised_size_share=0.0),
}


def resolve_params(params: TrackerParams | None, overrides: dict) -> TrackerParams:
    """``params`` (default :class:`TrackerParams`) with ``overrides`` applied: what a tracker's
    ``params=`` and keyword arguments give."""
    if params is not None and not isinstance(params, TrackerParams):
        raise ParameterError(f"params must be a TrackerParams, got {type(params).__name__} "
                             f"(TrackerParams(**values), or pass the values as keywords)")
    base = params if params is not None else TrackerParams()
    return base.replace(**overrides) if overrides else base


def unknown_parameter(name: str, context: str = "") -> ParameterError:
    """The one-line error for a name that is no field: the nearest field's name, and where the
    parameters measured and removed are listed."""
    close = difflib.get_close_matches(name, [f.name for f in dataclasses.fields(TrackerParams)], n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    return ParameterError(f"{context}unknown parameter {name!r}{hint} (`nrmlc params` lists them; "
                          f"parameters measured and removed: {REMOVED_PARAMETERS})")


def parse_param_assignment(text: str) -> tuple[str, object]:
    """Parse a ``name=value`` string (CLI ``--param``) into a typed pair.

    The value's type follows the field's default: int, float, bool, str, or a comma-separated tuple.
    """
    if "=" not in text:
        raise ParameterError(f"--param {text!r}: expected name=value")
    name, raw = (part.strip() for part in text.split("=", 1))
    defaults = {f.name: f.default for f in dataclasses.fields(TrackerParams)}
    if name not in defaults:
        raise unknown_parameter(name, f"--param {text!r}: ")
    default = defaults[name]
    try:
        if isinstance(default, bool):
            if raw.lower() not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                raise ValueError
            value: object = raw.lower() in ("true", "1", "yes", "on")
        elif isinstance(default, int):
            value = int(raw)
        elif isinstance(default, float):
            value = float(raw)
        elif isinstance(default, tuple):
            element = type(default[0])
            parts = [v.strip() for v in raw.split(",")]
            if any(not v for v in parts):
                raise ValueError
            value = tuple(element(v) for v in parts)
        else:
            value = raw
    except ValueError:
        raise ParameterError(f"--param {text!r}: cannot read {raw!r} as {type(default).__name__}") from None
    return name, value


def describe_parameters(preset: str = "default") -> list[dict]:
    """Every parameter for ``nrmlc params``: a dict each with ``name``, ``group`` (a key of
    :data:`GROUPS`), ``default`` (the value under ``preset``), ``range`` (the values it accepts)
    and ``meaning`` (the first sentence of its entry in its group's docstring)."""
    values = TrackerParams.preset(preset).as_dict()
    kinds = field_kinds(TrackerParams)
    rows = []
    for group, cls in GROUPS.items():
        meanings = _attribute_meanings(cls.__doc__ or "")
        for f in dataclasses.fields(cls):
            rows.append(dict(name=f.name, group=group, default=values[f.name], range=range_text(f, kinds[f.name]),
                             meaning=meanings.get(f.name, "")))
    return rows


def _attribute_meanings(doc: str) -> dict[str, str]:
    """{field: first sentence, without reST markup} from a numpydoc ``Attributes`` section."""
    meanings, names, text = {}, [], []

    def close() -> None:
        sentence = _first_sentence(re.sub(r":\w+:`~?([^`]+)`|``([^`]+)``", lambda m: m.group(1) or m.group(2),
                                          " ".join(text)))
        for name in names:
            meanings[name] = sentence

    for line in doc.split("Attributes\n", 1)[-1].splitlines():
        entry = re.match(r"^    (\w+(?:, \w+)*) : ", line)
        if entry:
            close()
            names, text = entry.group(1).split(", "), []
        elif line.startswith("        ") and names:
            text.append(line.strip())
    close()
    return meanings


def _first_sentence(text: str) -> str:
    """``text`` up to its first '. ' or '; ' outside parentheses (not after 'eq' or 'i.e')."""
    depth = 0
    for i, char in enumerate(text):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if depth == 0 and char in ".;" and text[i + 1:i + 2] in (" ", "") and not text[:i].endswith(("eq", "i.e", "e.g", "Sec")):
            return text[:i]
    return text.rstrip(".")
