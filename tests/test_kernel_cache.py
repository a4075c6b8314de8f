"""The kernels' numba cache is dropped as a whole when any kernel source changes
(numba itself only checks each function's own file)."""
from pathlib import Path

from nrmlc.kernels.cache import STAMP_NAME, drop_stale_cache, sources_digest


def _fake_kernels(folder: Path) -> Path:
    (folder / "kernels").mkdir()
    (folder / "config.py").write_text("FLAGS = 1\n")
    (folder / "kernels" / "coding.py").write_text("def f(): pass\n")
    (folder / "kernels" / "distance.py").write_text("def g(): pass\n")
    cache = folder / "kernels" / "__pycache__"
    cache.mkdir()
    for name in ("coding.f-1.py311.nbi", "coding.f-1.py311.1.nbc", "distance.g-1.py311.nbi", "other.h-1.py311.nbi"):
        (cache / name).write_bytes(b"x")
    return folder / "kernels"


def test_a_change_in_any_kernel_module_drops_every_kernel_cache_file(tmp_path):
    kernels = _fake_kernels(tmp_path)
    cache = kernels / "__pycache__"
    assert drop_stale_cache(kernels, cache)  # no stamp yet: unknown provenance
    assert sorted(p.name for p in cache.iterdir()) == ["nrmlc-kernels.stamp", "other.h-1.py311.nbi"]
    assert (cache / STAMP_NAME).read_text() == sources_digest(kernels)
    (cache / "coding.f-1.py311.nbi").write_bytes(b"x")
    assert not drop_stale_cache(kernels, cache)  # sources unchanged: the cache stays
    assert (cache / "coding.f-1.py311.nbi").exists()
    (kernels / "distance.py").write_text("def g(): return 1\n")  # only the callee's module changes
    assert drop_stale_cache(kernels, cache)
    assert not (cache / "coding.f-1.py311.nbi").exists()


def test_the_compilation_flags_are_part_of_the_digest(tmp_path):
    kernels = _fake_kernels(tmp_path)
    before = sources_digest(kernels)
    (tmp_path / "config.py").write_text("FLAGS = 2\n")
    assert sources_digest(kernels) != before
