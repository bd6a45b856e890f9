"""The EM loop: alternate an E-step smoother and an M-step until the parameters settle.

    theta_{i+1} = M(E(theta_i)),  stop when max relative change of (m, I) < tol
    or after max_iterations. The E-step's log-likelihood log p(y | theta_i) is recorded
    at every iteration; EM guarantees it never decreases for an exact E-step and M-step,
    so any decrease (possible with the EKF's linearisation) is flagged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior, StateSpaceModel
from pinquad.identify import MStepResult, relative_change
from pinquad.ssm import NoiseModel, Observations, QuadSSM, Theta

Array = NDArray[np.float64]

Smoother = Callable[[StateSpaceModel, Array], Posterior]
MStep = Callable[[Posterior, Observations, Theta], MStepResult]

PAPER_Q0 = 0.0707
PAPER_R0 = 0.00707


@dataclass(frozen=True)
class EMResult:
    """Outcome of one EM run.

    theta: final parameters; posterior: the last E-step's posterior (at the parameters
    before the last M-step); mass (I+1,), inertia_diag (I+1, 3): the parameter after
    each iteration (index 0 = initial); loglik (I,): E-step log-likelihood per
    iteration [nats]; converged; decreases: iterations whose log-likelihood fell by
    more than 1e-6 relative.
    """

    theta: Theta
    posterior: Posterior
    mass: Array
    inertia_diag: Array
    loglik: Array
    converged: bool
    decreases: tuple[int, ...]

    @property
    def iterations(self) -> int:
        return int(self.loglik.shape[0])


def paper_noise(meas_dim: int) -> NoiseModel:
    """The paper's fixed covariances: Q0 = 0.0707 I (12), R0 = 0.00707 I."""
    return NoiseModel(wrench=np.zeros(6), q_kin=np.zeros(6), meas=np.full(meas_dim, PAPER_R0),
                      fixed_q=np.full(12, PAPER_Q0))


def initial_theta(obs: Observations, mass: float, inertia: Array, gravity: float) -> Theta:
    """Start of EM: the given mass/inertia with the paper's Q0/R0 for the first E-step."""
    return Theta(mass=float(mass), inertia=np.asarray(inertia, float),
                 noise=paper_noise(3 * len(obs.channels)), gravity=gravity)


def _pack(theta: Theta) -> Array:
    """log-parameter vector [m, I diag (3), S (6), r (m)] for extrapolation."""
    nz = theta.noise
    return np.log(np.concatenate([[theta.mass], np.diag(theta.inertia), nz.wrench, nz.meas]))


def _unpack(vec: Array, like: Theta) -> Theta:
    v = np.exp(vec)
    nz = like.noise
    noise = NoiseModel(wrench=v[4:10], q_kin=nz.q_kin, meas=v[10:], fixed_q=None)
    return Theta(mass=float(v[0]), inertia=np.diag(v[1:4]), noise=noise, gravity=like.gravity)


def run_em(obs: Observations, theta0: Theta, smoother: Smoother, mstep: MStep,
           max_iterations: int = 60, tol: float = 1e-6, tol_loglik: float = 1e-7,
           accelerate: bool = True,
           on_iteration: Callable[[int, Theta], None] | None = None) -> EMResult:
    """Run EM from theta0 (see module docstring).

    With ``accelerate``, after the first plain step the structured-noise iterations are
    extrapolated with SQUAREM (Varadhan and Roland 2008, scheme S3) in log-parameter
    space: from theta0, theta1 = F(theta0), theta2 = F(theta1), r = theta1 - theta0,
    v = theta2 - 2 theta1 + theta0, alpha = min(-|r|/|v|, -1),
    theta' = theta0 - 2 alpha r + alpha^2 v, then one stabilising EM step from theta';
    if the log-likelihood at theta' is below that at theta1 the plain theta2 is used.
    Every E-step counts as one iteration and is recorded.
    """
    masses = [theta0.mass]
    inertias = [np.diag(theta0.inertia).copy()]
    logliks: list[float] = []
    state: dict[str, Posterior] = {}

    def em_map(theta: Theta) -> tuple[Theta, float]:
        post = smoother(QuadSSM(obs, theta), obs.ys)
        state["post"] = post
        new = mstep(post, obs, theta).theta
        logliks.append(post.loglik)
        masses.append(new.mass)
        inertias.append(np.diag(new.inertia).copy())
        if on_iteration is not None:
            on_iteration(len(logliks) - 1, new)
        return new, post.loglik

    def settled(a: Theta, b: Theta, ll_a: float, ll_b: float) -> bool:
        ll_change = abs(ll_a - ll_b) / max(abs(ll_b), 1.0)
        return relative_change(a, b) < tol and ll_change < tol_loglik

    theta, _ = em_map(theta0)
    converged = False
    can_extrapolate = accelerate and mstep.__name__ == "regressor_mstep"
    prev_ll = -np.inf
    while len(logliks) < max_iterations and not converged:
        if not can_extrapolate or len(logliks) + 3 > max_iterations:
            new, ll = em_map(theta)
            converged = settled(new, theta, ll, prev_ll)
            theta, prev_ll = new, ll
            continue
        t1, ll0 = em_map(theta)
        if settled(t1, theta, ll0, prev_ll):
            theta, converged = t1, True
            break
        t2, ll1 = em_map(t1)
        p0, p1, p2 = _pack(theta), _pack(t1), _pack(t2)
        r = p1 - p0
        v = p2 - 2.0 * p1 + p0
        alpha = min(-float(np.linalg.norm(r)) / max(float(np.linalg.norm(v)), 1e-300), -1.0)
        jump = _unpack(p0 - 2.0 * alpha * r + alpha * alpha * v, t2)
        t3, ll_jump = em_map(jump)
        if np.isfinite(ll_jump) and ll_jump >= ll1:
            converged = settled(t3, jump, ll_jump, ll1)
            theta, prev_ll = t3, ll_jump
        else:
            theta, prev_ll = t2, ll1
    ll = np.asarray(logliks)
    start = 1 if theta0.noise.fixed_q is not None and theta.noise.fixed_q is None else 0
    decreases = tuple(int(i) for i in range(start + 1, ll.size)
                      if ll[i] < ll[i - 1] - 1e-6 * abs(ll[i - 1]))
    return EMResult(theta, state["post"], np.asarray(masses), np.vstack(inertias), ll,
                    converged, decreases)
