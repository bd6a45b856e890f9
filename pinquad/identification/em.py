"""The EM loop: alternate an E-step smoother and an M-step until the parameters settle.

    theta_{i+1} = M(E(theta_i)),  stop when max relative change of (m, I) < tol
    or after max_iterations. The E-step's log-likelihood log p(y | theta_i) is recorded
    at every iteration; EM guarantees it never decreases for an exact E-step and M-step,
    so any decrease (possible with the EKF's linearisation) is flagged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior, StateSpaceModel
from pinquad.core.params import VehicleRange
from pinquad.models.ssm import KinematicSSM, NoiseModel, Observations, QuadSSM, Theta
from pinquad.mstep.protocol import MStep
from pinquad.mstep.updates import relative_change

Array = NDArray[np.float64]

Smoother = Callable[[StateSpaceModel, Array], Posterior]

ETA_MAX = 16.0
"""Largest over-relaxation factor of the shared eta."""

ETA_MAX_PER_PARAMETER = 1024.0
"""Largest over-relaxation factor of one log-parameter in ``per_parameter`` mode. A
variance whose maximum-likelihood value is near zero (the lateral force noise of a flight
that has none) creeps there with plain EM steps of a fraction of a percent each (the EM
map's rate close to 1); at 16x the refit of the benchmark's 60 s log ran its 100 E-steps
twice without converging, at 1024x it converges in 36 and 3, at a higher likelihood
(docs/benchmark.md). Every relaxed step is still checked against the likelihood."""

PAPER_Q0 = 0.0707
PAPER_R0 = 0.00707


@dataclass(frozen=True)
class EMResult:
    """Outcome of one EM run.

    theta: final parameters; posterior: the E-step at theta; mass (I,), inertia_diag
    (I, 3): the iterates (index 0 = initial guess, last = theta); loglik (I,): log
    p(y | iterate) [nats]; converged; decreases: iterations whose log-likelihood fell by
    more than 1e-6 relative; e_steps: smoother runs used (over-relaxation may reject
    some); failure: why EM stopped early if an E-step broke down (the result is then
    the last iterate whose E-step worked, not converged), else None.
    """

    theta: Theta
    posterior: Posterior
    mass: Array
    inertia_diag: Array
    loglik: Array
    converged: bool
    decreases: tuple[int, ...]
    e_steps: int = 0
    failure: str | None = None

    @property
    def iterations(self) -> int:
        return int(self.loglik.shape[0])


@dataclass(frozen=True)
class EMSettings:
    """How one EM run goes (``run_em``'s options): at most ``max_iterations`` E-steps;
    stop when the relative change of (m, I) is below ``tol`` [-] and the relative
    log-likelihood change below ``tol_loglik`` [-]; ``accelerate``: over-relaxed steps
    (of an M-step that declares ``over_relaxation``), one factor per log-parameter if
    ``per_parameter``; bounds:
    the vehicle's plausible range EM does not leave (None: none)."""

    max_iterations: int = 100
    tol: float = 1e-6
    tol_loglik: float = 1e-6
    accelerate: bool = True
    per_parameter: bool = False
    bounds: VehicleRange | None = None


def paper_noise(meas_dim: int) -> NoiseModel:
    """The paper's fixed covariances: Q0 = 0.0707 I (12), R0 = 0.00707 I."""
    return NoiseModel(wrench=np.zeros(6), q_kin=np.zeros(6), meas=np.full(meas_dim, PAPER_R0),
                      fixed_q=np.full(12, PAPER_Q0))


def initial_theta(obs: Observations, mass: float, inertia: Array, gravity: float) -> Theta:
    """Start of EM: the given mass/inertia with the paper's Q0/R0 for the first E-step."""
    return Theta(mass=float(mass), inertia=np.asarray(inertia, float),
                 noise=paper_noise(3 * len(obs.channels)), gravity=gravity)


def project(theta: Theta, bounds: VehicleRange) -> Theta:
    """theta with its mass and inertia diagonal projected onto ``bounds`` (the rest,
    noise included, as it is)."""
    return replace(theta, mass=bounds.clip_mass(theta.mass),
                   inertia=np.diag(bounds.clip_inertia(np.diag(theta.inertia))))


def _pack(theta: Theta) -> Array:
    """log-parameter vector [m, I diag (3), S (6), r (m)] for extrapolation."""
    nz = theta.noise
    return np.log(np.concatenate([[theta.mass], np.diag(theta.inertia), nz.wrench, nz.meas]))


def _unpack(vec: Array, like: Theta) -> Theta:
    v = np.exp(vec)
    nz = like.noise
    noise = NoiseModel(wrench=v[4:10], q_kin=nz.q_kin, meas=v[10:], fixed_q=None)
    return Theta(mass=float(v[0]), inertia=np.diag(v[1:4]), noise=noise, gravity=like.gravity,
                 nuisance=like.nuisance)


def run_em(obs: Observations, theta0: Theta, smoother: Smoother, mstep: MStep,
           max_iterations: int = 100, tol: float = 1e-6, tol_loglik: float = 1e-6,
           accelerate: bool = True,
           on_iteration: Callable[[int, Theta], None] | None = None,
           model_factory: Callable[[Any, Any], StateSpaceModel] = QuadSSM,
           distance: Callable[[Any, Any], float] = relative_change,
           per_parameter: bool = False, bounds: VehicleRange | None = None,
           quadcopter: bool = True) -> EMResult:
    """Run EM from theta0 (see module docstring).

    mstep: the update and what it declares (``pinquad.mstep.protocol.MStep``). With
    ``accelerate`` and an M-step that declares ``over_relaxation`` (the regressor M-step,
    the ten-parameter one) the steps are over-relaxed in log-parameter space (adaptive
    over-relaxed EM, Salakhutdinov and Roweis 2003): theta_p = theta_t * (M(theta_t) /
    theta_t)^eta (the M-step's ``extrapolate(theta_t, M(theta_t), eta)`` when it has
    one); if log p(y | theta_p) >= log p(y |
    theta_t) the step is taken and eta grows by 1.5x (at most ``ETA_MAX``), otherwise eta falls
    back to 1 and the plain EM step M(theta_t) is taken. Every E-step counts towards
    ``max_iterations``; the recorded history holds the accepted iterates only, so the
    recorded log-likelihood is the EM sequence's.

    per_parameter (the packed log-parameters, an M-step without ``extrapolate``): one eta per
    log-parameter (mass, inertia, wrench noise, measurement noise), eta_i applied to
    parameter i's EM step; a parameter whose plain EM step changes sign from its
    previous one falls back to eta_i = 1 while the others keep theirs; the acceptance
    test and the growth are the same, the cap ``ETA_MAX_PER_PARAMETER``. Where one
    parameter creeps in one direction over many steps (the force noise from an inflated
    start) while another has settled and only jitters (the measurement noise), the shared
    eta over-relaxes the jitter until the step is rejected, every eighth step or so, and
    never stays large for the creep: discovery's refit took 174 E-steps where this took
    ~95 (cap 16, before the continuous E-step). On the benchmark's log the refit's two EM
    passes then ran 100 E-steps each without converging; with the cap at 1024 they take
    36 and 3, to a higher likelihood (docs/benchmark.md).

    bounds: the vehicle's plausible range (mass, inertia diagonal). The start and every
    over-relaxed step are projected onto it; the M-step must keep its own proposal inside
    (``regressor_mstep``'s ``bounds``, ``bounded_mstep``). Then each iterate maximises the
    expected complete-data log-likelihood over the box, and the likelihood still never
    decreases (a generalised EM); a parameter the log does not determine stops at the
    box's edge instead of running off to 1e80.

    When theta0 carries the paper's fixed Q0 (``initial_theta``) and the model is a
    QuadSSM (or a subclass), the first E-step uses the force-free ``KinematicSSM`` (a
    data-driven warm-up); every later one the full model. ``model_factory(obs, theta)``
    builds the E-step's model and ``distance`` measures the
    parameter change; the defaults are the quadcopter's, other models (the
    linear-Gaussian test model) pass their own, with ``quadcopter=False``: their
    parameters have no mass, inertia or noise model, so the history records NaN for
    (m, I) and there is no warm-up, over-relaxation or bounds.
    """
    is_quad = quadcopter
    warm_up = (is_quad and isinstance(model_factory, type) and issubclass(model_factory, QuadSSM)
               and theta0.noise.fixed_q is not None)

    def mass_of(theta: Any) -> float:
        return theta.mass if is_quad else float("nan")

    def inertia_of(theta: Any) -> Array:
        return np.diag(theta.inertia).copy() if is_quad else np.full(3, np.nan)

    masses = [mass_of(theta0)]
    inertias = [inertia_of(theta0)]
    logliks: list[float] = []
    n_esteps = 0
    over_relax = accelerate and is_quad and mstep.over_relaxation
    extrapolate = mstep.extrapolate

    def e_step(theta: Theta) -> Posterior:
        nonlocal n_esteps
        n_esteps += 1
        if warm_up and n_esteps == 1:
            return smoother(KinematicSSM(obs, theta), obs.ys)
        return smoother(model_factory(obs, theta), obs.ys)

    def record(theta: Theta, post: Posterior) -> None:
        logliks.append(post.loglik)
        masses.append(mass_of(theta))
        inertias.append(inertia_of(theta))

    def inside(candidate: Theta) -> Theta:
        return candidate if bounds is None or not is_quad else project(candidate, bounds)

    theta = inside(theta0)
    post = e_step(theta)
    eta: float | Array = 1.0
    per_parameter = per_parameter and over_relax and extrapolate is None
    last_step: Array | None = None  # the previous plain EM step (per_parameter)
    converged = False
    failure: str | None = None

    def try_e_step(candidate: Theta) -> Posterior | None:
        nonlocal failure
        try:
            return e_step(candidate)
        except (np.linalg.LinAlgError, FloatingPointError) as exc:
            # the filter broke down at these parameters (a covariance lost positive
            # definiteness): an over-relaxed step is retried as a plain one, a plain
            # step ends EM at the last iterate whose E-step worked
            failure = (f"E-step {n_esteps} failed at m = {mass_of(candidate):.6g} kg, "
                       f"I = {inertia_of(candidate)} kg m^2: {exc}")
            return None

    while n_esteps < max_iterations:
        proposal = mstep(post, obs, theta).theta
        step_theta = proposal
        relaxing = over_relax and theta.noise.fixed_q is None
        if relaxing and per_parameter:
            p_old = _pack(theta)
            em_step = _pack(proposal) - p_old
            eta = (np.where(np.sign(em_step) == np.sign(last_step), eta, 1.0)
                   if last_step is not None else np.ones(em_step.size))
            last_step = em_step
            if np.any(eta > 1.0):
                step_theta = inside(_unpack(p_old + eta * em_step, proposal))
        elif relaxing and eta > 1.0:
            if extrapolate is not None:
                step_theta = inside(extrapolate(theta, proposal, eta))
            else:
                p_old, p_new = _pack(theta), _pack(proposal)
                step_theta = inside(_unpack(p_old + eta * (p_new - p_old), proposal))
        new_post = try_e_step(step_theta)
        if step_theta is not proposal and (new_post is None
                                           or not (new_post.loglik >= post.loglik)):
            eta = np.ones_like(eta) if per_parameter else 1.0
            step_theta = proposal
            if n_esteps >= max_iterations:
                break
            new_post = try_e_step(step_theta)
        elif relaxing:
            eta = (np.minimum(eta * 1.5, ETA_MAX_PER_PARAMETER) if per_parameter
                   else min(eta * 1.5, ETA_MAX))
        if new_post is None:
            break
        failure = None
        ll_change = abs(new_post.loglik - post.loglik) / max(abs(post.loglik), 1.0)
        change = distance(step_theta, theta)
        # the posterior recorded with an iterate is the E-step at that iterate
        record(theta, post)
        if on_iteration is not None:
            on_iteration(len(logliks) - 1, step_theta)
        theta, post = step_theta, new_post
        if change < tol and ll_change < tol_loglik:
            converged = True
            break
    record(theta, post)
    ll = np.asarray(logliks)
    start = 1 if is_quad and theta0.noise.fixed_q is not None else 0
    decreases = tuple(int(i) for i in range(start + 1, ll.size)
                      if ll[i] < ll[i - 1] - 1e-6 * abs(ll[i - 1]))
    return EMResult(theta, post, np.asarray(masses[1:]), np.vstack(inertias[1:]), ll,
                    converged, decreases, n_esteps, failure)


SETTLED_SHARE = 0.1
"""An unconverged EM whose estimate would still move by less than this share of each
parameter's statistical standard error has settled (``remaining_move``)."""


def remaining_move(history: Array) -> Array:
    """How far EM's iterates (K, p) would still move per parameter (p,) if it went on, from
    their last two steps d_{K-1}, d_{K-2}: under linear convergence at rate
    rho = |d_{K-1}| / |d_{K-2}| the rest of the way is |d_{K-1}| rho / (1 - rho) (inf when
    rho >= 1 or fewer than three iterates)."""
    h = np.asarray(history, dtype=float)
    if h.shape[0] < 3:
        return np.full(h.shape[1], np.inf)
    last, before = np.abs(h[-1] - h[-2]), np.abs(h[-2] - h[-3])
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(before > 0, last / before, np.where(last > 0, np.inf, 0.0))
        return np.where(rho < 1.0, last * rho / (1.0 - rho), np.where(last > 0, np.inf, 0.0))

