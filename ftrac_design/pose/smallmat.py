"""Solves of many tiny symmetric positive-definite systems (n ≤ 6) at once.

``np.linalg.solve`` on a stack of 5×5 matrices makes one LAPACK call per matrix (~3 µs
each here); for the thousands of systems of a batch solve or a workspace analysis an
unrolled Cholesky over the stack is ~10× faster. Small stacks go to LAPACK, whose fixed
overhead is lower than the unrolled loop's.
"""

from __future__ import annotations

import numpy as np

#: below this many matrices LAPACK's per-call cost is the smaller one
UNROLL_FROM = 48


def spd_solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``A X = B`` for SPD ``A`` (..., n, n) and ``B`` (..., n, k)."""
    n = A.shape[-1]
    count = int(np.prod(A.shape[:-2])) if A.ndim > 2 else 1
    if count < UNROLL_FROM:
        try:
            return np.linalg.solve(A, B)
        except np.linalg.LinAlgError:
            # a degenerate system (e.g. a trial pose far off): least-squares answer instead
            # of an exception; the caller sees large or non-finite residuals and rejects it
            return np.linalg.pinv(A) @ B
    # matrix axes first, so every row operation runs over one contiguous stack
    At = np.ascontiguousarray(np.moveaxis(A, (-2, -1), (0, 1)))
    Bt = np.ascontiguousarray(np.moveaxis(B, (-2, -1), (0, 1)))
    L = cholesky(At)
    Y = np.empty(Bt.shape)
    for i in range(n):
        acc = Bt[i].copy()
        for j in range(i):
            acc -= L[i][j] * Y[j]
        Y[i] = acc / L[i][i]
    X = Y
    for i in range(n - 1, -1, -1):
        acc = Y[i]
        for j in range(i + 1, n):
            acc -= L[j][i] * X[j]
        X[i] = acc / L[i][i]
    return np.moveaxis(X, (0, 1), (-2, -1))


def cholesky(At: np.ndarray) -> list[list[np.ndarray]]:
    """Lower Cholesky factor of SPD matrices given matrix-axes-first, ``At`` (n, n, ...),
    as nested lists of (...) arrays."""
    n = At.shape[0]
    L: list[list[np.ndarray]] = [[None] * n for _ in range(n)]  # type: ignore[list-item]
    for j in range(n):
        s = At[j, j].copy()
        for k in range(j):
            s -= L[j][k] * L[j][k]
        L[j][j] = np.sqrt(s)
        inv = 1.0 / L[j][j]
        for i in range(j + 1, n):
            s = At[i, j].copy()
            for k in range(j):
                s -= L[i][k] * L[j][k]
            L[i][j] = s * inv
    return L


def spd_inv(A: np.ndarray) -> np.ndarray:
    """Inverse of SPD ``A`` (..., n, n)."""
    return spd_solve(A, np.broadcast_to(np.eye(A.shape[-1]), A.shape))
