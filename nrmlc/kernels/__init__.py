"""Compiled per-particle kernels of the NRMLC tracker.

* :mod:`nrmlc.kernels.distance` -- candidate-template inner products, squared
  norms, template Gram, k-nearest templates.
* :mod:`nrmlc.kernels.coding` -- approximated-LLC coefficients per local
  dictionary, dictionary weights (Algorithm 1) and confidence errors.
"""
import os

# numba's OpenMP pool (its default threading layer here) busy-waits after every
# parallel region unless told otherwise. On a 2-core machine the spinning worker
# then competes with OpenBLAS, OpenCV and the main thread, which run between
# our kernels: measured, it doubled the CPU time per tracked frame and, on a
# shared machine, divided the frame rate by 3 to 5. Passive waiting costs a
# few microseconds of wake-up per kernel call. libgomp reads this when numba
# first starts its pool (the first parallel call), so setting it at import
# is early enough; a value set by the user wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from nrmlc.kernels.coding import (  # noqa: E402
    PLAIN_JITTER,
    combine_dictionaries,
    encode_dictionaries,
    scatter_codes,
)
from nrmlc.kernels.distance import candidate_template_dots, nearest_templates, squared_norms, template_gram  # noqa: E402

__all__ = [
    "candidate_template_dots",
    "squared_norms",
    "template_gram",
    "nearest_templates",
    "PLAIN_JITTER",
    "encode_dictionaries",
    "combine_dictionaries",
    "scatter_codes",
]
