"""Test oracles: slow, obvious numpy references of the compiled kernels
(:mod:`nrmlc.testing.reference`), importable by the tests and the bench."""
