"""Small dense linear algebra for the compiled E-step (numba): fills and copies, the
Cholesky factor and solve, symmetrisation. Square matrices are 12 x 12 (the state) or
p x p (the observed rows of a step).

Element loops instead of slice assignment: numba compiles a shape-mismatch error path
for every ``a[k] = b``, which cost seconds of the first-call compile time.
"""

from __future__ import annotations

import math

from numba import njit

from pinquad.models.kernel import STATE_DIM as _N


@njit(cache=True)
def fill(a, v):
    """a[:, :] = v for a 2-d array a."""
    for r in range(a.shape[0]):
        for c in range(a.shape[1]):
            a[r, c] = v


@njit(cache=True)
def copy_vec(src, dst):
    """dst[:] = src (1-d, same length)."""
    for r in range(src.shape[0]):
        dst[r] = src[r]


@njit(cache=True)
def copy_mat(src, dst):
    """dst[:, :] = src (2-d, same shape)."""
    for r in range(src.shape[0]):
        for c in range(src.shape[1]):
            dst[r, c] = src[r, c]


@njit(cache=True)
def cholesky(a, p, low):
    """Lower Cholesky factor L of a[:p, :p] = L L^T into low[:p, :p]; False if a[:p, :p]
    is not positive definite."""
    for j in range(p):
        d = a[j, j]
        for m in range(j):
            d -= low[j, m] * low[j, m]
        if not d > 0.0:
            return False
        d = math.sqrt(d)
        low[j, j] = d
        # one division per column, not per entry (divisions dominated the factor)
        d_inv = 1.0 / d
        for i in range(j + 1, p):
            s = a[i, j]
            for m in range(j):
                s -= low[i, m] * low[j, m]
            low[i, j] = s * d_inv
    return True


@njit(cache=True)
def chol_solve(low, p, b):
    """b[:p, :] <- (L L^T)^{-1} b[:p, :] in place (L = low[:p, :p]).

    Row-oriented substitution: every update is a whole row of b (12 contiguous numbers),
    which the compiler vectorises; per entry the arithmetic is that of column-wise
    forward/back substitution, except that a row is scaled by the reciprocal of its
    pivot (one division a row instead of one an entry; it changes the last bit).
    """
    ncol = b.shape[1]
    for i in range(p):
        for m in range(i):
            lim = low[i, m]
            for c in range(ncol):
                b[i, c] -= lim * b[m, c]
        d_inv = 1.0 / low[i, i]
        for c in range(ncol):
            b[i, c] *= d_inv
    for i in range(p - 1, -1, -1):
        for m in range(i + 1, p):
            lmi = low[m, i]
            for c in range(ncol):
                b[i, c] -= lmi * b[m, c]
        d_inv = 1.0 / low[i, i]
        for c in range(ncol):
            b[i, c] *= d_inv


@njit(cache=True)
def symmetrise(c, out):
    """out = (c + c^T) / 2 for c (12, 12), as the generic path does after every
    covariance update."""
    for r in range(_N):
        for s in range(_N):
            out[r, s] = 0.5 * (c[r, s] + c[s, r])
