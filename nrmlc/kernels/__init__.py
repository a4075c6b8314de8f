"""Compiled per-particle kernels of the NRMLC tracker.

* :mod:`nrmlc.kernels.distance` -- candidate-template inner products, squared
  norms, template Gram, k-nearest templates.
* :mod:`nrmlc.kernels.coding` -- approximated-LLC coefficients per local
  dictionary, dictionary weights (Algorithm 1) and confidence errors.
"""
from nrmlc.kernels.coding import (
    PLAIN_JITTER,
    combine_dictionaries,
    encode_dictionaries,
    scatter_codes,
)
from nrmlc.kernels.distance import candidate_template_dots, nearest_templates, squared_norms, template_gram

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
