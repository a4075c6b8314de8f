"""Test oracles: slow, obvious numpy references of the compiled kernels
(:mod:`nrmlc.testing.reference`), importable by the tests and the bench; small hand-made scenes whose outcome is known
(:mod:`nrmlc.testing.scenes`)."""
