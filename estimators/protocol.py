"""The state-space model protocol and the result types shared by all smoothers.

Discrete-time model over steps k = 0 .. N-1:

    x_{k+1} = f_k(x_k) + w_k,      w_k ~ N(0, Q_k(x_k))
    y_k     = h_k(x_k) + v_k,      v_k ~ N(0, R_k)

Inputs and parameters live inside the model object (it is built for one log and one
parameter value). A measurement vector y_k may contain NaN entries: those rows were not
observed at step k and carry no information.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@runtime_checkable
class StateSpaceModel(Protocol):
    """A (possibly nonlinear) Gaussian state-space model with known inputs."""

    state_dim: int
    meas_dim: int

    def initial(self) -> tuple[Array, Array]:
        """Prior mean (n,) and covariance (n, n) of x_0."""
        ...

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        """f_k(x) (n,) and its Jacobian df_k/dx (n, n) for the step k -> k+1."""
        ...

    def process_cov(self, x: Array, k: int) -> Array:
        """Q_k (n, n), the covariance of w_k (may depend on x_k)."""
        ...

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        """h_k(x) (m,) and its Jacobian dh_k/dx (m, n)."""
        ...

    def meas_cov(self, k: int) -> Array:
        """R_k (m, m), the covariance of v_k."""
        ...

    def residual(self, y: Array, y_pred: Array) -> Array:
        """y - y_pred (m,), wrapping angle rows where the model has any."""
        ...


@dataclass(frozen=True)
class FilterResult:
    """Output of the forward (extended) Kalman filter over N steps.

    filtered_mean (N, n), filtered_cov (N, n, n): p(x_k | y_0..k).
    predicted_mean (N, n), predicted_cov (N, n, n): p(x_k | y_0..k-1); index 0 is the
        prior.
    transition_jac (N-1, n, n): df_k/dx at the filtered mean, used by RTS.
    loglik: log p(y_0..N-1) from the innovations [nats].
    nis (N,): normalised innovation squared of each step (NaN where nothing observed).
    dof (N,): number of measurement rows used at each step.
    rejected (N, m) bool: rows dropped by the outlier gate.
    """

    filtered_mean: Array
    filtered_cov: Array
    predicted_mean: Array
    predicted_cov: Array
    transition_jac: Array
    loglik: float
    nis: Array
    dof: NDArray[np.int64]
    rejected: NDArray[np.bool_]


@dataclass(frozen=True)
class Posterior:
    """Smoothed Gaussian marginals p(x_k | y_0..N-1), the E-step's answer.

    mean (N, n); cov (N, n, n); cross_cov (N-1, n, n) = Cov(x_{k+1}, x_k | all y);
    loglik: log p(y | theta) of the model that produced it [nats] (for a MAP smoother,
    the value of the filter run at the same parameters); method: "rts", "ieks" (iterated
    EKF + RTS) or "gtsam";
    rejected (N, m): measurement rows excluded as outliers.
    """

    mean: Array
    cov: Array
    cross_cov: Array
    loglik: float
    method: str
    rejected: NDArray[np.bool_]

    @property
    def std(self) -> Array:
        """(N, n) marginal standard deviations."""
        return np.sqrt(np.maximum(np.einsum("kii->ki", self.cov), 0.0))
