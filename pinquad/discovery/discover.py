"""Effect discovery: find, name, fit and refit what the identified model leaves unexplained.

After EM with the base model (mass m, diagonal inertia I), each used transition k -> k+1
leaves the body-wrench residual (``pinquad.mstep.updates``)

    rho_k = Y_k pi - tau_k        (6,) [N (force x, y, z), N m (torque x, y, z)]

each gyro sample the measurement residual e_k = y_gyro,k - omega_k|N [rad/s], and each
transition the attitude-kinematics residual (Theta_{k+1} - Theta_k)/dt - E^{-1} omega_k
[rad/s] (``ATT_AXES``; where a gyro offset shows once the E-step has put most of it into
the smoothed rates, as the base model's E-step does: about 90 % on the simulated
flights, so the gyro residual itself keeps only a tenth of it). A
candidate effect (``pinquad.discovery.library``) adds a wrench Phi_k c, so the extended model is

    Y_k pi - tau_k - Phi_k c ~ N(0, diag(s_j)),

fitted by profiled maximum likelihood over (pi, c) with the state Jacobian of the
M-step (``J = sum_j (n/2) log sum_k rho_kj^2 - n (3 log m + sum log I)``, expected
sums from the posterior including its covariances, as in ``regressor_mstep``);
``motor_lag``'s time constant is found by a grid plus golden-section search;
``gyro_bias`` is the mean of e_k.

Validation (no reward for extra parameters): the flight is cut into blocks of
``block_seconds``; even blocks train, odd blocks are held out, and then the other way
round (two folds, ``DiscoveryConfig.two_fold``). A candidate is selected when, fitted on
each fold's training blocks together with the effects already selected,

* its held-out residual sum of squares on the rows it explains (each row scaled by the
  training variance), summed over the folds, falls by at least ``min_heldout_gain``
  (relative), and
* it passes BIC on the training blocks (the folds' 2 dJ - p log n summed, > 0) and
  improves the held-out Gaussian log-likelihood (summed over the folds).

The refit still trains on the even blocks and reports the residual on the odd ones.

Every model the selection compares, the base one included, also carries two nuisance
columns with fitted coefficients (``residuals.sampling_columns``): half the change of
the thrust force within the logged interval, so that a log whose actuation is the
command sampled at each row of a faster controller (not held over the interval, as
every model here assumes) does not read as drag (docs/discovery.md, "Actuation between
samples"). The best such candidate is added and the search repeats until none passes. The refit
folds the identified effects into the observations (thrust/torque corrections at the
smoothed state, lagged inputs, de-biased gyro) and reruns EM with the unchanged
E-step and M-step on the training blocks (the held-out transitions excluded from the
M-step), alternating with re-estimates of the coefficients. Residual RMS before (base
model) and after (refit + effects) is measured on the held-out blocks only, per axis,
on ``window_seconds`` means (white wrench noise averages out, structure remains).

Modules: ``library`` (the effects' wrench features), ``residuals`` (the residual
statistics and held-out RMS), ``selection`` (fitting and testing candidates),
``refit``, ``evidence`` (the data of the report's figures), ``result`` (settings and
result types); this module runs the loop. Figures and report text are drawn by
``pinquad.report.discovery``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.discovery.domain import on_edge, project
from pinquad.discovery.evidence import effect_evidence
from pinquad.discovery.refit import refit
from pinquad.discovery.residuals import (
    Residuals,
    compute_residuals,
    heldout_rms,
    window_steps,
)
from pinquad.discovery.result import (
    DEFAULT_CONFIG,
    CandidateScore,
    DiscoveryConfig,
    DiscoveryResult,
)
from pinquad.discovery.selection import (
    base_fits,
    estimate_coefficients,
    jackknife,
    score_candidate,
)
from pinquad.discovery.uncertainty import information_fit, information_stderr, reported_stderr
from pinquad.identification.identify import get_smoother
from pinquad.models.ssm import Observations, Theta


def base_heldout_rms(obs: Observations, theta: Theta, posterior: Posterior,
                     cfg: DiscoveryConfig = DEFAULT_CONFIG) -> dict[str, float]:
    """The held-out residual RMS per axis that ``discover`` reports as "before" (base
    model, ``cfg.window_seconds`` means on the odd ``cfg.block_seconds`` blocks), for a
    fit on which discovery is not run: a clean flight's floor to compare "after" with."""
    res = compute_residuals(obs, posterior, theta.gravity, cfg.block_seconds)
    test = np.arange(res.n_blocks) % 2 == 1
    window = window_steps(cfg, obs.dt)
    return heldout_rms(res, np.r_[theta.mass, np.diag(theta.inertia)], {}, test, window)


