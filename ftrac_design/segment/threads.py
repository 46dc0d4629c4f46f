"""One BLAS thread while an image is tracked.

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

from contextlib import AbstractContextManager
from functools import cache

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
