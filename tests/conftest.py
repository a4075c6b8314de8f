"""Shared pytest fixtures."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

REPO_ROOT = Path(__file__).resolve().parent.parent

# Property tests draw their examples from a fixed seed by default, so the suite
# (and CI) gives the same verdict on every run; a CI failure must be reproducible
# here. `pytest --hypothesis-profile=explore` draws fresh random examples, to hunt
# for new counterexamples before they are pinned with @example.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile("deterministic")


@pytest.fixture(scope="session")
def real_data_root() -> Path:
    """The real sequences folder: ``$NRMLC_DATA``, else ``<repo>/../shared/data/sequences``.

    Tests using it are skipped (with the path in the reason) when it is absent.
    """
    root = Path(os.environ.get("NRMLC_DATA", "").strip() or REPO_ROOT.parent / "shared" / "data" / "sequences")
    if not root.is_dir():
        pytest.skip(f"real data not found at {root} (set NRMLC_DATA)")
    return root


@pytest.fixture(scope="module")
def data_root(tmp_path_factory) -> Path:
    """Three small synthetic sequences in the OTB layout (a folder each), made once per module."""
    from nrmlc.testing.scenes import write_small_suite

    return write_small_suite(tmp_path_factory.mktemp("data"), n_sequences=3)


@pytest.fixture(scope="module")
def names(data_root) -> list[str]:
    """The sequence names of :func:`data_root`, sorted."""
    return sorted(p.name for p in data_root.iterdir())
