"""Compiled per-particle kernels of the NRMLC tracker.

* :mod:`nrmlc.kernels.warp` -- bilinear affine warp of many particles into
  unit-norm patch vectors; zero-mean (centred) patches.
* :mod:`nrmlc.kernels.distance` -- candidate-template inner products, squared
  norms, template Gram, k-nearest templates.
* :mod:`nrmlc.kernels.coding` -- approximated-LLC coefficients per local
  dictionary, dictionary weights (Algorithm 1) and confidence errors;
  :func:`~nrmlc.kernels.coding.code_candidates` runs everything after the
  product (norms, nearest templates, coding, weights) in one parallel pass.
* :mod:`nrmlc.kernels.checks` -- the input checks of their public wrappers.

Threads (numba, BLAS, OpenCV) follow the policy of
:func:`nrmlc.config.set_threads`, which also explains it.
"""
from nrmlc.kernels.cache import drop_stale_cache, make_cache_robust

# Before any kernel module loads its cached machine code (see nrmlc.kernels.cache).
drop_stale_cache()
make_cache_robust()

from nrmlc.kernels.coding import (  # noqa: E402
    PLAIN_JITTER,
    code_candidates,
    combine_dictionaries,
    encode_dictionaries,
    scatter_codes,
)
from nrmlc.kernels.distance import (  # noqa: E402
    candidate_template_dots,
    nearest_templates,
    squared_norms,
    template_gram,
)
from nrmlc.kernels.warp import warp_patches  # noqa: E402

__all__ = [
    "warp_patches",
    "candidate_template_dots",
    "squared_norms",
    "template_gram",
    "nearest_templates",
    "PLAIN_JITTER",
    "encode_dictionaries",
    "combine_dictionaries",
    "code_candidates",
    "scatter_codes",
]
