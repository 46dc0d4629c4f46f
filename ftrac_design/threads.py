"""Threads while an image is tracked: one BLAS thread for the many small solves, and a second
thread for work that lets go of the interpreter (OpenCV's filters, ONNX Runtime, NumPy's
large reductions) beside it.

**One BLAS thread.**

Tracking an image is a few thousand small linear-algebra calls (2 × 2 to 6 × 6 solves,
least-squares lines over a crop's pixels) between OpenCV filters and ONNX Runtime's
inference, which keep their own thread pools. A multi-threaded BLAS wakes its threads for
each of those calls; where another process holds a core (a viewer beside a live feed, the
optimiser's other workers) the threads wait for one another. Measured on the 2-core machine
with one core held busy: a run's tracked frames took a median of 56–61 ms with the BLAS
threads instead of 29–30 ms with one, and single images 7.5 % longer (median ratio, 22
realism images); quiet, one thread was 0.5 ms a frame faster and single images 2 % slower.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import AbstractContextManager
from functools import cache
from typing import Any, Generic, TypeVar

from threadpoolctl import ThreadpoolController


@cache
def _controller() -> ThreadpoolController:
    # made once, when the first image is tracked (every BLAS library numpy, SciPy and OpenCV
    # bring is loaded by then): a new controller inspects the loaded libraries, ~0.4 ms
    return ThreadpoolController()


def one_blas_thread() -> AbstractContextManager:
    """A context in which every BLAS library of the process uses one thread (restored on
    exit); nested uses are harmless."""
    return _controller().limit(limits=1, user_api="blas")


T = TypeVar("T")


class Beside(Generic[T]):
    """A call running on a thread of its own (:func:`beside`): :meth:`result` waits for it
    and returns its value or raises its exception on the caller's thread."""

    def __init__(self, fn: Callable[..., T], *args: Any, **kwargs: Any):
        self._out: dict[str, Any] = {}

        def run() -> None:
            try:
                self._out["value"] = fn(*args, **kwargs)
            except BaseException as exc:  # raised again by result()
                self._out["error"] = exc

        self._thread = threading.Thread(target=run, name=f"ftrac-{getattr(fn, '__name__', 'call')}", daemon=True)
        self._thread.start()

    def result(self) -> T:
        """The call's value, once it has returned; its exception, raised here, if it raised."""
        self._thread.join()
        if "error" in self._out:
            raise self._out["error"]
        return self._out["value"]


def beside(fn: Callable[..., T], *args: Any, **kwargs: Any) -> Beside[T]:
    """``fn(*args, **kwargs)`` started on a thread of its own while the caller goes on; the
    caller must call :meth:`Beside.result` (also when it fails itself, so that no thread is
    left running into the next image). Only worth it for work that lets go of the
    interpreter. A thread per call rather than a pool: a forked worker process (the
    optimiser's, a data loader's) would inherit a pool without its threads."""
    return Beside(fn, *args, **kwargs)
