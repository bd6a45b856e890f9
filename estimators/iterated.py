"""Iterated extended Kalman smoother (Bell 1994; Saerkkae, Bayesian Filtering and
Smoothing, 2nd ed., Sec. 13.2): EKF + RTS repeated on the model linearised about the
previous smoothed trajectory, which is Gauss-Newton on the negative log-posterior J of
``estimators.objective`` and ends at the MAP trajectory, the point the GTSAM batch
smoother (``estimators.factor_graph``) also finds.

One iteration at the trajectory xbar (N, n):

    f~_k(x) = f_k(xbar_k) + F_k(xbar_k) (x - xbar_k),   Q~_k = Q_k(xbar_k)
    h~_k(x) = h_k(xbar_k) + H_k(xbar_k) (x - xbar_k)
    x*      = RTS means of the affine model (the exact minimiser of J's Gauss-Newton
              quadratic at xbar), delta = x* - xbar
    xbar   <- xbar + alpha delta, alpha the first of 1, 1/2, 1/4, ... that lowers J.

It stops when every component of the step is at most ``tolerance`` posterior standard
deviations; the posterior returned is the RTS posterior of the last linearisation
(means x*, covariances and lag-one cross-covariances of the affine model), the same
Laplace approximation at the MAP that GTSAM's Bayes net gives.

The single EKF + RTS pass linearises step k at the filtered mean, which sees only
y_0..k; when a state is observed only through a nonlinear function (the yaw of a
quadcopter without an attitude sensor) those points can stay off the MAP for the whole
log. Iterating moves them to the smoothed trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.objective import check_shapes, negative_log_posterior
from estimators.protocol import Array, Posterior, StateSpaceModel
from estimators.rts import smooth as rts_smooth

# Step-halving gives up below alpha = 2^-30 (as the GTSAM smoother does).
_MAX_HALVINGS = 30


class LinearisedAbout:
    """``model`` linearised about a trajectory (N, n): the affine model f~_k, h~_k, Q~_k of
    the module docstring, with the same prior, measurement covariances and residual
    (angle wrapping). Its exact (RTS) posterior is the target of one Gauss-Newton step
    taken at the trajectory."""

    def __init__(self, model: StateSpaceModel, trajectory: Array) -> None:
        self.model = model
        self.trajectory = np.asarray(trajectory, dtype=float)
        self.state_dim = model.state_dim
        self.meas_dim = model.meas_dim
        steps = range(self.trajectory.shape[0] - 1)
        self._f = [model.transition(self.trajectory[k], k) for k in steps]
        self._q = [model.process_cov(self.trajectory[k], k) for k in steps]

    def initial(self) -> tuple[Array, Array]:
        return self.model.initial()

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        value, jac = self._f[k]
        return value + jac @ (x - self.trajectory[k]), jac

    def process_cov(self, x: Array, k: int) -> Array:
        return self._q[k]

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        value, jac = self.model.measure(self.trajectory[k], k)
        return value + jac @ (x - self.trajectory[k]), jac

    def meas_cov(self, k: int) -> Array:
        return self.model.meas_cov(k)

    def residual(self, y: Array, y_pred: Array) -> Array:
        return self.model.residual(y, y_pred)


@dataclass(frozen=True)
class IterationInfo:
    """How the iteration went.

    iterations: accepted Gauss-Newton steps; converged: the last step was within
    ``tolerance`` posterior std (False after ``max_iterations`` or a failed line search);
    reason: which stop fired; cost_history (iterations + 1,): J at the EKF + RTS means and
    after each accepted step [nats]; last_step: max over steps and states of
    |delta| / posterior std at the final linearisation.
    """

    iterations: int
    converged: bool
    reason: str
    cost_history: Array
    last_step: float


def smooth_with_info(model: StateSpaceModel, ys: Array, *, max_iterations: int = 50,
                     tolerance: float = 1e-3, gate_sigma: float | None = None
                     ) -> tuple[Posterior, IterationInfo]:
    """:func:`smooth`, also returning how the iteration went."""
    ys = np.asarray(ys, dtype=float)
    check_shapes(model, ys, None)
    if max_iterations < 0 or not tolerance > 0.0:
        raise ValueError("max_iterations must be non-negative and tolerance positive")
    first = rts_smooth(model, ys, gate_sigma=gate_sigma)
    # The outlier gate decides once, on the EKF pass; later passes see the same rows.
    ys_used = np.where(first.rejected, np.nan, ys)
    traj = first.mean
    cost = negative_log_posterior(model, ys_used, traj)
    history = [cost]
    converged = False
    reason = f"max_iterations={max_iterations} reached"
    for iteration in range(max_iterations + 1):
        lin = rts_smooth(LinearisedAbout(model, traj), ys_used)
        delta = lin.mean - traj
        step = float(np.max(np.abs(delta) / np.maximum(lin.std, np.finfo(float).tiny)))
        if step <= tolerance:
            converged = True
            reason = "step below tolerance"
            break
        if iteration == max_iterations:
            break
        alpha = 1.0
        for _ in range(_MAX_HALVINGS + 1):
            trial = traj + alpha * delta
            trial_cost = negative_log_posterior(model, ys_used, trial)
            if math.isfinite(trial_cost) and trial_cost < cost:
                break
            alpha *= 0.5
        else:
            reason = "line search found no decrease along the Gauss-Newton step"
            break
        traj, cost = trial, trial_cost
        history.append(cost)
    post = Posterior(lin.mean, lin.cov, lin.cross_cov, first.loglik, "ieks", first.rejected)
    return post, IterationInfo(len(history) - 1, converged, reason, np.asarray(history), step)


def smooth(model: StateSpaceModel, ys: Array, *, max_iterations: int = 50,
           tolerance: float = 1e-3, gate_sigma: float | None = None) -> Posterior:
    """MAP trajectory and its Laplace marginals p(x_k | all y) by the iterated EKF + RTS
    smoother (module docstring), a drop-in for :func:`estimators.rts.smooth`.

    ys (N, m), NaN = not observed. Stops when every component of the Gauss-Newton step is
    at most ``tolerance`` posterior std, after ``max_iterations`` accepted steps, or when
    step halving finds no decrease. ``gate_sigma``: the first EKF pass's outlier gate;
    the rows it rejects stay out of every later pass and are reported in
    ``Posterior.rejected``. ``Posterior.loglik`` is the first EKF pass's log p(y | theta);
    ``Posterior.method`` is "ieks".
    """
    post, _ = smooth_with_info(model, ys, max_iterations=max_iterations,
                               tolerance=tolerance, gate_sigma=gate_sigma)
    return post
