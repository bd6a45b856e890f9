"""A linear-Gaussian state-space model, and its exact dense joint posterior.

    x_{k+1} = A x_k + B u_k + w_k,  w_k ~ N(0, Q);   y_k = C x_k + v_k,  v_k ~ N(0, R)

Used to check every smoother against the closed-form answer, and as EM's test model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.protocol import Array


@dataclass(frozen=True)
class LinearGaussianModel:
    """A (n, n), B (n, p), inputs (N, p), C (m, n), Q (n, n), R (m, m), prior m0, P0."""

    a: Array
    c: Array
    q: Array
    r: Array
    m0: Array
    p0: Array
    b: Array | None = None
    inputs: Array | None = None

    @property
    def state_dim(self) -> int:
        return int(self.a.shape[0])

    @property
    def meas_dim(self) -> int:
        return int(self.c.shape[0])

    def initial(self) -> tuple[Array, Array]:
        return self.m0, self.p0

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        nxt = self.a @ x
        if self.b is not None and self.inputs is not None:
            nxt = nxt + self.b @ self.inputs[k]
        return nxt, self.a

    def process_cov(self, x: Array, k: int) -> Array:
        return self.q

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        return self.c @ x, self.c

    def meas_cov(self, k: int) -> Array:
        return self.r

    def residual(self, y: Array, y_pred: Array) -> Array:
        return y - y_pred

    def simulate(self, n_steps: int, rng: np.random.Generator) -> tuple[Array, Array]:
        """Draw states (N, n) and measurements (N, m) from the model."""
        xs = np.empty((n_steps, self.state_dim))
        ys = np.empty((n_steps, self.meas_dim))
        x = rng.multivariate_normal(self.m0, self.p0)
        for k in range(n_steps):
            xs[k] = x
            ys[k] = self.c @ x + rng.multivariate_normal(np.zeros(self.meas_dim), self.r)
            if k + 1 < n_steps:
                x, _ = self.transition(x, k)
                x = x + rng.multivariate_normal(np.zeros(self.state_dim), self.q)
        return xs, ys


@dataclass(frozen=True)
class DensePosterior:
    """Exact joint posterior of all states: mean (N, n), joint covariance (Nn, Nn), and
    log p(y) [nats]."""

    mean: Array
    joint_cov: Array
    loglik: float

    def block(self, i: int, j: int) -> Array:
        """Cov(x_i, x_j | y) (n, n)."""
        n = self.mean.shape[1]
        return self.joint_cov[i * n:(i + 1) * n, j * n:(j + 1) * n]


def dense_posterior(model: LinearGaussianModel, ys: Array) -> DensePosterior:
    """Condition the joint Gaussian of (x_0..N-1, observed y) on the observed y.

    Builds the prior mean mu_x and covariance Sigma_x of the stacked states from the
    recursion, then mean = mu_x + Sigma_x C^T S^{-1} (y - C mu_x) and
    cov = Sigma_x - Sigma_x C^T S^{-1} C Sigma_x over the observed rows only.
    """
    n_steps = ys.shape[0]
    n = model.state_dim
    mu = np.empty((n_steps, n))
    sig = np.zeros((n_steps * n, n_steps * n))
    mu[0] = model.m0
    # Cov(x_i, x_j) for j >= i is Cov(x_i, x_i) (A^T)^{j-i}.
    marg = [model.p0]
    for k in range(1, n_steps):
        mu[k], _ = model.transition(mu[k - 1], k - 1)
        marg.append(model.a @ marg[-1] @ model.a.T + model.q)
    for i in range(n_steps):
        block = marg[i]
        for j in range(i, n_steps):
            sig[i * n:(i + 1) * n, j * n:(j + 1) * n] = block
            sig[j * n:(j + 1) * n, i * n:(i + 1) * n] = block.T
            block = block @ model.a.T
    obs = ~np.isnan(ys)
    rows = []
    for k in range(n_steps):
        for i in np.flatnonzero(obs[k]):
            rows.append((k, i))
    big_c = np.zeros((len(rows), n_steps * n))
    big_r = np.zeros((len(rows), len(rows)))
    y_vec = np.empty(len(rows))
    for a_idx, (k, i) in enumerate(rows):
        big_c[a_idx, k * n:(k + 1) * n] = model.c[i]
        y_vec[a_idx] = ys[k, i]
        for b_idx, (k2, i2) in enumerate(rows):
            if k2 == k:
                big_r[a_idx, b_idx] = model.r[i, i2]
    s = big_c @ sig @ big_c.T + big_r
    innov = y_vec - big_c @ mu.reshape(-1)
    gain = np.linalg.solve(s, big_c @ sig).T
    mean = mu.reshape(-1) + gain @ innov
    cov = sig - gain @ big_c @ sig
    _, logdet = np.linalg.slogdet(s)
    loglik = -0.5 * (innov @ np.linalg.solve(s, innov) + logdet + len(rows) * math.log(2 * math.pi))
    return DensePosterior(mean.reshape(n_steps, n), cov, float(loglik))


@dataclass(frozen=True)
class LinearMStep:
    """Result of :func:`linear_em_mstep`: the updated model as ``theta``."""

    theta: LinearGaussianModel


def linear_em_mstep(post, data, model: LinearGaussianModel) -> LinearMStep:
    """Shumway-Stoffer M-step for A, Q and a diagonal R (C, m0, P0 kept).

    With smoothed means m_k, covariances P_k and C_k = Cov(x_k, x_{k-1} | y):
    S11 = sum_{k>=1} P_k + m_k m_k^T, S10 = sum_{k>=1} C_k + m_k m_{k-1}^T,
    S00 = sum_{k<N-1} P_k + m_k m_k^T;  A = S10 S00^{-1},  Q = (S11 - A S10^T) / (N-1);
    r_i = mean over observed k of (y_ki - c_i m_k)^2 + c_i P_k c_i^T.
    ``data`` is anything with a ``ys`` (N, m) attribute.
    """
    m, p, cross = post.mean, post.cov, post.cross_cov
    ys = data.ys
    s11 = np.einsum("ki,kj->ij", m[1:], m[1:]) + p[1:].sum(axis=0)
    s10 = np.einsum("ki,kj->ij", m[1:], m[:-1]) + cross.sum(axis=0)
    s00 = np.einsum("ki,kj->ij", m[:-1], m[:-1]) + p[:-1].sum(axis=0)
    a = s10 @ np.linalg.inv(s00)
    q = (s11 - a @ s10.T) / (m.shape[0] - 1)
    q = 0.5 * (q + q.T)
    r = np.array(np.diag(model.r), dtype=float)
    for i in range(ys.shape[1]):
        ok = ~np.isnan(ys[:, i])
        c_i = model.c[i]
        pred = m[ok] @ c_i
        var = np.einsum("j,kjl,l->k", c_i, p[ok], c_i)
        r[i] = float(np.mean((ys[ok, i] - pred) ** 2 + var))
    new = LinearGaussianModel(a=a, c=model.c, q=q, r=np.diag(r), m0=model.m0, p0=model.p0,
                              b=model.b, inputs=model.inputs)
    return LinearMStep(new)


def linear_change(a: LinearGaussianModel, b: LinearGaussianModel) -> float:
    """Largest relative change of A, Q, R entries between two models."""
    out = 0.0
    for x, y in ((a.a, b.a), (a.q, b.q), (a.r, b.r)):
        out = max(out, float(np.max(np.abs(x - y)) / max(float(np.max(np.abs(y))), 1e-300)))
    return out
