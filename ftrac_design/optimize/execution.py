"""Where evaluations run: any ``concurrent.futures``-style executor.

- ``workers = 0``: in this process, one after another (:class:`SerialExecutor`; the
  baseline of the scaling benchmark and the fastest choice for tiny runs);
- default: a local :class:`~concurrent.futures.ProcessPoolExecutor` with one process per
  core (``forkserver`` start with this package preloaded, so a worker starts in
  milliseconds and never inherits the parent's threads);
- ``scheduler = "tcp://HOST:8786"`` (or the ``DASK_SCHEDULER_ADDRESS`` variable): an
  existing Dask cluster through ``distributed.Client(...).get_executor()``.

Results never depend on the executor: the driver tells them back in submission order.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor

from ..errors import InputError, require


class SerialExecutor(Executor):
    """Runs each submitted call at once in the calling thread; returns a finished future."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        fut: Future = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # the caller sees it from result(), as with any executor
            fut.set_exception(exc)
        return fut


def machine_workers() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def local_pool(workers: int) -> ProcessPoolExecutor:
    """A process pool of ``workers`` processes that start from a preloaded fork server."""
    methods = multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
    if ctx.get_start_method() == "forkserver":
        ctx.set_forkserver_preload(
            ["ftrac_design.optimize.evaluate", "ftrac_design.manufacture.rules", "ftrac_design.analysis.poses"]
        )
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx)


@contextlib.contextmanager
def open_executor(scheduler: str | None = None, workers: int | None = None) -> Iterator[tuple[Executor, str]]:
    """The executor asked for (see the module doc) and a one-line description of it."""
    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if scheduler:
        Client = require("distributed", "optimize", "a Dask cluster (scheduler address)").Client
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(
                None,
                None,
                f"a reachable Dask scheduler address, got {scheduler!r} ({type(exc).__name__}: {exc})",
                parameter="scheduler",
            ) from None
        try:
            n = sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values())
            yield client.get_executor(), f"Dask cluster {scheduler} ({n} worker threads)"
        finally:
            client.close()
        return
    n = machine_workers() if workers is None else workers
    if n == 0:
        yield SerialExecutor(), "in-process (serial)"
        return
    pool = local_pool(n)
    try:
        yield pool, f"local process pool ({n} worker{'s' * (n != 1)})"
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
