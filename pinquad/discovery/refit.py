"""The refit: mass and inertia re-identified with the selected effects in the model.

The effects are folded into the observations the unchanged E-step and M-step see
(``corrected_observations``); drag and wind, whose body x/y forces are no input, ride in
``EffectSSM``'s transition and ``effect_mstep``'s noise update; a gyro offset is solved
for the smoothed gyro residual's zero mean (``solve_gyro_bias``). The method is in
``pinquad.discovery.discover``'s docstring."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.params import VehicleRange
from pinquad.discovery.library import TransitionData, applied_lag, wrench_features
from pinquad.discovery.residuals import step_blocks
from pinquad.discovery.result import DEFAULT_CONFIG, DiscoveryConfig
from pinquad.discovery.selection import estimate_coefficients
from pinquad.identification.em import initial_theta, run_em
from pinquad.models.effect import EffectSSM
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.mstep.protocol import MStep
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import (
    applied_force,
    body_regressor,
    expected_quadratics,
    regressor_mstep,
)

Array = NDArray[np.float64]


def corrected_observations(obs: Observations, state: Array, coefficients: dict[str, Array]
                           ) -> Observations:
    """Fold identified effects into the observations the unchanged E/M-steps see.

    state (N, 12): the smoothed trajectory at which state-dependent corrections are
    evaluated. motor_lag: inputs replaced by the lagged command (``applied_lag``: on the
    log's samples when it has them; the returned inputs are no longer their interval means,
    so the returned observations carry no samples); thrust and torque rows of
    drag / wind / ground_effect / com_offset added to the thrust and torques; gyro_bias
    subtracted from the gyro samples. The body x/y forces of drag and wind cannot be
    expressed as [F, M] inputs and are left out (they do not enter the mass/inertia
    M-step, which uses the thrust and torque rows); ``EffectSSM`` adds them to the
    E-step's transition.
    """
    inputs = obs.inputs.copy()
    if "motor_lag" in coefficients:
        inputs = applied_lag(obs.inputs, obs.samples, float(coefficients["motor_lag"][0]), obs.dt)
    idx = np.arange(obs.n)
    data = TransitionData(x=state, inputs=inputs, applied_history=inputs, index=idx, dt=obs.dt,
                          ground_radius=obs.ground_radius, floor_height=obs.floor.height)
    extra = np.zeros((obs.n, 6))
    for name, c in coefficients.items():
        if name in ("motor_lag", "gyro_bias"):
            continue
        extra += np.einsum("kap,p->ka", wrench_features(name, data), c)
    inputs[:, 0] += extra[:, 2]
    inputs[:, 1:4] += extra[:, 3:6]
    ys = obs.ys.copy()
    if "gyro_bias" in coefficients and "gyro" in obs.channels:
        i = obs.channels.index("gyro")
        ys[:, 3 * i:3 * i + 3] -= coefficients["gyro_bias"]
    return replace(obs, inputs=inputs, ys=ys, samples=None)


def effect_mstep(coefficients: dict[str, Array], bounds: VehicleRange | None = None):
    """The regressor M-step (``pinquad.mstep.updates.regressor_mstep``) with the lateral wrench
    noise of an ``EffectSSM``: the body x/y force rows' variance is re-estimated from the
    residual the drag / wind forces f_k leave,

        S_j = dt / n E[sum_k ((Y_k pi)_j - tau_kj - f_kj)^2]
            = dt / n (q_j(pi) - 2 sum_k ((Y_k pi)_j - tau_kj) f_kj + sum_k f_kj^2),  j = x, y,

    (q_j = pi^T A_j pi - 2 b_j^T pi + c_j the M-step's expected row sum; tau_kj the
    applied force's row, zero for a held thrust, the thrust direction's turn on a
    continuous flight (``applied_force``); Y_k pi, tau_k and f_k at the smoothed states),
    instead of from q_j alone, which would re-inflate the noise by the very forces the
    extended model now explains. One pass over the posterior serves both (the expected
    quadratics). Without drag or wind in ``coefficients`` it is ``regressor_mstep``
    itself. bounds: the range mass and inertia are searched in (``regressor_mstep``)."""
    wrench_effects = [e for e in ("drag", "wind") if e in coefficients]

    def mstep(post: Posterior, obs: Observations, theta: Theta):
        stats = expected_quadratics(post, obs, theta.gravity)
        out = regressor_mstep(post, obs, theta, stats=stats, bounds=bounds)
        if not wrench_effects:
            return out
        new = out.theta
        idx = np.flatnonzero(transition_mask(obs))
        data = TransitionData.of(obs, post.mean[idx], idx)
        force = sum(np.einsum("kap,p->ka", wrench_features(e, data), coefficients[e])
                    for e in wrench_effects)[:, 0:2]
        x_now, x_next = post.mean[idx], post.mean[idx + 1]
        applied, _ = applied_force(x_now, x_next, obs.inputs[idx, 0], bool(obs.continuous))
        residual = (new.mass * body_regressor(x_now, x_next, obs.dt, theta.gravity)[:, 0:2, 0]
                    - applied[:, 0:2])
        pi = np.r_[new.mass, np.diag(new.inertia)]
        quad = (np.einsum("p,apq,q->a", pi, stats.a[0:2], pi) - 2.0 * stats.b[0:2] @ pi
                + stats.c[0:2])
        var = ((quad - 2.0 * np.sum(residual * force, axis=0) + np.sum(force**2, axis=0))
               / max(idx.size, 1))
        wrench = new.noise.wrench.copy()
        wrench[0:2] = np.maximum(obs.dt * var, 1e-6 * wrench[2])
        return replace(out, theta=new.with_noise(replace(new.noise, wrench=wrench)))

    return MStep(mstep, over_relaxation=True)


def model_factory(coefficients: dict[str, Array]):
    """The E-step's model class for ``coefficients``: ``QuadSSM`` unless drag or wind need
    body x/y forces in the transition (then ``EffectSSM`` at those coefficients)."""
    if "drag" not in coefficients and "wind" not in coefficients:
        return QuadSSM
    drag, wind = coefficients.get("drag"), coefficients.get("wind")

    def factory(obs: Observations, theta: Theta) -> QuadSSM:
        return EffectSSM(obs, theta, drag, wind)

    return factory


def _gyro_residual_mean(obs: Observations, post: Posterior, steps: NDArray[np.bool_]) -> Array:
    """(3,) mean over the steps ``steps`` of y_gyro - omega_k|N [rad/s]."""
    i = obs.channels.index("gyro")
    e = obs.ys[:, 3 * i:3 * i + 3] - post.mean[:, 9:12]
    ok = ~np.isnan(e) & steps[:, None]
    return np.array([float(np.mean(e[ok[:, j], j])) if ok[:, j].any() else 0.0 for j in range(3)])


def solve_gyro_bias(obs: Observations, theta: Theta, smoother, factory, steps: NDArray[np.bool_],
                    start: Array, iterations: int = 3) -> tuple[Array, Posterior]:
    """The gyro offset b (3,) [rad/s] at which the smoothed gyro residual has zero mean.

    With theta fixed, the residual mean of the observations de-biased by b is close to
    linear, f(b) = alpha (b_true - b) with 0 < alpha < 1 (the smoother absorbs part of an
    offset into the rates); f is evaluated by one E-step per point and its root found by
    secant steps per axis from b = start. Returns (b, posterior at b)."""
    i = obs.channels.index("gyro")

    def evaluate(b: Array) -> tuple[Array, Posterior]:
        ys = obs.ys.copy()
        ys[:, 3 * i:3 * i + 3] -= b
        o = replace(obs, ys=ys)
        post = smoother(factory(o, theta), o.ys)
        return _gyro_residual_mean(o, post, steps), post

    b0 = np.asarray(start, dtype=float)
    f0, post = evaluate(b0)
    b1 = b0 + f0
    for _ in range(iterations):
        f1, post = evaluate(b1)
        db = b1 - b0
        alpha = np.where(np.abs(db) > 1e-12, (f0 - f1) / np.where(np.abs(db) > 1e-12, db, 1.0), 1.0)
        b_next = b1 + f1 / np.clip(alpha, 0.02, 1.0)
        b0, f0, b1 = b1, f1, b_next
        if np.all(np.abs(f1) < 1e-6):
            break
    f1, post = evaluate(b1)
    return b1, post


def _joint_refinement(obs: Observations, exclude: NDArray[np.bool_], coeffs: dict[str, Array],
                      theta: Theta, post: Posterior, effects: Sequence[str], smoother,
                      cfg: DiscoveryConfig, train: NDArray[np.bool_]
                      ) -> tuple[dict[str, Array], Theta, Posterior]:
    """Coefficients, mass, inertia and noise updated together, one E-step at a time (an
    ECM iteration): E-step on the observations corrected with the current coefficients at
    the latest smoothed state, the regressor M-step for (m, I, noise), then the
    coefficients refitted on that posterior; until no coefficient moves by more than
    ``cfg.joint_tol`` (relative) or after ``cfg.joint_iterations`` E-steps.

    The passes of ``refit`` reach the same fixed point, but each E-step's accelerations
    lean towards the coefficients it was given, so the coefficients creep (ground effect's
    k_ge 0.79, 0.86, 0.90 over two passes where the true states give 0.99): here every
    E-step moves them, not every converged EM run. Drag and wind use ``EffectSSM`` and
    ``effect_mstep`` at the current coefficients (the generic E-step)."""
    for _ in range(cfg.joint_iterations):
        corr = replace(corrected_observations(obs, post.mean, coeffs), exclude=exclude)
        post = smoother(model_factory(coeffs)(corr, theta), corr.ys)
        theta = effect_mstep(coeffs, cfg.search)(post, corr, theta).theta
        new, _, _ = estimate_coefficients(obs, post, theta, effects, cfg, train,
                                          sampling=cfg.sampling_nuisance, bounded=True)
        change = max(float(np.max(np.abs(new[e] - coeffs[e])
                                  / np.maximum(np.abs(coeffs[e]), 1e-12))) for e in new)
        coeffs = new
        if change < cfg.joint_tol:
            break
    return coeffs, theta, post


def refit(obs: Observations, theta: Theta, post: Posterior, effects: Sequence[str],
          smoother, cfg: DiscoveryConfig = DEFAULT_CONFIG,
          train_blocks: NDArray[np.bool_] | None = None,
          gyro_bias_used: Array | None = None
          ) -> tuple[Theta, Posterior, dict[str, Array]]:
    """Re-identify mass and inertia with ``effects`` in the model.

    Alternates ``cfg.refit_passes`` times: coefficients from the current posterior
    (residuals against the original observations, training blocks), then EM (warm start
    at ``theta``) on ``corrected_observations`` with the held-out transitions excluded
    from the M-step. A gyro offset is solved before each EM pass (``solve_gyro_bias``,
    from ``gyro_bias_used`` when given: the offset already removed from the observations
    ``post`` was smoothed on) and finally at the EM's parameters, so the returned offset
    is the one the returned posterior used. Every coefficient is fitted inside its
    physical domain (``selection.fit_model``'s ``bounded``). Returns the refit
    parameters, their posterior (on the corrected observations) and the final
    coefficients.
    """
    n_blocks = int(step_blocks(obs, cfg.block_seconds).max()) + 1
    train = np.ones(n_blocks, dtype=bool) if train_blocks is None else train_blocks
    steps_block = step_blocks(obs, cfg.block_seconds)
    exclude = (obs.exclude.copy() if obs.exclude.size else np.zeros(obs.n, dtype=bool))
    exclude |= ~train[steps_block]
    train_steps = train[steps_block]
    coeffs, _, mf = estimate_coefficients(obs, post, theta, effects, cfg, train, bounded=True)
    # The base fit bent mass, inertia and the wrench noise to absorb the missing effect
    # (a CoM torque can inflate the inertia a hundredfold): start the refit EM from the
    # joint fit of (pi, c) at the base posterior, its profiled row variances as wrench
    # noise (S_j = dt s_j), the lateral rows no larger than the thrust row's.
    wrench = obs.dt * np.maximum(mf.fit.row_var, 1e-30)
    wrench[0:2] = np.minimum(wrench[0:2], wrench[2])
    if np.all(np.isfinite(mf.fit.pi)) and np.all(mf.fit.pi > 0):
        theta = replace(theta, mass=float(mf.fit.pi[0]), inertia=np.diag(mf.fit.pi[1:4]))
    theta = theta.with_noise(replace(theta.noise, wrench=wrench))
    if cfg.restart_em:
        # EM from the paper's data-driven warm-up (fixed Q0/R0) at the joint fit's mass
        # and inertia, as the base EM started, so the refit does not inherit the base
        # fit's noise levels, inflated by the effect it lacked
        theta = initial_theta(obs, theta.mass, theta.inertia, theta.gravity)
    gyro = "gyro_bias" in coeffs and "gyro" in obs.channels
    if gyro and gyro_bias_used is not None:
        coeffs["gyro_bias"] = np.asarray(gyro_bias_used, dtype=float).copy()
    for _ in range(cfg.refit_passes):
        factory = model_factory(coeffs)
        if gyro:
            others = {e: c for e, c in coeffs.items() if e != "gyro_bias"}
            base = corrected_observations(obs, post.mean, others)
            coeffs["gyro_bias"], _ = solve_gyro_bias(base, theta, smoother, factory, train_steps,
                                                     coeffs["gyro_bias"])
        corr = replace(corrected_observations(obs, post.mean, coeffs),
                       exclude=exclude)
        # one over-relaxation factor per parameter: the force noise creeps down from the
        # warm-up's inflated start while the measurement noise has settled
        em = run_em(corr, theta, smoother, effect_mstep(coeffs, cfg.search),
                    max_iterations=cfg.em_iterations, tol=1e-5, tol_loglik=1e-7,
                    model_factory=factory, per_parameter=True, bounds=cfg.search)
        b_used = coeffs.get("gyro_bias")
        theta, post = em.theta, em.posterior
        coeffs, _, _ = estimate_coefficients(obs, post, theta, effects, cfg, train,
                                             sampling=cfg.sampling_nuisance, bounded=True)
        if gyro:
            coeffs["gyro_bias"] = b_used
    if cfg.joint_iterations and not gyro:
        coeffs, theta, post = _joint_refinement(obs, exclude, coeffs, theta, post, effects,
                                                smoother, cfg, train)
    if gyro:
        others = {e: c for e, c in coeffs.items() if e != "gyro_bias"}
        base = replace(corrected_observations(obs, post.mean, others), exclude=exclude)
        coeffs["gyro_bias"], post = solve_gyro_bias(base, theta, smoother, model_factory(coeffs),
                                                    train_steps, coeffs["gyro_bias"])
    return theta, post, coeffs
