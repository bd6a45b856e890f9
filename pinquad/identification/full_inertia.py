"""All ten inertial parameters: mass, centre of mass and the full inertia tensor.

Pinocchio's dynamic parameters of the body about its origin O (the thrust centre),

    pi = [m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz],   h = m c,

I_O = I_c + m [c]x^T [c]x (I_c about the centre of mass c). Body-frame Newton-Euler
about O, with a_O = R^T (v'_world + g e3) the proper acceleration of O and tau = [0, 0,
F, M] the applied wrench:

    m a_O + omega' x h + omega x (omega x h)       = F e3
    I_O omega' + omega x I_O omega + h x a_O        = M

i.e. M_O [a_O; omega'] = tau - [omega x (omega x h); omega x I_O omega] with the spatial
inertia M_O = [[m 1, -[h]x], [[h]x, I_O]], and body wrench = Y pi with the regressor Y
of :func:`spatial_regressor` (equal to Pinocchio's ``computeJointTorqueRegressor``).

``FullQuadSSM`` is the E-step model with these dynamics (process noise on the wrench,
Cov = dt G S G^T, G = blockdiag(R, 1) M_O^{-1}); ``full_mstep`` maximises the expected
complete-data log-likelihood over all ten parameters,

    J(pi) = 1/2 sum_j log E[sum_k rho_kj^2] - log det M_O(pi)     (per transition)

(rho = Y pi - tau, S diagonal and profiled out, det M_O = m^3 det I_c the Jacobian of
the wrench -> state change of variables), over Pinocchio's log-Cholesky parameters
(Rucker and Wensing 2022), so every iterate is physically consistent: the pseudo-inertia
is positive definite, hence m > 0, I_c > 0 and the triangle inequalities hold.
``identify_full`` runs EM with these, from ``staged_start`` (the diagonal model's EM
refitted with the horizontal CoM) in ``offline --log --mstep full``, with
observed-information standard errors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.optimize import minimize

from estimators.protocol import Posterior
from pinquad.core.conventions import rotation_from_euler, skew
from pinquad.estep.fast_smoother import loglik_quad
from pinquad.identification.em import run_em
from pinquad.identification.fisher import determined_covariance
from pinquad.models.full import (
    FullQuadSSM,
    dynamic_parameters,
    from_dynamic_parameters,
)
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.protocol import MStep
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import MStepResult, applied_force, update_noise

Array = NDArray[np.float64]

PI_NAMES = ("m", "h_x", "h_y", "h_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz")
# The state coordinates Y(x_k, x_{k+1}) and tau depend on: velocity, Euler angles and
# rates of x_k, velocity, Euler angles (tau's force rows on a continuous flight only) and
# rates of x_{k+1} (indices into the stacked (x_k, x_{k+1}) (24,)).
_Z = np.array([3, 4, 5, 6, 7, 8, 9, 10, 11, 15, 16, 17, 18, 19, 20, 21, 22, 23])
# where applied_force's derivative columns (Theta_k, v_k, v_{k+1}, Theta_{k+1}) sit in _Z
_FORCE_COLS = np.r_[3:6, 0:3, 9:12, 12:15]
_FD_STEP = 1e-6
# (row, column) of the inertia entries pi[4:10] = [I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]
_INERTIA_ENTRIES = ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))


# ----------------------------------------------------------------------------- parameters

def log_cholesky(pi: Array) -> Array:
    """Pinocchio's log-Cholesky parameters theta (10,) of a physically consistent pi:
    the pseudo-inertia J = U U^T, U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2],
    [0, 0, e^d3, t3], [0, 0, 0, 1]] upper triangular, theta = [alpha, d1, d2, d3, s12,
    s23, s13, t1, t2, t3]. Raises ValueError if pi is not physically consistent."""
    j = np.asarray(pin.PseudoInertia.FromDynamicParameters(np.asarray(pi, float)).toMatrix())
    flip = np.eye(4)[::-1]
    try:
        upper = flip @ np.linalg.cholesky(flip @ j @ flip) @ flip
    except np.linalg.LinAlgError as exc:
        raise ValueError("the inertial parameters are not physically consistent "
                         "(pseudo-inertia not positive definite)") from exc
    alpha = math.log(upper[3, 3])
    scale = upper[3, 3]
    return np.array([alpha, math.log(upper[0, 0]) - alpha, math.log(upper[1, 1]) - alpha,
                     math.log(upper[2, 2]) - alpha, upper[0, 1] / scale, upper[1, 2] / scale,
                     upper[0, 2] / scale, upper[0, 3] / scale, upper[1, 3] / scale,
                     upper[2, 3] / scale])


def from_log_cholesky(theta: Array) -> tuple[Array, Array]:
    """pi (10,) and d pi / d theta (10, 10) of log-Cholesky parameters theta."""
    lc = pin.LogCholeskyParameters(np.asarray(theta, dtype=float))
    return np.asarray(lc.toDynamicParameters(), float).copy(), np.asarray(lc.calculateJacobian())


# ----------------------------------------------------------------------------- regressor

def _inertia_map(w: Array) -> Array:
    """L(w) (K, 3, 6) with I w = L(w) [I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]."""
    out = np.zeros(w.shape[:-1] + (3, 6))
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 3] = wx, wy, wz
    out[..., 1, 1], out[..., 1, 2], out[..., 1, 4] = wx, wy, wz
    out[..., 2, 3], out[..., 2, 4], out[..., 2, 5] = wx, wy, wz
    return out


def spatial_regressor(x_now: Array, x_next: Array, dt: float, gravity: float) -> Array:
    """Y (K, 6, 10): body wrench about O = Y pi over transitions x_k -> x_{k+1} (K, 12)
    (module docstring), with v'_world = (v_{k+1} - v_k)/dt, omega' = (omega_{k+1} -
    omega_k)/dt, omega = omega_k and R = R(Theta_k)."""
    rot = rotation_from_euler(x_now[:, 6:9])
    acc = (x_next[:, 3:6] - x_now[:, 3:6]) / dt
    acc[:, 2] += gravity
    a_o = np.einsum("kji,kj->ki", rot, acc)
    w = x_now[:, 9:12]
    wd = (x_next[:, 9:12] - x_now[:, 9:12]) / dt
    sw = skew(w)
    y = np.zeros((x_now.shape[0], 6, 10))
    y[:, 0:3, 0] = a_o
    y[:, 0:3, 1:4] = skew(wd) + sw @ sw
    y[:, 3:6, 1:4] = -skew(a_o)
    y[:, 3:6, 4:10] = _inertia_map(wd) + sw @ _inertia_map(w)
    return y


# ----------------------------------------------------------------------------- E-step model

# ----------------------------------------------------------------------------- M-step

@dataclass(frozen=True)
class FullStats:
    """Expected sufficient statistics of the wrench residuals, per row j: a (6, 10, 10),
    b (6, 10), c (6,) with E[sum_k rho_kj^2] = pi^T a_j pi - 2 b_j^T pi + c_j; n
    transitions."""

    a: Array
    b: Array
    c: Array
    n: int


def full_stats(post: Posterior, obs: Observations, gravity: float) -> FullStats:
    """FullStats over every transition the M-step uses (``identify.transition_mask``):
    the regressor and the applied wrench tau at the smoothed means, plus the first-order
    term of the residual rho = Y pi - tau about them,

        E[rho_j^2] ~ rho_j(mean)^2 + (D_j pi - T_j)^T Sigma (D_j pi - T_j),

    with D = dY/dz by central differences over the 18 state coordinates z that Y and tau
    depend on, T = d tau / dz (``mstep.updates.applied_force``'s derivative: non-zero
    only for the force rows of a continuous flight, whose thrust acts along the
    interval's mean direction F (e3 + R_k^T R_{k+1} e3) / 2 as the E-step moves it) and
    Sigma their smoothed joint covariance (from the covariances and lag-one
    cross-covariances). Held flights: tau = [0, 0, F, M], T = 0."""
    idx = np.flatnonzero(transition_mask(obs))
    dt = obs.dt
    x_now, x_next = post.mean[idx], post.mean[idx + 1]
    y = spatial_regressor(x_now, x_next, dt, gravity)
    tau = np.zeros((idx.size, 6))
    tau[:, 0:3], d_applied = applied_force(x_now, x_next, obs.inputs[idx, 0],
                                           bool(obs.continuous))
    tau[:, 3:6] = obs.inputs[idx, 1:4]
    joint = np.empty((idx.size, 24, 24))
    joint[:, 0:12, 0:12] = post.cov[idx]
    joint[:, 12:24, 12:24] = post.cov[idx + 1]
    joint[:, 12:24, 0:12] = post.cross_cov[idx]
    joint[:, 0:12, 12:24] = np.transpose(post.cross_cov[idx], (0, 2, 1))
    sigma = joint[:, _Z][:, :, _Z]
    stacked = np.concatenate([x_now, x_next], axis=1)
    deriv = np.empty((idx.size, 6, 10, _Z.size))
    for col, zi in enumerate(_Z):
        plus, minus = stacked.copy(), stacked.copy()
        plus[:, zi] += _FD_STEP
        minus[:, zi] -= _FD_STEP
        deriv[..., col] = (spatial_regressor(plus[:, :12], plus[:, 12:], dt, gravity)
                           - spatial_regressor(minus[:, :12], minus[:, 12:], dt, gravity)
                           ) / (2.0 * _FD_STEP)
    a = np.einsum("kjp,kjq->jpq", y, y)
    a += np.einsum("kjpa,kab,kjqb->jpq", deriv, sigma, deriv, optimize=True)
    b = np.einsum("kjp,kj->jp", y, tau)
    c = np.einsum("kj,kj->j", tau, tau)
    if d_applied is not None:
        d_tau = np.zeros((idx.size, 3, _Z.size))
        d_tau[:, :, _FORCE_COLS] = d_applied
        b[0:3] += np.einsum("kjpa,kab,kjb->jp", deriv[:, 0:3], sigma, d_tau, optimize=True)
        c[0:3] += np.einsum("kja,kab,kjb->j", d_tau, sigma, d_tau, optimize=True)
    return FullStats(a, b, c, int(idx.size))


def _basis() -> Array:
    """d M_O / d pi_p (10, 6, 6): M_O = [[m 1, -[h]x], [[h]x, I_O]] is linear in pi
    (built by hand: Pinocchio's constructor divides by the mass, zero for most e_p)."""
    out = np.zeros((10, 6, 6))
    out[0, 0:3, 0:3] = np.eye(3)
    for i in range(3):
        e = np.zeros(3)
        e[i] = 1.0
        out[1 + i, 0:3, 3:6] = -skew(e)
        out[1 + i, 3:6, 0:3] = skew(e)
    for p, (r, c) in enumerate(_INERTIA_ENTRIES):
        out[4 + p, 3 + r, 3 + c] = out[4 + p, 3 + c, 3 + r] = 1.0
    return out


_M_BASIS = _basis()


def objective(pi: Array, stats: FullStats) -> tuple[float, Array]:
    """J(pi) (module docstring) and its gradient dJ/dpi (10,); +inf where a row sum or
    det M_O is not positive."""
    q = np.einsum("p,jpq,q->j", pi, stats.a, pi) - 2.0 * stats.b @ pi + stats.c
    m_o = np.einsum("p,pij->ij", pi, _M_BASIS)
    sign, logdet = np.linalg.slogdet(m_o)
    if np.any(q <= 0.0) or sign <= 0:
        return math.inf, np.zeros(10)
    m_inv = np.linalg.inv(m_o)
    dq = 2.0 * np.einsum("jpq,q->jp", stats.a, pi) - 2.0 * stats.b
    grad = 0.5 * np.sum(dq / q[:, None], axis=0) - np.einsum("ij,pji->p", m_inv, _M_BASIS)
    return float(0.5 * np.sum(np.log(q / stats.n)) - logdet), grad


def _least_squares(stats: FullStats) -> Array | None:
    """The unweighted least-squares pi = (sum_j a_j)^-1 sum_j b_j, if it is physically
    consistent (else None)."""
    try:
        pi = np.linalg.solve(stats.a.sum(axis=0), stats.b.sum(axis=0))
        log_cholesky(pi)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return pi


def _consistent(pi: Array) -> Array:
    """pi itself if physically consistent, else the same mass and CoM with the inertia
    about the CoM moved towards isotropic until it is (e.g. the paper's I0 = diag(1, 2,
    1) e-4 sits on the triangle inequality's boundary)."""
    mass, com, inertia = from_dynamic_parameters(pi)
    iso = np.trace(inertia) / 3.0 * np.eye(3)
    for weight in (0.0, 0.01, 0.1, 0.5, 1.0):
        candidate = dynamic_parameters(mass, com, (1.0 - weight) * inertia + weight * iso)
        try:
            log_cholesky(candidate)
        except ValueError:
            continue
        return candidate
    raise ValueError("no physically consistent start (mass or inertia not positive)")


def maximise(stats: FullStats, start: Array) -> Array:
    """argmin J(pi) over physically consistent pi (log-Cholesky, BFGS with the analytic
    gradient), from the better of ``start`` (10,) and the unweighted least-squares
    solution. For noise-free data the least-squares solution makes every row sum
    vanish (J = -inf) and is returned as is."""

    def fun(theta: Array) -> tuple[float, Array]:
        pi, jac = from_log_cholesky(theta)
        value, grad = objective(pi, stats)
        if not math.isfinite(value):
            return 1e300, np.zeros(10)
        return value, jac.T @ grad

    candidates = [_consistent(np.asarray(start, dtype=float))]
    pi_ls = _least_squares(stats)
    if pi_ls is not None:
        fit = np.einsum("p,jpq,q->j", pi_ls, stats.a, pi_ls)
        q = fit - 2.0 * stats.b @ pi_ls + stats.c
        if np.all(q <= 1e-12 * float(np.sum(fit + stats.c))):
            return pi_ls
        candidates.append(pi_ls)
    first = min((log_cholesky(c) for c in candidates), key=lambda t: fun(t)[0])
    res = minimize(fun, first, jac=True, method="BFGS", options={"gtol": 1e-9, "maxiter": 500})
    best = res.x if res.fun <= fun(first)[0] else first
    return from_log_cholesky(best)[0]


def full_mstep(post: Posterior, obs: Observations, theta: Theta) -> MStepResult:
    """ML update of all ten inertial parameters and the noise variances."""
    stats = full_stats(post, obs, theta.gravity)
    pi = maximise(stats, dynamic_parameters(theta.mass, theta.com, theta.inertia))
    q = np.einsum("p,jpq,q->j", pi, stats.a, pi) - 2.0 * stats.b @ pi + stats.c
    row_var = np.maximum(q / stats.n, 0.0)
    noise = update_noise(post, obs, theta, row_var)
    mass, com, inertia = from_dynamic_parameters(pi)
    new = Theta(mass=mass, inertia=inertia, noise=noise, gravity=theta.gravity, com=com)
    return MStepResult(new, objective(pi, stats)[0], row_var)


def full_change(a: Theta, b: Theta) -> float:
    """Largest relative change between two full parameter sets: mass over mass, inertia
    entries over the mean principal moment, CoM over the radius of gyration."""
    scale_i = float(np.trace(b.inertia)) / 3.0
    gyration = math.sqrt(scale_i / b.mass)
    return max(abs(a.mass - b.mass) / b.mass,
               float(np.max(np.abs(np.asarray(a.inertia) - np.asarray(b.inertia)))) / scale_i,
               float(np.max(np.abs(np.asarray(a.com) - np.asarray(b.com)))) / gyration)


def full_extrapolate(old: Theta, new: Theta, eta: float) -> Theta:
    """Over-relaxed EM step: log-Cholesky parameters and log noise variances moved eta
    times the M-step's change (physically consistent for any eta); the plain step
    ``new`` when either end is physically consistent only to rounding."""
    try:
        lc_old = log_cholesky(dynamic_parameters(old.mass, old.com, old.inertia))
        lc_new = log_cholesky(dynamic_parameters(new.mass, new.com, new.inertia))
    except ValueError:  # on the boundary to rounding: take the plain step
        return new
    mass, com, inertia = from_dynamic_parameters(
        from_log_cholesky(lc_old + eta * (lc_new - lc_old))[0])
    no, nn = old.noise, new.noise

    def geo(a: Array, b: Array) -> Array:
        return np.exp(np.log(a) + eta * (np.log(b) - np.log(a)))

    noise = type(nn)(wrench=geo(no.wrench, nn.wrench), q_kin=nn.q_kin,
                     meas=geo(no.meas, nn.meas), fixed_q=None)
    return Theta(mass=mass, inertia=inertia, noise=noise, gravity=new.gravity, com=com)


# ----------------------------------------------------------------------------- EM

@dataclass(frozen=True)
class FullIdentification:
    """EM over all ten parameters: theta (mass, com, inertia about the CoM, noise);
    stderr_mass [kg], stderr_com (3,) [m], stderr_inertia (3, 3) [kg m^2] (observed
    information, ``standard_errors``; NaN when not computed); posterior; loglik (I,);
    converged; e_steps; failure (``EMResult.failure``); start: the parameters EM started
    from."""

    theta: Theta
    stderr_mass: float
    stderr_com: Array
    stderr_inertia: Array
    posterior: Posterior
    loglik: Array
    converged: bool
    e_steps: int
    failure: str | None = None
    start: Theta | None = None

    @property
    def mass(self) -> float:
        return self.theta.mass

    @property
    def com(self) -> Array:
        return np.asarray(self.theta.com)

    @property
    def inertia(self) -> Array:
        return np.asarray(self.theta.inertia)


def _derived(pi: Array) -> Array:
    """[m, c (3), I_c (3, 3) row-major] (13,) of pi."""
    mass, com, inertia = from_dynamic_parameters(pi)
    return np.concatenate([[mass], com, inertia.ravel()])


def _loglik_at(pi: Array, obs: Observations, theta: Theta, loglik: Callable | None = None
               ) -> float:
    """log p(y | pi) of the EKF (or ``loglik``) on FullQuadSSM with the ten parameters pi
    and theta's noise. The EKF is the compiled one (``fast_smoother.loglik_quad``, which
    falls back to the generic filter where its kernels do not reproduce the model)."""
    mass, com, inertia = from_dynamic_parameters(pi)
    model = FullQuadSSM(obs, Theta(mass, inertia, theta.noise, theta.gravity, com))
    return (loglik or loglik_quad)(model, obs.ys)


def standard_errors(obs: Observations, theta: Theta, loglik: Callable | None = None
                    ) -> tuple[float, Array, Array, Array]:
    """Standard errors of (mass, com, inertia about the CoM) from the observed
    information of log p(y | pi) (the EKF's, :func:`_loglik_at`) over the ten
    parameters at ``theta``, the noise held at its values: central second differences
    in pi with steps h of 1e-3 m, 1e-4 m x m and 1e-3 x the mean principal moment,

        H_ii h_i^2 = L(+e_i) - 2 L(0) + L(-e_i) =: D_i
        H_ij h_i h_j = [L(+e_i + e_j) + L(-e_i - e_j) - 2 L(0) - D_i - D_j] / 2

    (offsets in units of h, both O(h^2)), Info = -H; then the delta method through
    pi -> (m, c, I_c). Returns (se_mass, se_com (3,), se_inertia
    (3, 3), the information (10, 10)); a direction the data do not determine (the
    information not positive there: ``fisher.determined_covariance``) leaves NaN for
    the parameters it moves and the others' errors from the rest (111 likelihood
    evaluations, compiled)."""
    pi0 = dynamic_parameters(theta.mass, theta.com, theta.inertia)
    scale_i = float(np.trace(theta.inertia)) / 3.0
    steps = np.array([1e-3 * theta.mass] + [1e-4 * theta.mass] * 3 + [1e-3 * scale_i] * 6)
    n = 10
    cache: dict[tuple[int, ...], float] = {}

    def value(offset: tuple[int, ...]) -> float:
        if offset not in cache:
            cache[offset] = _loglik_at(pi0 + steps * np.asarray(offset, dtype=float), obs,
                                       theta, loglik)
        return cache[offset]

    def at(sign: int, *axes: int) -> float:
        o = [0] * n
        for a in axes:
            o[a] = sign
        return value(tuple(o))

    # second differences along the axes and along the diagonals e_i + e_j: both
    # O(h^2), and the diagonal one needs 2 new evaluations a pair where the four-corner
    # stencil needs 4 (111 evaluations in all instead of 201)
    centre = at(0)
    along = np.array([at(1, i) + at(-1, i) - 2.0 * centre for i in range(n)])
    hess = np.diag(along)
    for i in range(n):
        for j in range(i):
            hess[i, j] = hess[j, i] = 0.5 * (at(1, i, j) + at(-1, i, j) - 2.0 * centre
                                             - along[i] - along[j])
    info = -hess / np.outer(steps, steps)
    cov_pi, undetermined = determined_covariance(info, steps)
    jac = np.empty((13, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = steps[i]
        jac[:, i] = (_derived(pi0 + e) - _derived(pi0 - e)) / (2.0 * steps[i])
    var = np.diag(jac @ cov_pi @ jac.T)
    # an output the data leave undetermined: the mass if m is, c_i if m or h_i is, an
    # entry of I_c if its own entry of I_O is (the parallel-axis term's share is second
    # order in c)
    unknown = np.zeros(13, dtype=bool)
    unknown[0] = undetermined[0]
    unknown[1:4] = undetermined[0] | undetermined[1:4]
    for p, (r, c) in enumerate(_INERTIA_ENTRIES):
        unknown[4 + 3 * r + c] = unknown[4 + 3 * c + r] = undetermined[4 + p]
    se = np.where((var > 0) & ~unknown, np.sqrt(np.abs(var)), math.nan)
    return float(se[0]), se[1:4], se[4:13].reshape(3, 3), info


def identify_full(obs: Observations, start: Theta, smoother: Callable, max_iterations: int = 100,
                  tol: float = 1e-6, information: bool = True) -> FullIdentification:
    """Over-relaxed EM with ``FullQuadSSM`` and ``full_mstep`` from ``start`` (with the
    paper's fixed Q0 the first E-step is the force-free warm-up), then the observed-
    information standard errors at the result (``standard_errors``; skipped without
    ``information``)."""
    res = run_em(obs, start, smoother,
                 MStep(full_mstep, over_relaxation=True, extrapolate=full_extrapolate),
                 max_iterations=max_iterations, tol=tol, model_factory=FullQuadSSM,
                 distance=full_change)
    se_m, se_c, se_i = (standard_errors(obs, res.theta)[:3] if information
                        else (math.nan, np.full(3, math.nan), np.full((3, 3), math.nan)))
    return FullIdentification(res.theta, se_m, se_c, se_i, res.posterior, res.loglik,
                              res.converged, res.e_steps, res.failure, start=start)
