"""Where a job's independent tasks run: ``sync``, ``threads:N``, ``processes:N``,
``dask:ADDRESS`` (a running ``dask.distributed`` scheduler) or ``dask:local:N`` (a
``LocalCluster`` of N one-thread worker processes).

A task is a module-level function and its arguments (picklable); results come back in
the order given. A task whose worker process dies is run again: on a fresh pool for
``processes``, by the dask scheduler itself for ``dask`` (which reruns the tasks of a
lost worker). Tasks must be pure (the same inputs give the same outputs, and what they
write depends on nothing else), so every scheduler gives the same results.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from geoterrain.exceptions import UsageError

__all__ = ["SCHEDULER_HELP", "parse_scheduler", "run_tasks"]

SCHEDULER_HELP = "sync, threads:N, processes:N, dask:ADDRESS or dask:local:N"
Task = tuple[Callable, tuple]


def parse_scheduler(spec: str) -> tuple[str, int | str]:
    """``(kind, N or address)`` of a scheduler spec; UsageError naming the forms.

    Examples
    --------
    >>> parse_scheduler("sync"), parse_scheduler("processes:2")
    (('sync', 1), ('processes', 2))
    >>> parse_scheduler("dask:local:2"), parse_scheduler("dask:tcp://10.0.0.5:8786")
    (('dask-local', 2), ('dask', 'tcp://10.0.0.5:8786'))
    """
    kind, _, arg = str(spec).partition(":")
    if kind == "sync" and not arg:
        return "sync", 1
    if kind in ("threads", "processes"):
        if arg.isdigit() and int(arg) >= 1:
            return kind, int(arg)
    elif kind == "dask" and arg:
        local, _, n = arg.partition(":")
        if local == "local":
            if n.isdigit() and int(n) >= 1:
                return "dask-local", int(n)
        else:
            return "dask", arg
    raise UsageError(f"unknown scheduler {spec!r}; use {SCHEDULER_HELP}",
                     cli=f"--scheduler {spec!r} is not one of {SCHEDULER_HELP}")


def run_tasks(spec: str, tasks: Sequence[Task], retries: int = 2) -> list:
    """Run ``tasks`` on the scheduler ``spec`` and return their results in order.

    Examples
    --------
    >>> run_tasks("threads:2", [(pow, (2, 3)), (pow, (3, 2))])
    [8, 9]
    """
    kind, arg = parse_scheduler(spec)
    if kind == "sync":
        return [f(*a) for f, a in tasks]
    if kind == "threads":
        with ThreadPoolExecutor(int(arg)) as ex:
            return [fu.result() for fu in [ex.submit(f, *a) for f, a in tasks]]
    if kind == "processes":
        return _processes(tasks, int(arg), retries)
    return _dask(kind, arg, tasks)


def _processes(tasks: Sequence[Task], n: int, retries: int) -> list:
    # spawned workers (no fork of a process whose compiled kernels hold threads); the
    # tasks of a pool broken by a dead worker go to a fresh one
    results: list = [None] * len(tasks)
    todo = list(range(len(tasks)))
    ctx = multiprocessing.get_context("spawn")
    for attempt in range(retries + 1):
        with ProcessPoolExecutor(n, mp_context=ctx) as ex:
            futures = {i: ex.submit(tasks[i][0], *tasks[i][1]) for i in todo}
            failed = []
            for i, fu in futures.items():
                try:
                    results[i] = fu.result()
                except BrokenProcessPool:
                    if attempt == retries:
                        raise
                    failed.append(i)
        todo = failed
        if not todo:
            break
    return results


def _dask(kind: str, arg: int | str, tasks: Sequence[Task]) -> list:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise UsageError("the dask schedulers need dask.distributed: pip install "
                         "'geoterrain[dask]'") from None
    cluster = None
    if kind == "dask-local":
        cluster = LocalCluster(n_workers=int(arg), threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    else:
        try:
            client = Client(str(arg), timeout="10s")
        except OSError as exc:
            raise UsageError(f"no dask scheduler at {arg}: {exc}; start one "
                             "(dask scheduler) or use dask:local:N") from None
    try:
        futures = [client.submit(f, *a, pure=False) for f, a in tasks]
        return client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