@dataclass(frozen=True)
class Selection:
    """What the selection found on a base fit, before any refit: the selected effects
    (in order), every candidate's score, the held-out RMS per axis of the base model
    ("before"), the base posterior's residuals res0 and the training blocks (B,) bool."""

    selected: tuple[str, ...]
    scores: tuple[CandidateScore, ...]
    before: dict[str, float]
    res0: Residuals
    train: NDArray[np.bool_]


def select_effects(obs: Observations, theta: Theta, posterior: Posterior,
                   cfg: DiscoveryConfig = DEFAULT_CONFIG,
                   start_inertia: NDArray[np.float64] | None = None) -> Selection:
    """The selection of ``discover`` (module docstring) on the base posterior alone: no
    E-step, so it costs a fraction of the refit that ``refit_selection`` runs on its
    result (the null calibration needs only this). start_inertia (3,) [kg m^2]: where the
    candidates' profiled fits start their inertia instead of the base fit's (a base fit
    diverged to 1e77 kg m^2 overflows them; ``null.plausible_base_fit`` gives a plausible
    start); the held-out RMS "before" stays the base fit's."""
    res0 = compute_residuals(obs, posterior, theta.gravity, cfg.block_seconds)
    train = np.arange(res0.n_blocks) % 2 == 0
    test = ~train
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    window = window_steps(cfg, obs.dt)
    before = heldout_rms(res0, pi0, {}, test, window)
    if start_inertia is not None:
        pi0 = np.r_[theta.mass, np.asarray(start_inertia, dtype=float)]
    selected: list[str] = []
    scores: list[CandidateScore] = []
    for rnd in range(cfg.max_effects):
        todo = [c for c in cfg.candidates if c not in selected]
        base = (base_fits(res0, selected, pi0, cfg, train)
                if any(c != "gyro_bias" for c in todo) else None)
        round_scores = [score_candidate(res0, selected, c, pi0, rnd, cfg, train, base)
                        for c in todo]
        passing = [s for s in round_scores if s.passed]
        best = max(passing, key=lambda s: s.gain) if passing else None
        scores.extend(replace(s, passed=(s is best)) for s in round_scores)
        if best is None:
            break
        selected.append(best.effect)
    return Selection(tuple(selected), tuple(scores), before, res0, train)


def discover(obs: Observations, theta: Theta, posterior: Posterior, smoother=None,
             cfg: DiscoveryConfig = DEFAULT_CONFIG) -> DiscoveryResult:
    """Find the significant unmodelled effects of a base-model EM fit (module docstring).

    obs: the log's observations; theta / posterior: base EM result on them; smoother:
    the E-step for the refit (default ``get_smoother("rts")``). Draws nothing: the
    result's ``evidence`` holds the data of one figure per selected effect
    (``pinquad.report.discovery.draw_discovery_figures`` draws them). The same as
    ``refit_selection`` of ``select_effects``.
    """
    return refit_selection(obs, theta, posterior, select_effects(obs, theta, posterior, cfg),
                           smoother, cfg)


