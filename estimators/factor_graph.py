"""GTSAM batch smoother (maximum a posteriori trajectory) over a
:class:`~estimators.protocol.StateSpaceModel`, returning the same
:class:`~estimators.protocol.Posterior` as the RTS smoother (``method="gtsam"``).

The factor graph has one vector variable X(k) in R^n per step and three kinds of factor,
each a residual r with covariance Sigma = L L^T (L lower Cholesky factor):

    prior        r_0   = x_0 - m_0                            Sigma = P_0
    transition   r^f_k = x_{k+1} - f_k(x_k)                   Sigma = Q_k(x_k), k < N-1
    measurement  r^h_k = residual(y_k, h_k(x_k))[o_k]         Sigma = R_k[o_k, o_k]

where o_k are the rows of y_k that are observed (not NaN) and not rejected by the EKF's
optional outlier gate; ``model.residual`` wraps angle rows. The objective is

    J(x) = sum over factors of 1/2 ||L^{-1} r||^2 + 1/2 log det(2 pi Sigma)
         = -log p(x_0..N-1, y_obs | theta)

(:func:`negative_log_posterior`), the negative log posterior up to the constant
log p(y | theta). Gauss-Newton: at the current trajectory x every residual is linearised
in NumPy, r(x + delta) ~ r + J_r delta, and whitened by its own covariance (residual and
Jacobian both multiplied by L^{-1}); each becomes a GTSAM ``JacobianFactor``
1/2 ||A delta - b||^2 with A = L^{-1} J_r, b = -L^{-1} r, in a ``GaussianFactorGraph``.
Sequential elimination in time order (x_0 first) turns it into a Gaussian Bayes net of
conditionals

    R_k delta_k + S_k delta_{k+1} = d_k + e_k,   e_k ~ N(0, I)    (S_{N-1} absent),

which is the block-tridiagonal (Kalman-like) solve; its back substitution gives the
step delta. A step-halving line search on J accepts the first alpha in 1, 1/2, 1/4, ...
that lowers J. The covariances of the smoothed marginals come from the Bayes net of the
final linearisation by the backward recursion

    G_k = -R_k^{-1} S_k,   D_k = R_k^{-1} R_k^{-T}
    Cov(x_{N-1}) = D_{N-1},   Cov(x_k) = G_k Cov(x_{k+1}) G_k^T + D_k
    Cov(x_{k+1}, x_k) = Cov(x_{k+1}) G_k^T                      (Posterior.cross_cov[k])

(the Laplace approximation at the MAP; for a linear-Gaussian model it is the exact
posterior and equals RTS). ``covariance="marginals"`` instead asks ``gtsam.Marginals``
for every marginal and adjacent joint marginal; it gives the same numbers but is far
slower on long sequences (see :func:`smooth`).

Q_k may depend on x_k; like the EKF, the Gauss-Newton Jacobian treats it as frozen at
the linearisation point (dQ/dx is ignored), while J uses Q_k evaluated at the trial
trajectory. Q_k, R_k and P_0 must be positive definite: the graph whitens by their
Cholesky factors.

``Posterior.loglik`` is the EKF's innovation log-likelihood log p(y | theta) at the same
parameters (the EKF also provides the default initial trajectory, its filtered means);
it is not the value of J.

GTSAM is imported at module level: this module is the optional part of ``estimators``
and nothing else in the package imports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from estimators.ekf import run_filter
from estimators.objective import (
    Linearisation,
    check_shapes,
    linearise,
    negative_log_posterior,
    used_rows,
    whiten_measurements,
)
from estimators.protocol import Array, Posterior, StateSpaceModel

# Step-halving gives up below alpha = 2^-30: by then the Gauss-Newton direction carries
# no usable decrease (rounding, or a state-dependent Q_k whose dQ/dx the step ignores).
_MAX_HALVINGS = 30

CovarianceRoute = Literal["bayes_net", "marginals"]

__all__ = ["CovarianceRoute", "SolveInfo", "negative_log_posterior", "smooth", "smooth_with_info"]


@dataclass(frozen=True)
class SolveInfo:
    """How the Gauss-Newton iteration went.

    iterations: accepted steps; converged: the stop test below was met (False after
    ``max_iterations`` steps or when the line search found no decrease); reason: which
    stop fired; cost_history (iterations + 1,): J after 0, 1, ... accepted steps [nats];
    decrement: the last Gauss-Newton predicted decrease 1/2 ||b||^2 - 1/2 ||A delta - b||^2
    [nats], which bounds every mean component's distance to the step's target by
    sqrt(2 * decrement) linearised posterior standard deviations.
    """

    iterations: int
    converged: bool
    reason: str
    cost_history: Array
    decrement: float


def _graph(lin: Linearisation, keys: list[int], units: dict[int, object]
           ) -> gtsam.GaussianFactorGraph:
    """The whitened factors as a GTSAM graph; the noise models are unit because the
    whitening is already in A and b."""

    def unit(dim: int) -> object:
        if dim not in units:
            units[dim] = gtsam.noiseModel.Unit.Create(dim)
        return units[dim]

    n = lin.prior_a.shape[0]
    graph = gtsam.GaussianFactorGraph()
    graph.push_back(gtsam.JacobianFactor(keys[0], lin.prior_a, lin.prior_b, unit(n)))
    for k in range(lin.trans_b.shape[0]):
        graph.push_back(gtsam.JacobianFactor(keys[k], lin.trans_prev[k], keys[k + 1],
                                             lin.trans_next[k], lin.trans_b[k], unit(n)))
    for k, a, b in lin.meas:
        graph.push_back(gtsam.JacobianFactor(keys[k], a, b, unit(b.size)))
    return graph


def _covariances_from_bayes_net(bayes_net: gtsam.GaussianBayesNet, keys: list[int], n: int
                                ) -> tuple[Array, Array]:
    """Backward covariance recursion over the time-ordered conditionals (module
    docstring); O(N n^3)."""
    n_steps = len(keys)
    r_blocks = np.empty((n_steps, n, n))
    s_blocks = np.empty((max(n_steps - 1, 0), n, n))
    for k in range(n_steps):
        cond = bayes_net.at(k)
        # Elimination in time order must give p(x_k | x_{k+1}); unit noise because every
        # input factor was whitened. Anything else would make the recursion wrong.
        expected = keys[k:k + 2]
        if list(cond.keys()) != expected or cond.get_model() is not None:
            raise RuntimeError(f"unexpected conditional structure at step {k}")
        r_blocks[k] = cond.R()
        if k + 1 < n_steps:
            s_blocks[k] = cond.S()
    r_inv = np.linalg.inv(r_blocks)
    d_blocks = r_inv @ np.swapaxes(r_inv, 1, 2)
    gains = -(r_inv[:-1] @ s_blocks)
    cov = np.empty((n_steps, n, n))
    cross = np.empty((max(n_steps - 1, 0), n, n))
    cov[-1] = d_blocks[-1]
    for k in range(n_steps - 2, -1, -1):
        c_next_gt = cov[k + 1] @ gains[k].T
        cross[k] = c_next_gt
        c = gains[k] @ c_next_gt + d_blocks[k]
        cov[k] = 0.5 * (c + c.T)
    return cov, cross


def _covariances_from_marginals(graph: gtsam.GaussianFactorGraph, delta: gtsam.VectorValues,
                                keys: list[int], n: int) -> tuple[Array, Array]:
    """Cov(x_k) and Cov(x_{k+1}, x_k) from gtsam.Marginals (multifrontal Bayes tree)."""
    n_steps = len(keys)
    marginals = gtsam.Marginals(graph, delta)
    cov = np.empty((n_steps, n, n))
    cross = np.empty((max(n_steps - 1, 0), n, n))
    for k in range(n_steps - 1):
        joint = marginals.jointMarginalCovariance([keys[k], keys[k + 1]])
        cov[k] = joint.at(keys[k], keys[k])
        cross[k] = joint.at(keys[k + 1], keys[k])
    cov[-1] = marginals.marginalCovariance(keys[-1])
    return 0.5 * (cov + np.swapaxes(cov, 1, 2)), cross


def smooth_with_info(model: StateSpaceModel, ys: Array, *, max_iterations: int = 20,
                     tolerance: float = 1e-10, initial: Array | None = None,
                     gate_sigma: float | None = None,
                     covariance: CovarianceRoute = "bayes_net") -> tuple[Posterior, SolveInfo]:
    """:func:`smooth`, also returning how the iteration went."""
    ys = np.asarray(ys, dtype=float)
    check_shapes(model, ys, None)
    if max_iterations < 0 or not tolerance >= 0.0:
        raise ValueError("max_iterations and tolerance must be non-negative")
    if covariance not in ("bayes_net", "marginals"):
        raise ValueError(f"unknown covariance route {covariance!r}")
    filt = run_filter(model, ys, gate_sigma=gate_sigma)
    traj = filt.filtered_mean.copy() if initial is None else np.array(initial, dtype=float)
    check_shapes(model, ys, traj)
    n_steps, n = traj.shape

    white = whiten_measurements(model, used_rows(ys, filt.rejected))
    keys = [X(k) for k in range(n_steps)]
    ordering = gtsam.Ordering()
    for key in keys:
        ordering.push_back(key)
    units: dict[int, object] = {}

    lin = linearise(model, ys, traj, white)
    if not math.isfinite(lin.cost):
        raise ValueError("the negative log-posterior is not finite at the initial trajectory")
    history = [lin.cost]
    converged = False
    reason = f"max_iterations={max_iterations} reached"
    for iteration in range(max_iterations + 1):
        # Eliminate at the current point even when about to stop: the final Bayes net is
        # the linearisation the covariances must come from.
        graph = _graph(lin, keys, units)
        bayes_net = graph.eliminateSequential(ordering)
        delta_values = bayes_net.optimize()
        decrement = lin.half_sq - graph.error(delta_values)
        if decrement <= tolerance * (1.0 + lin.half_sq):
            converged = True
            reason = "predicted decrease below tolerance"
            break
        if iteration == max_iterations:
            break
        delta = np.asarray(delta_values.vector(keys)).reshape(n_steps, n)
        alpha = 1.0
        for _ in range(_MAX_HALVINGS + 1):
            trial = linearise(model, ys, traj + alpha * delta, white)
            if trial.cost < lin.cost:
                break
            alpha *= 0.5
        else:
            reason = "line search found no decrease along the Gauss-Newton step"
            break
        traj = traj + alpha * delta
        lin = trial
        history.append(lin.cost)

    if covariance == "bayes_net":
        cov, cross = _covariances_from_bayes_net(bayes_net, keys, n)
    else:
        cov, cross = _covariances_from_marginals(graph, delta_values, keys, n)
    post = Posterior(traj, cov, cross, filt.loglik, "gtsam", filt.rejected)
    info = SolveInfo(len(history) - 1, converged, reason, np.asarray(history),
                     float(decrement))
    return post, info


def smooth(model: StateSpaceModel, ys: Array, *, max_iterations: int = 20,
           tolerance: float = 1e-10, initial: Array | None = None,
           gate_sigma: float | None = None,
           covariance: CovarianceRoute = "bayes_net") -> Posterior:
    """MAP trajectory and its Laplace marginals p(x_k | all y) by Gauss-Newton on the
    factor graph (module docstring), a drop-in for :func:`estimators.rts.smooth`.

    ys (N, m), NaN = not observed. ``initial`` (N, n): starting trajectory (default: the
    EKF's filtered means). Stops when the Gauss-Newton predicted decrease is at most
    ``tolerance * (1 + 1/2 sum of squared whitened residuals)``, after ``max_iterations``
    accepted steps, or when step halving finds no decrease. ``gate_sigma``: the EKF's
    outlier gate; rows it rejects are left out of the graph and reported in
    ``Posterior.rejected``, as RTS does. ``covariance``: "bayes_net" (backward recursion
    over GTSAM's time-ordered conditionals, O(N)) or "marginals" (``gtsam.Marginals``
    joint marginals of adjacent variables, same result, much slower for long N).
    ``Posterior.loglik`` is the EKF's log p(y | theta) at the same parameters.
    """
    post, _ = smooth_with_info(model, ys, max_iterations=max_iterations, tolerance=tolerance,
                               initial=initial, gate_sigma=gate_sigma, covariance=covariance)
    return post
