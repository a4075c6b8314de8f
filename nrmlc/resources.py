"""How much memory and disk this machine has: the limits that refuse, before any work, a job
that would end in a MemoryError or a full disk.

Memory is limited by more than the RAM: a container's cgroup (v2 ``memory.max``, v1
``memory.limit_in_bytes``, also set on every ancestor group) and the process's own limits
(``ulimit -v``: ``RLIMIT_AS``; ``RLIMIT_DATA``). The one that applies is the smallest; for the
process limits, what is left of them after what the process already holds.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

#: Where the cgroup file systems are mounted, and this process's cgroups and memory use (tests
#: point these at folders of their own).
CGROUP_ROOT = Path("/sys/fs/cgroup")
PROC_CGROUP = Path("/proc/self/cgroup")
PROC_STATUS = Path("/proc/self/status")


def physical_memory() -> int | None:
    """Bytes of RAM in this machine (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return None


def _free_ram() -> int | None:
    """Bytes of RAM available now without swapping (``MemAvailable``), else the physical size."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return physical_memory()


def _number_in(path: Path) -> int | None:
    """The byte count a cgroup file holds (None: absent, unreadable, or ``max``, no limit)."""
    try:
        text = path.read_text().strip()
    except (OSError, ValueError):
        return None
    return int(text) if text.isdigit() else None


def _cgroup_folders() -> list[tuple[Path, str, str]]:
    """(folder, limit file, usage file) of this process's memory cgroups and their ancestors."""
    try:
        lines = PROC_CGROUP.read_text().splitlines()
    except OSError:
        return []
    found = []
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, group = parts
        if controllers == "":  # v2, the unified hierarchy (or its hybrid mount)
            mounts, files = [CGROUP_ROOT, CGROUP_ROOT / "unified"], ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):
            mounts, files = [CGROUP_ROOT / "memory"], ("memory.limit_in_bytes", "memory.usage_in_bytes")
        else:
            continue
        for mount in mounts:
            folder = mount / group.strip("/")
            # In a cgroup namespace the group's path is not under the mount: its root is the group.
            folders = [folder, *folder.parents] if folder.is_dir() else [mount]
            found += [(f, *files) for f in folders if f == mount or mount in f.parents]
    return found


def _process_status(field: str) -> int | None:
    """A ``kB`` field of ``/proc/self/status`` (``VmSize``, ``VmData``) in bytes."""
    try:
        with open(PROC_STATUS) as handle:
            for line in handle:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def memory_limits() -> list[tuple[int, int, str, bool]]:
    """Every limit on this process's memory other than the RAM: ``(limit, left, what, own)``, in
    bytes, ``left`` being what the process (or its cgroup) may still take; ``what`` completes
    "the 2.0 GB ..." in a message; ``own``: the process's own limit, not one its cgroup shares."""
    limits = []
    for folder, limit_file, usage_file in _cgroup_folders():
        limit = _number_in(folder / limit_file)
        if limit is None or limit >= 2**60:  # v1 writes "no limit" as a number near 2**63
            continue
        used = _number_in(folder / usage_file) or 0
        limits.append((limit, max(0, limit - used), f"its cgroup allows ({folder / limit_file})", False))
    try:
        import resource
    except ImportError:  # not POSIX
        return limits
    for name, field, what in (("RLIMIT_AS", "VmSize", "ulimit -v"), ("RLIMIT_DATA", "VmData", "ulimit -d")):
        try:
            soft = resource.getrlimit(getattr(resource, name))[0]
        except (AttributeError, OSError, ValueError):
            continue
        if soft == resource.RLIM_INFINITY or soft < 0:
            continue
        used = _process_status(field) or 0
        limits.append((soft, max(0, soft - used), f"that {name} ({what}) leaves this process", True))
    return limits


def memory_ceiling() -> tuple[int, str] | None:
    """The most memory one process can take here, and what sets it, for messages (None: unknown).

    The smallest of the RAM, a cgroup's limit, and what ``RLIMIT_AS``/``RLIMIT_DATA`` leave
    after what this process already holds.

    Returns
    -------
    (int, str) or None
        Bytes, and a phrase for "more than ..." (``"this machine's 16.0 GB of memory"``).
    """
    candidates = []
    ram = physical_memory()
    if ram is not None:
        candidates.append((ram, f"this machine's {gigabytes(ram)} of memory"))
    for limit, left, what, own in memory_limits():
        # A process limit counts what this process holds already; a cgroup's is shared with
        # others (the workers of one run), so its whole size is the ceiling of one of them.
        size = left if own else limit
        candidates.append((size, f"the {gigabytes(size)} of memory {what}"))
    return min(candidates, key=lambda c: c[0]) if candidates else None


def available_memory() -> int | None:
    """Bytes of memory this process may take now: the RAM available without swapping
    (``MemAvailable``, else the physical size), or less where a cgroup's or the process's own
    limit leaves less."""
    sizes = [size for size in [_free_ram()] + [limit[1] for limit in memory_limits()] if size is not None]
    return min(sizes) if sizes else None


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
