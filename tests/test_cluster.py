"""The cluster path: a small grid on a real Dask cluster (``distributed.LocalCluster``,
2 worker processes) through :meth:`nrmlc.workbench.run_cache.RunCache.run`.

- the cached results equal the local process pool's, array by array (every array but
  the two timings, which differ from run to run) and their descriptions byte for byte;
- a run whose worker is killed (SIGKILL) mid-run is retried by the scheduler and lands
  in the cache, equal to the same run computed locally;
- a rerun resumes from the cache: nothing already cached is computed or rewritten.

Needs the ``cluster`` extra (``pip install -e .[cluster]``; ``make test`` installs it).
"""
from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed", reason="needs the cluster extra: pip install -e .[cluster]")

from nrmlc.data import SyntheticSequence, SyntheticSpec  # noqa: E402
from nrmlc.workbench.jobs import RunSpec  # noqa: E402
from nrmlc.workbench.run_cache import RunCache  # noqa: E402
from nrmlc.tracker.params import TrackerParams  # noqa: E402

#: Arrays of a cached run that measure time, not results.
TIMINGS = ("seconds_tracking", "seconds_total")
PARAMS = TrackerParams(n_particles=40, n_positive=10, n_negative=20, max_positive=20)


def tiny_sequence(k: int, n_frames: int) -> SyntheticSequence:
    return SyntheticSequence(SyntheticSpec(
        name=f"cluster-{k}", seed=k, n_frames=n_frames, frame_height=48, frame_width=64, target_width=16,
        target_height=12, translation_amplitude_x=8, translation_amplitude_y=6, n_distractors=1))


def small_grid() -> list[RunSpec]:
    return [RunSpec(tiny_sequence(k, 10), PARAMS, seed=seed, label=f"{k}/{seed}") for k in range(2) for seed in range(2)]


def long_run() -> RunSpec:
    # Long enough (a few seconds) to be caught running and killed.
    return RunSpec(tiny_sequence(7, 400), PARAMS.replace(n_particles=300), seed=0, label="long")


def assert_same_results(cache_a: RunCache, cache_b: RunCache, specs: list[RunSpec]) -> None:
    for spec in specs:
        path_a, path_b = cache_a.path(spec), cache_b.path(spec)
        assert path_a.with_suffix(".json").read_bytes() == path_b.with_suffix(".json").read_bytes()
        with np.load(path_a) as a, np.load(path_b) as b:
            assert sorted(a.files) == sorted(b.files)
            compared = [name for name in a.files if name not in TIMINGS]
            assert "boxes" in compared and "diag_codes" in compared
            for name in compared:
                assert a[name].dtype == b[name].dtype and a[name].tobytes() == b[name].tobytes(), (spec.label, name)


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=50) as cluster, distributed.Client(cluster) as dask_client:
        yield dask_client


def test_grid_on_a_dask_cluster_equals_the_local_pool_survives_a_killed_worker_and_resumes(client, tmp_path):
    specs = small_grid()
    local = RunCache(tmp_path / "local")
    local.run(specs, jobs=2, progress=False)

    on_cluster = RunCache(tmp_path / "dask")
    on_cluster.run(specs, executor=client.get_executor(), progress=False)
    assert_same_results(local, on_cluster, specs)

    # A rerun with one more (long) run: the cached runs are neither computed nor rewritten,
    # and the new run's worker is killed while it runs.
    stamps = {spec.label: on_cluster.path(spec).stat().st_mtime_ns for spec in specs}
    extended = [*specs, long_run()]
    assert [job.label for job in on_cluster.missing(extended)] == ["long"]
    pids_before = client.run(os.getpid)
    outcome: dict = {}

    def run_grid() -> None:
        try:
            outcome["results"] = on_cluster.run(extended, executor=client.get_executor(), progress=False)
        except BaseException as error:  # reported by the assertions below
            outcome["error"] = error

    runner_thread = threading.Thread(target=run_grid)
    runner_thread.start()
    killed = None
    deadline = time.monotonic() + 30
    while killed is None and time.monotonic() < deadline and runner_thread.is_alive():
        busy = [worker for worker, keys in client.processing().items() if keys]
        if busy:
            time.sleep(0.5)  # let it get going
            killed = pids_before[busy[0]]
            os.kill(killed, signal.SIGKILL)
        else:
            time.sleep(0.05)
    runner_thread.join(timeout=120)
    assert killed is not None, "the long run was never seen running"
    assert not runner_thread.is_alive() and "error" not in outcome, outcome.get("error")
    assert len(outcome["results"]) == len(extended)
    assert killed not in client.run(os.getpid).values()  # that worker is gone (the nanny started a new one)
    assert {spec.label: on_cluster.path(spec).stat().st_mtime_ns for spec in specs} == stamps

    # The retried run equals the same run computed here.
    local.run([extended[-1]], jobs=1, progress=False)
    assert_same_results(local, on_cluster, extended)

    # Everything cached now: a rerun computes nothing.
    assert on_cluster.missing(extended) == []
    on_cluster.run(extended, executor=client.get_executor(), progress=False)
    assert {spec.label: on_cluster.path(spec).stat().st_mtime_ns for spec in specs} == stamps