def refit_selection(obs: Observations, theta: Theta, posterior: Posterior, sel: Selection,
                    smoother=None, cfg: DiscoveryConfig = DEFAULT_CONFIG) -> DiscoveryResult:
    """The rest of ``discover`` after ``select_effects`` gave ``sel`` (on the same base
    fit and ``cfg``): the refit with the selected effects, the held-out RMS after it, the
    coefficients' standard errors and the figures' data."""
    if smoother is None:
        smoother = get_smoother("rts")
    res0, train = sel.res0, sel.train
    test = ~train
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    window = window_steps(cfg, obs.dt)
    before, selected, scores = sel.before, list(sel.selected), sel.scores
    folds_text = ("summed over two folds (even blocks train and odd are held out, then the "
                  "other way round)" if cfg.two_fold else "on the even-block fold")
    validation = (f"{cfg.block_seconds:g}-s blocks of the flight alternate: even blocks train "
                  f"(refit M-step), odd blocks are held out (never in a refit "
                  f"M-step); RMS per axis of {cfg.window_seconds:g}-s means of the residual on the "
                  f"held-out blocks; before: base model (EM on all data); after: refit on the "
                  f"training blocks plus the identified effects. Selection, {folds_text}: "
                  f"held-out SSE gain >= {cfg.min_heldout_gain:g}, BIC on training and held-out "
                  f"likelihood gain; a motor lag under {cfg.min_lag_intervals:g} log intervals "
                  f"or {1e3 * cfg.min_lag_seconds:g} ms is not selected.")
    if not selected:
        return DiscoveryResult((), {}, {}, tuple(scores), before, dict(before), theta.mass,
                               np.asarray(theta.inertia), theta, posterior, validation)
    if not cfg.refit_em:
        # No EM refit: the base inertia stands (on measured flights it comes from the
        # band-limited M-step, and a full-band refit of it here would show up as worse
        # torque rows that no effect caused); mass and coefficients are fitted together
        # on the force rows, since a missing force effect bends the base mass.
        coeffs, _, mf = estimate_coefficients(obs, posterior, theta, selected, cfg, train,
                                              hold_inertia=True, bounded=True)
        pi_after = mf.fit.pi
        after = heldout_rms(res0, pi_after, coeffs, test, window)
        jack = jackknife(obs, posterior, theta, selected, cfg, train, hold_inertia=True)
        info = information_stderr(obs, replace(theta, mass=float(pi_after[0])), posterior.mean,
                                  coeffs, selected, jack)
        evidence = effect_evidence(selected, res0, pi0, res0, pi_after, coeffs, test)
        return DiscoveryResult(tuple(selected), coeffs, reported_stderr(jack, info),
                               tuple(scores), before, after,
                               float(pi_after[0]), np.asarray(theta.inertia), theta, posterior,
                               validation + " (no EM refit: effects fitted on the base posterior)",
                               evidence, stderr_jackknife=jack, stderr_information=info,
                               coefficients_free={e: mf.free[e] for e in on_edge(coeffs)
                                                  if e in mf.free})
    th_tr, post_tr, coeffs_tr = refit(obs, theta, posterior, selected, smoother, cfg, train)
    res_tr = compute_residuals(obs, post_tr, th_tr.gravity, cfg.block_seconds)
    pi_tr = np.r_[th_tr.mass, np.diag(th_tr.inertia)]
    after = heldout_rms(res_tr, pi_tr, coeffs_tr, test, window)
    if cfg.full_refit:
        # warm start from the training-block refit, whose parameters already carry the
        # effects (restart_em guards against a base fit's noise inflated by a missing
        # effect). From there the mass and inertia move by < 1e-5 (relative) over an EM
        # pass that still takes ~80 E-steps for its log-likelihood's creep of a few
        # nats in the noise levels; the joint refinement alone (one E-step per update of
        # coefficients and parameters, until the coefficients settle) reaches the same
        # estimates within a small fraction of their standard errors (docs/benchmark.md,
        # "Discovery in a minute"). A gyro offset has no joint refinement: one EM pass.
        passes = 1 if "gyro_bias" in selected or not cfg.joint_iterations else 0
        th_f, post_f, coeffs_f = refit(obs, th_tr, post_tr, selected, smoother,
                                       replace(cfg, refit_passes=passes, restart_em=False),
                                       gyro_bias_used=coeffs_tr.get("gyro_bias"))
        all_blocks = np.ones(res0.n_blocks, dtype=bool)
    else:
        th_f, post_f, coeffs_f = th_tr, post_tr, coeffs_tr
        all_blocks = train
    jack = jackknife(obs, post_f, th_f, selected, cfg, all_blocks,
                     sampling=cfg.sampling_nuisance)
    # the coefficients at the maximum of their likelihood (theta held), where the
    # refit's alternation stalls short of it (uncertainty.information_fit)
    fit = information_fit(obs, th_f, post_f.mean, coeffs_f, selected, jack)
    info = fit.stderr
    alternation = {e: np.asarray(coeffs_f[e], dtype=float) for e in selected}
    coeffs_f = project({**coeffs_f, **fit.maximiser})
    edge = on_edge({e: coeffs_f[e] for e in selected})
    free: dict[str, NDArray[np.float64]] = {}
    if edge:
        # what the same posterior says without the domains, reported beside the edge
        unbounded, _, _ = estimate_coefficients(obs, post_f, th_f, selected, cfg, all_blocks,
                                                sampling=cfg.sampling_nuisance)
        free = {e: unbounded[e] for e in edge}
    evidence = effect_evidence(selected, res0, pi0, res_tr, pi_tr, coeffs_tr, test)
    return DiscoveryResult(tuple(selected), coeffs_f, reported_stderr(jack, info), tuple(scores),
                           before, after, th_f.mass, np.asarray(th_f.inertia), th_f, post_f,
                           validation, evidence, stderr_jackknife=jack, stderr_information=info,
                           coefficients_alternation=alternation,
                           likelihood_step_gain=fit.gain, coefficients_free=free)
