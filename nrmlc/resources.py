"""How much memory and disk this machine has: the limits that refuse, before any work, a job
that would end in a MemoryError or a full disk."""
from __future__ import annotations

import os
import shutil


def physical_memory() -> int | None:
    """Bytes of RAM in this machine (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return None


def available_memory() -> int | None:
    """Bytes of RAM available now without swapping (``MemAvailable``), else the physical size."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return physical_memory()


def free_disk(folder: str | os.PathLike) -> int | None:
    """Bytes free for this user on the file system of ``folder`` (or of its nearest existing parent)."""
    path = os.path.abspath(os.fspath(folder))
    while not os.path.exists(path) and os.path.dirname(path) != path:
        path = os.path.dirname(path)
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


def gigabytes(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:.1f} GB" if n_bytes >= 2**30 else f"{n_bytes / 2**20:.0f} MB"
