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
``block_seconds``; even blocks train, odd blocks are held out. A candidate is selected
when, fitted on the training blocks together with the effects already selected,

* its held-out residual sum of squares on the rows it explains (each row scaled by the
  training variance) falls by at least ``min_heldout_gain`` (relative), and
* it passes BIC on the training blocks (2 dJ > p log n) and improves the held-out
  Gaussian log-likelihood.

The best such candidate is added and the search repeats until none passes. The refit
folds the identified effects into the observations (thrust/torque corrections at the
smoothed state, lagged inputs, de-biased gyro) and reruns EM with the unchanged
E-step and M-step on the training blocks (the held-out transitions excluded from the
M-step), alternating with re-estimates of the coefficients. Residual RMS before (base
model) and after (refit + effects) is measured on the held-out blocks only, per axis,
on ``window_seconds`` means (white wrench noise averages out, structure remains).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize, minimize_scalar

from estimators.protocol import Posterior
from pinquad.core.conventions import euler_rate_matrix_inv, wrap_angle
from pinquad.core.effect_vocabulary import EFFECT_NAMES
from pinquad.discovery.library import (
    SPECS,
    TransitionData,
    explaining_feature,
    lag_wrench,
    lagged_inputs,
    wrench_features,
)
from pinquad.models.effect import EffectSSM
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import regressor_mstep, regressor_stats

Array = NDArray[np.float64]

AXES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")
ATT_AXES = ("att_rate_x", "att_rate_y", "att_rate_z")
"""The attitude-kinematics residual (Theta_{k+1} - Theta_k)/dt - E^{-1}(Theta_k) omega_k
[rad/s] of the smoothed means, per Euler angle (roll, pitch, yaw)."""
GYRO_AXES = ("gyro_x", "gyro_y", "gyro_z")
LAG_GRID = np.concatenate([[0.0], np.geomspace(0.002, 0.25, 28)])


@dataclass(frozen=True)
class DiscoveryConfig:
    """Settings of the discovery loop.

    block_seconds [s]: length of the alternating train/held-out blocks;
    window_seconds [s]: averaging window of the reported residual RMS;
    min_heldout_gain [-]: minimum relative held-out SSE reduction on the candidate's rows
    (calibrated on clean flights, see ``python -m pinquad.discovery``);
    max_effects: stop after this many; candidates: effect names searched;
    refit_passes: coefficient/EM alternations of the refit; em_iterations: E-steps per EM
    run of the refit (at most; the compiled E-step covers ``QuadSSM`` and ``EffectSSM``);
    restart_em: start the refit EM from the paper's warm-up (fixed Q0/R0) rather than
    the base fit's noise, which absorbed the missing effect (a refit that kept it and ran
    10 E-steps left drag flights' held-out force residual at 2.4x a clean flight's);
    full_refit: also refit on all transitions for the reported estimates (else the
    training-block refit is reported); refit_em: False skips the EM refit (mass and
    coefficients fitted on the base posterior's force rows with the base inertia held:
    measured flights, whose inertia comes from a band-limited M-step, and quick checks);
    joint_iterations, joint_tol: after the passes, at most this many single-E-step
    updates of coefficients and parameters together, until the coefficients change by
    less than joint_tol (relative; ``_joint_refinement``).
    """

    block_seconds: float = 2.0
    window_seconds: float = 0.1
    min_heldout_gain: float = 0.10
    max_effects: int = 3
    candidates: tuple[str, ...] = EFFECT_NAMES
    refit_passes: int = 2
    em_iterations: int = 100
    restart_em: bool = True
    full_refit: bool = True
    refit_em: bool = True
    joint_iterations: int = 60
    joint_tol: float = 1e-3


def _window_steps(cfg: DiscoveryConfig, dt: float) -> int:
    """Steps per averaging window of the residual RMS (``cfg.window_seconds`` / dt, >= 1)."""
    return max(int(round(cfg.window_seconds / dt)), 1)


@dataclass(frozen=True)
class CandidateScore:
    """One candidate's test in one round.

    gain: relative held-out SSE reduction on its rows [-]; d_loglik_heldout: held-out
    Gaussian log-likelihood gain [nats]; d_bic: training 2 dJ - p log n (> 0 passes);
    coefficients: fitted on the training blocks.
    """

    effect: str
    round: int
    gain: float
    d_loglik_heldout: float
    d_bic: float
    coefficients: tuple[float, ...]
    passed: bool


@dataclass(frozen=True)
class DiscoveryResult:
    """What discovery found.

    selected: effect names in the order found; coefficients / stderr: name -> (p,) in the
    units of ``pinquad.discovery.library.SPECS`` (stderr by block jackknife); scores: every
    candidate test of every round; rms_before / rms_after: held-out residual RMS per axis
    (``AXES`` [N, N m], ``GYRO_AXES`` [rad/s]); mass [kg], inertia (3, 3) [kg m^2]: after
    the refit (the base estimates if nothing was selected); theta: refit parameters;
    posterior: its E-step; validation: how before/after was measured; figures: paths.
    """

    selected: tuple[str, ...]
    coefficients: dict[str, Array]
    stderr: dict[str, Array]
    scores: tuple[CandidateScore, ...]
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    mass: float
    inertia: Array
    theta: Theta
    posterior: Posterior
    validation: str
    figures: tuple[str, ...] = field(default_factory=tuple)

    def to_report(self) -> dict:
        """The DESIGN 4.3 ``discovery`` section (plus candidate scores and refit estimates)."""
        selected = []
        for name in self.selected:
            spec = SPECS[name]
            best = [s for s in self.scores if s.effect == name and s.passed][-1]
            selected.append({
                "effect": name,
                "coefficients": {n: float(v) for n, v in zip(spec.coefficient_names,
                                                              self.coefficients[name], strict=True)},
                "stderr": {n: float(v) for n, v in zip(spec.coefficient_names,
                                                        self.stderr[name], strict=True)},
                "units": dict(zip(spec.coefficient_names, spec.units, strict=True)),
                "evidence": {"heldout_gain": best.gain, "d_loglik_heldout": best.d_loglik_heldout,
                             "d_bic_train": best.d_bic, "round": best.round,
                             "rows": [AXES[r] for r in spec.rows] or list(GYRO_AXES)},
            })
        return {
            "selected": selected,
            "residual_rms_before": dict(self.rms_before),
            "residual_rms_after": dict(self.rms_after),
            "validation": self.validation,
            "candidates": [{"effect": s.effect, "round": s.round, "heldout_gain": s.gain,
                            "d_loglik_heldout": s.d_loglik_heldout, "d_bic_train": s.d_bic,
                            "selected": s.passed} for s in self.scores],
            "refit": {"mass": self.mass, "inertia": np.asarray(self.inertia).tolist()},
            "figures": list(self.figures),
        }


# --------------------------------------------------------------------------------------
# residual statistics
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Residuals:
    """Per-transition quantities at one posterior.

    idx (K,): steps k of the used transitions; block (K,): block number; y (K, 6, 4);
    tau (K, 6); corr (B, 6, 4, 4): posterior-covariance part of E[Y^T Y] per block;
    data: effect features' view; gyro_res (N, 3) with NaN where unobserved;
    gyro_block (N,): block of each step; att_res (N, 3) [rad/s]: the attitude-kinematics
    residual (``ATT_AXES``) of transition k -> k+1, NaN on the last step and on excluded
    transitions.
    """

    idx: NDArray[np.int64]
    block: NDArray[np.int64]
    y: Array
    tau: Array
    corr: Array
    data: TransitionData
    gyro_res: Array
    gyro_block: NDArray[np.int64]
    n_blocks: int
    att_res: Array


def _blocks(obs: Observations, seconds: float) -> NDArray[np.int64]:
    """(N,) block number of each step."""
    return np.floor((obs.t - obs.t[0]) / seconds).astype(np.int64)


def _residuals(obs: Observations, post: Posterior, gravity: float, block_seconds: float
               ) -> _Residuals:
    steps_block = _blocks(obs, block_seconds)
    n_blocks = int(steps_block.max()) + 1
    stats = regressor_stats(post, obs, gravity)
    idx = np.flatnonzero(transition_mask(obs))
    block = steps_block[idx]
    corr = np.zeros((n_blocks, 6, 4, 4))
    base_ex = obs.exclude if obs.exclude.size else np.zeros(obs.n, dtype=bool)
    for b in range(n_blocks):
        sel = block == b
        if not sel.any():
            continue
        ex = base_ex.copy() | (steps_block != b)
        sb = regressor_stats(post, replace(obs, exclude=ex), gravity)
        corr[b] = sb.a - np.einsum("kap,kaq->apq", stats.y[sel], stats.y[sel])
    data = TransitionData(x=post.mean[idx], inputs=obs.inputs[idx], applied_history=obs.inputs,
                          index=idx, dt=obs.dt)
    gyro_res = np.full((obs.n, 3), np.nan)
    if "gyro" in obs.channels:
        i = obs.channels.index("gyro")
        gyro_res = obs.ys[:, 3 * i:3 * i + 3] - post.mean[:, 9:12]
    euler, rates = post.mean[:, 6:9], post.mean[:, 9:12]
    att_res = np.full((obs.n, 3), np.nan)
    att_res[idx] = (wrap_angle(euler[idx + 1] - euler[idx]) / obs.dt
                    - np.einsum("kij,kj->ki", euler_rate_matrix_inv(euler[idx]), rates[idx]))
    return _Residuals(idx, block, stats.y, stats.tau, corr, data, gyro_res, steps_block, n_blocks,
                      att_res)


def _effect_columns(res: _Residuals, effects: Sequence[str], lag: float | None
                    ) -> tuple[Array, Array]:
    """Linear feature columns Phi (K, 6, p) of ``effects`` (wrench effects only) and the
    fixed extra wrench (K, 6) of motor_lag at time constant ``lag`` (zero if absent)."""
    cols = [wrench_features(e, res.data) for e in effects
            if e not in ("motor_lag", "gyro_bias")]
    k = res.y.shape[0]
    phi = np.concatenate(cols, axis=2) if cols else np.zeros((k, 6, 0))
    fixed = lag_wrench(res.data, lag) if lag is not None and lag > 0 else np.zeros((k, 6))
    return phi, fixed


def _grams(res: _Residuals, phi: Array, fixed: Array, window: int = 0) -> Array:
    """Per-block expected Gram matrices G (B, 6, q, q), q = 4 + p + 1, of
    z = [Y, -Phi, -(tau + fixed)] so that rho - Phi c = z [pi, c, 1].

    window > 0: Gram matrices of the means of z over ``window`` consecutive steps (the
    low-frequency part the selection gain is measured on; no covariance correction)."""
    z = np.concatenate([res.y, -phi, -(res.tau + fixed)[:, :, None]], axis=2)
    q = z.shape[2]
    g = np.zeros((res.n_blocks, 6, q, q))
    if window > 0:
        key = res.block * 1_000_000 + res.idx // window
        uniq, inv = np.unique(key, return_inverse=True)
        zs = np.zeros((uniq.size, 6, q))
        np.add.at(zs, inv, z)
        zs /= np.bincount(inv)[:, None, None]
        np.add.at(g, uniq // 1_000_000, np.einsum("kaq,kar->kaqr", zs, zs))
        return g
    np.add.at(g, res.block, np.einsum("kaq,kar->kaqr", z, z))
    g[:, :, 0:4, 0:4] += res.corr
    return g


@dataclass(frozen=True)
class _Fit:
    pi: Array
    c: Array
    objective: float
    row_var: Array
    n: int


def _objective(theta_full: Array, gram: Array, n: int) -> tuple[float, Array]:
    s = np.einsum("q,aqr,r->a", theta_full, gram, theta_full)
    s = np.maximum(s, 1e-300)
    val = 0.5 * n * float(np.sum(np.log(s))) - n * (3.0 * math.log(theta_full[0])
                                                     + float(np.sum(np.log(theta_full[1:4]))))
    grad = n * np.einsum("aqr,r,a->q", gram, theta_full, 1.0 / s)
    grad[0] -= 3.0 * n / theta_full[0]
    grad[1:4] -= n / theta_full[1:4]
    return val, grad


def _fit(gram: Array, n: int, pi0: Array, p: int, hold_inertia: bool = False) -> _Fit:
    """Profiled ML over (log pi, c) of J (module docstring) for the summed Gram (6, q, q).

    hold_inertia: the inertia stays at ``pi0[1:4]`` and only (log m, c) move (J's inertia
    log det term is then constant): the measured-flight M-step fits the mass on the same
    full-band force rows, but its inertia on band-limited torque rows this fit must not
    undo."""
    free = np.array([True] + [not hold_inertia] * 3)
    scale_c = np.ones(p)
    if p:
        # c from weighted LS at pi0 (starting point and parameter scale)
        w = 1.0 / np.maximum(np.einsum("q,aqr,r->a", np.r_[pi0, np.zeros(p), 1.0], gram,
                                       np.r_[pi0, np.zeros(p), 1.0]), 1e-300)
        gw = np.einsum("a,aqr->qr", w, gram)
        cc = gw[4:4 + p, 4:4 + p]
        rhs = -(gw[4:4 + p, 0:4] @ pi0 + gw[4:4 + p, -1])
        c0 = np.linalg.lstsq(cc, rhs, rcond=None)[0]
        scale_c = np.maximum(np.abs(c0), np.sqrt(np.maximum(np.diag(np.linalg.pinv(cc)), 1e-30)))
    else:
        c0 = np.zeros(0)
    n_free = int(free.sum())

    def unpack(v: Array) -> Array:
        # log-parameter steps clipped at e^+-20: a BFGS line search from a base fit far
        # off (a CoM torque can put the inertia 100x off) must not overflow
        pi = pi0.copy()
        pi[free] *= np.exp(np.clip(v[:n_free], -20.0, 20.0))
        return np.concatenate([pi, v[n_free:] * scale_c, [1.0]])

    def fun(v: Array) -> tuple[float, Array]:
        th = unpack(v)
        val, g = _objective(th, gram, n)
        gv = np.concatenate([(g[0:4] * th[0:4])[free], g[4:4 + p] * scale_c])
        return val, gv

    v0 = np.concatenate([np.zeros(n_free), c0 / scale_c])
    out = minimize(fun, v0, jac=True, method="BFGS", options={"gtol": 1e-8, "maxiter": 500})
    th = unpack(out.x)
    s = np.einsum("q,aqr,r->a", th, gram, th)
    return _Fit(th[0:4], th[4:4 + p], float(out.fun), s / n, n)


def _heldout_sse(fit: _Fit, gram: Array) -> Array:
    th = np.concatenate([fit.pi, fit.c, [1.0]])
    return np.einsum("q,aqr,r->a", th, gram, th)


def _heldout_loglik(sse: Array, n_test: int, fit: _Fit) -> float:
    return float(-0.5 * np.sum(sse / fit.row_var) - 0.5 * n_test * np.sum(np.log(fit.row_var))
                 + n_test * (3.0 * math.log(fit.pi[0]) + np.sum(np.log(fit.pi[1:4]))))


@dataclass(frozen=True)
class _ModelFit:
    """A set of wrench effects fitted on a set of blocks: linear coefficients by effect,
    the lag time constant (or None), the fit, and the held-out SSE per row (6,)."""

    coefficients: dict[str, Array]
    lag: float | None
    fit: _Fit
    heldout_sse: Array
    n_test: int
    heldout_sse_window: Array
    train_var_window: Array


def _fit_model(res: _Residuals, effects: Sequence[str], train: NDArray[np.bool_], pi0: Array,
               window: int = 10, hold_inertia: bool = False) -> _ModelFit:
    """Fit pi and the wrench effects' coefficients on the blocks ``train`` (B,) bool
    (``hold_inertia``: mass and coefficients, the inertia held at ``pi0``'s)."""
    wrench_effects = [e for e in effects if e != "gyro_bias"]
    n_train = int(np.isin(res.block, np.flatnonzero(train)).sum())
    n_test = int(np.isin(res.block, np.flatnonzero(~train)).sum())
    phi, _ = _effect_columns(res, wrench_effects, None)
    p = phi.shape[2]

    def fit_at(lag: float | None) -> tuple[_Fit, Array]:
        _, fixed = _effect_columns(res, [], lag)
        g = _grams(res, phi, fixed)
        return (_fit(g[train].sum(axis=0), n_train, pi0, p, hold_inertia),
                g[~train].sum(axis=0))

    lag = None
    if "motor_lag" in wrench_effects:
        vals = [fit_at(t)[0].objective for t in LAG_GRID]
        i = int(np.argmin(vals))
        lo, hi = LAG_GRID[max(i - 1, 0)], LAG_GRID[min(i + 1, LAG_GRID.size - 1)]
        if hi > lo:
            opt = minimize_scalar(lambda t: fit_at(float(t))[0].objective, bounds=(lo, hi),
                                  method="bounded", options={"xatol": 1e-5})
            lag = float(opt.x) if opt.fun <= vals[i] else float(LAG_GRID[i])
        else:
            lag = float(LAG_GRID[i])
    fit, g_test = fit_at(lag)
    _, fixed = _effect_columns(res, [], lag)
    gw = _grams(res, phi, fixed, window)
    th = np.concatenate([fit.pi, fit.c, [1.0]])
    sse_w = np.einsum("q,baqr,r->ba", th, gw, th)
    coeffs: dict[str, Array] = {}
    j = 0
    for e in wrench_effects:
        if e == "motor_lag":
            coeffs[e] = np.array([lag])
            continue
        n_c = SPECS[e].n_coefficients
        coeffs[e] = fit.c[j:j + n_c].copy()
        j += n_c
    return _ModelFit(coeffs, lag, fit, _heldout_sse(fit, g_test), n_test,
                     sse_w[~train].sum(axis=0), sse_w[train].sum(axis=0))


def _gyro_fit(res: _Residuals, train_steps: NDArray[np.bool_]) -> tuple[Array, Array, Array]:
    """Gyro bias (3,) = mean training residual; held-out SSE (3,) without and with it."""
    e = res.gyro_res
    ok = ~np.isnan(e)
    tr = ok & train_steps[:, None]
    te = ok & ~train_steps[:, None]
    bias = np.array([float(np.mean(e[tr[:, i], i])) if tr[:, i].any() else 0.0 for i in range(3)])
    sse0 = np.array([float(np.sum(e[te[:, i], i] ** 2)) for i in range(3)])
    sse1 = np.array([float(np.sum((e[te[:, i], i] - bias[i]) ** 2)) for i in range(3)])
    return bias, sse0, sse1


def _score(res: _Residuals, current: Sequence[str], cand: str, pi0: Array, rnd: int,
           cfg: DiscoveryConfig, train: NDArray[np.bool_]) -> CandidateScore:
    """Test adding ``cand`` to the effects ``current`` (module docstring)."""
    if cand == "gyro_bias":
        train_steps = train[res.gyro_block]
        bias, sse0, sse1 = _gyro_fit(res, train_steps)
        ok = ~np.isnan(res.gyro_res)
        tr = ok & train_steps[:, None]
        var0 = np.array([np.mean(res.gyro_res[tr[:, i], i] ** 2) for i in range(3)])
        var1 = np.array([np.var(res.gyro_res[tr[:, i], i]) for i in range(3)])
        n_tr = tr.sum(axis=0)
        n_te = (ok & ~train_steps[:, None]).sum(axis=0)
        window = _window_steps(cfg, res.data.dt)
        steps = np.arange(res.gyro_res.shape[0])
        te_steps = ~train_steps
        w0 = np.array([_window_rms(res.gyro_res[te_steps, i], res.gyro_block[te_steps],
                                   steps[te_steps], window) for i in range(3)])
        w1 = np.array([_window_rms(res.gyro_res[te_steps, i] - bias[i], res.gyro_block[te_steps],
                                   steps[te_steps], window) for i in range(3)])
        gain = 1.0 - float(np.sum(w1**2) / np.sum(w0**2))
        d_bic = float(np.sum(n_tr * np.log(var0 / var1)) - 3 * math.log(max(n_tr.sum(), 2)))
        ll0 = -0.5 * np.sum(sse0 / var0 + n_te * np.log(var0))
        ll1 = -0.5 * np.sum(sse1 / var1 + n_te * np.log(var1))
        passed = gain >= cfg.min_heldout_gain and d_bic > 0 and ll1 > ll0
        return CandidateScore(cand, rnd, gain, float(ll1 - ll0), d_bic, tuple(bias), passed)
    window = _window_steps(cfg, res.data.dt)
    base = _fit_model(res, current, train, pi0, window)
    ext = _fit_model(res, [*current, cand], train, pi0, window)
    rows = list(SPECS[cand].rows)
    w = 1.0 / base.train_var_window[rows]
    gain = 1.0 - float(np.sum(ext.heldout_sse_window[rows] * w)
                       / np.sum(base.heldout_sse_window[rows] * w))
    p = SPECS[cand].n_coefficients
    d_bic = 2.0 * (base.fit.objective - ext.fit.objective) - p * math.log(base.fit.n)
    d_ll = (_heldout_loglik(ext.heldout_sse, ext.n_test, ext.fit)
            - _heldout_loglik(base.heldout_sse, base.n_test, base.fit))
    passed = gain >= cfg.min_heldout_gain and d_bic > 0 and d_ll > 0
    return CandidateScore(cand, rnd, gain, float(d_ll), float(d_bic),
                          tuple(float(v) for v in ext.coefficients[cand]), passed)


# --------------------------------------------------------------------------------------
# refit
# --------------------------------------------------------------------------------------


def corrected_observations(obs: Observations, state: Array, coefficients: dict[str, Array]
                           ) -> Observations:
    """Fold identified effects into the observations the unchanged E/M-steps see.

    state (N, 12): the smoothed trajectory at which state-dependent corrections are
    evaluated. motor_lag: inputs replaced by the lagged command; thrust and torque rows of
    drag / wind / ground_effect / com_offset added to the thrust and torques; gyro_bias
    subtracted from the gyro samples. The body x/y forces of drag and wind cannot be
    expressed as [F, M] inputs and are left out (they do not enter the mass/inertia
    M-step, which uses the thrust and torque rows); ``EffectSSM`` adds them to the
    E-step's transition.
    """
    inputs = obs.inputs.copy()
    if "motor_lag" in coefficients:
        inputs = lagged_inputs(obs.inputs, float(coefficients["motor_lag"][0]), obs.dt)
    idx = np.arange(obs.n)
    data = TransitionData(x=state, inputs=inputs, applied_history=inputs, index=idx, dt=obs.dt)
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
    return replace(obs, inputs=inputs, ys=ys)


def effect_mstep(coefficients: dict[str, Array]):
    """The regressor M-step (``pinquad.mstep.updates.regressor_mstep``) with the lateral wrench
    noise of an ``EffectSSM``: the body x/y force rows' variance is re-estimated from the
    residual the drag / wind forces leave,

        S_j = dt / n sum_k (E[(Y_k pi)_j] - (Phi_k c)_j)^2 + dt / n pi^T Cov-part_j pi,  j = x, y,

    (Phi at the smoothed state), instead of from Y pi alone, which would re-inflate the
    noise by the very forces the extended model now explains. Without drag or wind in
    ``coefficients`` it is ``regressor_mstep`` itself."""
    wrench_effects = [e for e in ("drag", "wind") if e in coefficients]
    if not wrench_effects:
        return regressor_mstep

    def mstep(post: Posterior, obs: Observations, theta: Theta):
        out = regressor_mstep(post, obs, theta)
        new = out.theta
        stats = regressor_stats(post, obs, theta.gravity)
        idx = np.flatnonzero(transition_mask(obs))
        data = TransitionData(x=post.mean[idx], inputs=obs.inputs[idx], applied_history=obs.inputs,
                              index=idx, dt=obs.dt)
        force = sum(np.einsum("kap,p->ka", wrench_features(e, data), coefficients[e])
                    for e in wrench_effects)
        pi = np.r_[new.mass, np.diag(new.inertia)]
        rho = np.einsum("kap,p->ka", stats.y, pi) - stats.tau - force
        cov_part = np.einsum("p,apq,q->a", pi, stats.a - np.einsum("kap,kaq->apq", stats.y, stats.y),
                             pi)
        var = (np.sum(rho**2, axis=0) + cov_part) / max(idx.size, 1)
        wrench = new.noise.wrench.copy()
        wrench[0:2] = np.maximum(obs.dt * var[0:2], 1e-6 * wrench[2])
        return replace(out, theta=new.with_noise(replace(new.noise, wrench=wrench)))

    mstep.__name__ = "regressor_mstep"  # keeps EM's over-relaxation for this M-step
    return mstep


def _model_factory(coefficients: dict[str, Array]):
    """QuadSSM unless drag or wind need body x/y forces in the transition."""
    if "drag" not in coefficients and "wind" not in coefficients:
        return QuadSSM
    drag, wind = coefficients.get("drag"), coefficients.get("wind")

    def factory(obs: Observations, theta: Theta) -> QuadSSM:
        return EffectSSM(obs, theta, drag, wind)

    return factory


def _estimate_coefficients(obs: Observations, post: Posterior, theta: Theta, effects: Sequence[str],
                           cfg: DiscoveryConfig, train: NDArray[np.bool_],
                           hold_inertia: bool = False
                           ) -> tuple[dict[str, Array], _Residuals, _ModelFit]:
    res = _residuals(obs, post, theta.gravity, cfg.block_seconds)
    train = train[: res.n_blocks]
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    mf = _fit_model(res, effects, train, pi0, hold_inertia=hold_inertia)
    coeffs = dict(mf.coefficients)
    if "gyro_bias" in effects:
        coeffs["gyro_bias"] = _gyro_fit(res, train[res.gyro_block])[0]
    return coeffs, res, mf


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
        post = smoother(_model_factory(coeffs)(corr, theta), corr.ys)
        theta = effect_mstep(coeffs)(post, corr, theta).theta
        new, _, _ = _estimate_coefficients(obs, post, theta, effects, cfg, train)
        change = max(float(np.max(np.abs(new[e] - coeffs[e])
                                  / np.maximum(np.abs(coeffs[e]), 1e-12))) for e in new)
        coeffs = new
        if change < cfg.joint_tol:
            break
    return coeffs, theta, post


def refit(obs: Observations, theta: Theta, post: Posterior, effects: Sequence[str],
          smoother, cfg: DiscoveryConfig = DiscoveryConfig(),
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
    is the one the returned posterior used. Returns the refit parameters, their posterior
    (on the corrected observations) and the final coefficients.
    """
    n_blocks = int(_blocks(obs, cfg.block_seconds).max()) + 1
    train = np.ones(n_blocks, dtype=bool) if train_blocks is None else train_blocks
    steps_block = _blocks(obs, cfg.block_seconds)
    exclude = (obs.exclude.copy() if obs.exclude.size else np.zeros(obs.n, dtype=bool))
    exclude |= ~train[steps_block]
    train_steps = train[steps_block]
    from pinquad.identification.em import run_em

    coeffs, _, mf = _estimate_coefficients(obs, post, theta, effects, cfg, train)
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
        from pinquad.identification.em import initial_theta

        theta = initial_theta(obs, theta.mass, theta.inertia, theta.gravity)
    gyro = "gyro_bias" in coeffs and "gyro" in obs.channels
    if gyro and gyro_bias_used is not None:
        coeffs["gyro_bias"] = np.asarray(gyro_bias_used, dtype=float).copy()
    for _ in range(cfg.refit_passes):
        factory = _model_factory(coeffs)
        if gyro:
            others = {e: c for e, c in coeffs.items() if e != "gyro_bias"}
            base = corrected_observations(obs, post.mean, others)
            coeffs["gyro_bias"], _ = solve_gyro_bias(base, theta, smoother, factory, train_steps,
                                                     coeffs["gyro_bias"])
        corr = replace(corrected_observations(obs, post.mean, coeffs),
                       exclude=exclude)
        em = run_em(corr, theta, smoother, effect_mstep(coeffs), max_iterations=cfg.em_iterations,
                    tol=1e-5, tol_loglik=1e-7, model_factory=factory)
        b_used = coeffs.get("gyro_bias")
        theta, post = em.theta, em.posterior
        coeffs, _, _ = _estimate_coefficients(obs, post, theta, effects, cfg, train)
        if gyro:
            coeffs["gyro_bias"] = b_used
    if cfg.joint_iterations and not gyro:
        coeffs, theta, post = _joint_refinement(obs, exclude, coeffs, theta, post, effects,
                                                smoother, cfg, train)
    if gyro:
        others = {e: c for e, c in coeffs.items() if e != "gyro_bias"}
        base = replace(corrected_observations(obs, post.mean, others), exclude=exclude)
        coeffs["gyro_bias"], post = solve_gyro_bias(base, theta, smoother, _model_factory(coeffs),
                                                    train_steps, coeffs["gyro_bias"])
    return theta, post, coeffs


# --------------------------------------------------------------------------------------
# the loop
# --------------------------------------------------------------------------------------


def _window_rms(values: Array, block: NDArray[np.int64], steps: NDArray[np.int64], window: int
                ) -> float:
    """RMS of means over windows of ``window`` consecutive steps (within one block)."""
    ok = ~np.isnan(values)
    if not ok.any():
        return float("nan")
    key = block[ok] * 100000 + steps[ok] // max(window, 1)
    _, inv = np.unique(key, return_inverse=True)
    sums = np.bincount(inv, values[ok])
    counts = np.bincount(inv)
    return float(np.sqrt(np.mean((sums / counts) ** 2)))


def _heldout_rms(res: _Residuals, pi: Array, coeffs: dict[str, Array], test: NDArray[np.bool_],
                 window: int, steps_mask: NDArray[np.bool_] | None = None) -> dict[str, float]:
    """RMS per axis of ``window``-step means of the residual on the blocks in ``test``
    (and, if given, only on the steps k with steps_mask[k])."""
    wrench = [e for e in coeffs if e not in ("motor_lag", "gyro_bias")]
    phi, fixed = _effect_columns(res, wrench, float(coeffs["motor_lag"][0]) if "motor_lag" in coeffs
                                 else None)
    c = np.concatenate([coeffs[e] for e in wrench]) if wrench else np.zeros(0)
    rho = (np.einsum("kap,p->ka", res.y, pi) - res.tau - fixed
           - np.einsum("kap,p->ka", phi, c))
    sel = test[res.block]
    if steps_mask is not None:
        sel = sel & steps_mask[res.idx]
    out = {a: _window_rms(rho[sel, i], res.block[sel], res.idx[sel], window)
           for i, a in enumerate(AXES)}
    g = res.gyro_res - (coeffs["gyro_bias"] if "gyro_bias" in coeffs else 0.0)
    gsel = test[res.gyro_block]
    steps = np.arange(g.shape[0])
    if steps_mask is not None:
        gsel = gsel & steps_mask
    for i, a in enumerate(GYRO_AXES):
        out[a] = _window_rms(g[gsel, i], res.gyro_block[gsel], steps[gsel], window)
    for i, a in enumerate(ATT_AXES):
        out[a] = _window_rms(res.att_res[gsel, i], res.gyro_block[gsel], steps[gsel], window)
    return out


def _jackknife(obs: Observations, post: Posterior, theta: Theta, effects: Sequence[str],
               cfg: DiscoveryConfig, train: NDArray[np.bool_], hold_inertia: bool = False
               ) -> dict[str, Array]:
    """Block-jackknife standard errors of the coefficients (robust to the residuals'
    serial correlation within a block)."""
    blocks = np.flatnonzero(train)
    draws: dict[str, list[Array]] = {e: [] for e in effects}
    for b in blocks:
        t = train.copy()
        t[b] = False
        c, _, _ = _estimate_coefficients(obs, post, theta, effects, cfg, t, hold_inertia)
        for e in effects:
            draws[e].append(c[e])
    nb = blocks.size
    out = {}
    for e in effects:
        d = np.asarray(draws[e])
        out[e] = np.sqrt((nb - 1) / nb * np.sum((d - d.mean(axis=0)) ** 2, axis=0))
    return out


def base_heldout_rms(obs: Observations, theta: Theta, posterior: Posterior,
                     cfg: DiscoveryConfig = DiscoveryConfig()) -> dict[str, float]:
    """The held-out residual RMS per axis that ``discover`` reports as "before" (base
    model, ``cfg.window_seconds`` means on the odd ``cfg.block_seconds`` blocks), for a
    fit on which discovery is not run: a clean flight's floor to compare "after" with."""
    res = _residuals(obs, posterior, theta.gravity, cfg.block_seconds)
    test = np.arange(res.n_blocks) % 2 == 1
    window = _window_steps(cfg, obs.dt)
    return _heldout_rms(res, np.r_[theta.mass, np.diag(theta.inertia)], {}, test, window)


def discover(obs: Observations, theta: Theta, posterior: Posterior, smoother=None,
             cfg: DiscoveryConfig = DiscoveryConfig(), figures_dir: str | Path | None = None
             ) -> DiscoveryResult:
    """Find the significant unmodelled effects of a base-model EM fit (module docstring).

    obs: the log's observations; theta / posterior: base EM result on them; smoother:
    the E-step for the refit (default ``get_smoother("rts")``); figures_dir: where to
    save one figure per selected effect (none if None).
    """
    if smoother is None:
        from pinquad.identification.identify import get_smoother

        smoother = get_smoother("rts")
    res0 = _residuals(obs, posterior, theta.gravity, cfg.block_seconds)
    train = np.arange(res0.n_blocks) % 2 == 0
    test = ~train
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    window = _window_steps(cfg, obs.dt)
    before = _heldout_rms(res0, pi0, {}, test, window)
    selected: list[str] = []
    scores: list[CandidateScore] = []
    for rnd in range(cfg.max_effects):
        round_scores = [_score(res0, selected, c, pi0, rnd, cfg, train)
                        for c in cfg.candidates if c not in selected]
        passing = [s for s in round_scores if s.passed]
        best = max(passing, key=lambda s: s.gain) if passing else None
        scores.extend(replace(s, passed=(s is best)) for s in round_scores)
        if best is None:
            break
        selected.append(best.effect)
    validation = (f"{cfg.block_seconds:g}-s blocks of the flight alternate: even blocks train "
                  f"(selection fits, refit M-step), odd blocks are held out (never in a refit "
                  f"M-step); RMS per axis of {cfg.window_seconds:g}-s means of the residual on the "
                  f"held-out blocks; before: base model (EM on all data); after: refit on the "
                  f"training blocks plus the identified effects. Selection: held-out SSE gain "
                  f">= {cfg.min_heldout_gain:g}, BIC on training and held-out likelihood gain.")
    if not selected:
        return DiscoveryResult((), {}, {}, tuple(scores), before, dict(before), theta.mass,
                               np.asarray(theta.inertia), theta, posterior, validation)
    if not cfg.refit_em:
        # No EM refit: the base inertia stands (on measured flights it comes from the
        # band-limited M-step, and a full-band refit of it here would show up as worse
        # torque rows that no effect caused); mass and coefficients are fitted together
        # on the force rows, since a missing force effect bends the base mass.
        coeffs, _, mf = _estimate_coefficients(obs, posterior, theta, selected, cfg, train,
                                               hold_inertia=True)
        pi_after = mf.fit.pi
        after = _heldout_rms(res0, pi_after, coeffs, test, window)
        stderr = _jackknife(obs, posterior, theta, selected, cfg, train, hold_inertia=True)
        figures: list[str] = []
        if figures_dir is not None:
            figures = _figures(Path(figures_dir), selected, res0, pi0, res0, pi_after, coeffs,
                               test, window)
        return DiscoveryResult(tuple(selected), coeffs, stderr, tuple(scores), before, after,
                               float(pi_after[0]), np.asarray(theta.inertia), theta, posterior,
                               validation + " (no EM refit: effects fitted on the base posterior)",
                               tuple(figures))
    th_tr, post_tr, coeffs_tr = refit(obs, theta, posterior, selected, smoother, cfg, train)
    res_tr = _residuals(obs, post_tr, th_tr.gravity, cfg.block_seconds)
    pi_tr = np.r_[th_tr.mass, np.diag(th_tr.inertia)]
    after = _heldout_rms(res_tr, pi_tr, coeffs_tr, test, window)
    if cfg.full_refit:
        th_f, post_f, coeffs_f = refit(obs, th_tr, post_tr, selected, smoother,
                                       replace(cfg, refit_passes=1),
                                       gyro_bias_used=coeffs_tr.get("gyro_bias"))
        all_blocks = np.ones(res0.n_blocks, dtype=bool)
    else:
        th_f, post_f, coeffs_f = th_tr, post_tr, coeffs_tr
        all_blocks = train
    stderr = _jackknife(obs, post_f, th_f, selected, cfg, all_blocks)
    figures = []
    if figures_dir is not None:
        figures = _figures(Path(figures_dir), selected, res0, pi0, res_tr, pi_tr, coeffs_tr, test,
                           window)
    return DiscoveryResult(tuple(selected), coeffs_f, stderr, tuple(scores), before, after,
                           th_f.mass, np.asarray(th_f.inertia), th_f, post_f, validation,
                           tuple(figures))


def _figures(out: Path, selected: Sequence[str], res0: _Residuals, pi0: Array, res1: _Residuals,
             pi1: Array, coeffs: dict[str, Array], test: NDArray[np.bool_], window: int
             ) -> list[str]:
    """One figure per effect: held-out residual (window means) of its main row against the
    explaining feature, before (base model) and after (refit with the effects)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    wrench = [e for e in coeffs if e not in ("motor_lag", "gyro_bias")]
    for name in selected:
        spec = SPECS[name]
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
        for ax, res, pi, label, with_eff in ((axes[0], res0, pi0, "before (base model)", False),
                                             (axes[1], res1, pi1, "after (refit + effects)", True)):
            sel = test[res.block] if name != "gyro_bias" else test[res.gyro_block]
            if name == "gyro_bias":
                g = res.gyro_res - (coeffs["gyro_bias"] if with_eff else 0.0)
                t = np.arange(g.shape[0]) * res.data.dt
                for i in range(3):
                    ax.plot(t[sel], g[sel, i], ".", ms=1, label=GYRO_AXES[i])
                ax.set_xlabel("time [s]")
                ax.set_ylabel("gyro residual [rad/s]")
            else:
                use = {e: coeffs[e] for e in coeffs if with_eff and e != "gyro_bias"}
                phi, fixed = _effect_columns(res, [e for e in wrench if e in use],
                                             float(use["motor_lag"][0]) if "motor_lag" in use else None)
                c = np.concatenate([use[e] for e in wrench if e in use]) if wrench and use else np.zeros(0)
                rho = np.einsum("kap,p->ka", res.y, pi) - res.tau - fixed
                if c.size:
                    rho = rho - np.einsum("kap,p->ka", phi, c)
                for r in spec.rows[:2]:
                    ax.plot(explaining_feature(name, res.data, r)[sel], rho[sel, r], ".", ms=1,
                            label=AXES[r])
                ax.set_xlabel(spec.feature_name)
                ax.set_ylabel("wrench residual [N or N m]")
            ax.set_title(label)
            ax.legend(markerscale=8, fontsize=7)
        fig.suptitle(f"{name}: held-out residuals")
        fig.tight_layout()
        path = out / f"discovery_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(str(path))
    return paths


# --------------------------------------------------------------------------------------
# report text
# --------------------------------------------------------------------------------------

_AXIS_UNITS = {**{a: "N" for a in AXES[:3]}, **{a: "N m" for a in AXES[3:]},
               **{a: "rad/s" for a in GYRO_AXES + ATT_AXES}}


def discovery_markdown(section: dict) -> str:
    """The ``report.md`` text of a ``DiscoveryResult.to_report()`` section: each selected
    effect with its evidence and coefficients (value +- standard error), the held-out
    residual RMS per axis before/after (and the change in %), the candidate tests and
    the figures (paths as stored in the section, relative to the run directory)."""
    lines = ["## Effect discovery", ""]
    if "error" in section:
        return "\n".join([*lines, f"Not completed: {section['error']}", ""])
    sel = section.get("selected", [])
    if not sel:
        lines.append("No significant unmodelled effect: no candidate passed the held-out test.")
    for s in sel:
        ev = s["evidence"]
        lines.append(f"### {s['effect']}")
        lines.append("")
        lines.append(f"Evidence (round {ev['round']}): held-out SSE on {', '.join(ev['rows'])} "
                     f"falls by {100 * ev['heldout_gain']:.1f} %; held-out log-likelihood "
                     f"+{ev['d_loglik_heldout']:.1f} nats; training BIC margin "
                     f"{ev['d_bic_train']:.1f}.")
        lines.append("")
        lines.append("| coefficient | value | std. error | unit |")
        lines.append("|---|---|---|---|")
        for n, v in s["coefficients"].items():
            lines.append(f"| {n} | {v:.4g} | {s['stderr'][n]:.2g} | {s['units'][n]} |")
        lines.append("")
    before, after = section.get("residual_rms_before", {}), section.get("residual_rms_after", {})
    if before:
        lines += ["### Held-out residual RMS per axis", "",
                  "| axis | before | after | change | unit |", "|---|---|---|---|---|"]
        for a, b in before.items():
            x = after.get(a, float("nan"))
            ch = 100.0 * (x / b - 1.0) if b and np.isfinite(b) and np.isfinite(x) else float("nan")
            lines.append(f"| {a} | {b:.3g} | {x:.3g} | {ch:+.0f} % | {_AXIS_UNITS.get(a, '')} |")
        lines.append("")
    lines += [f"Validation: {section.get('validation', '')}", ""]
    cands = section.get("candidates", [])
    if cands:
        lines += ["### Candidate tests", "", "| round | effect | held-out gain | d loglik (held out) "
                  "| BIC margin | selected |", "|---|---|---|---|---|---|"]
        for c in cands:
            lines.append(f"| {c['round']} | {c['effect']} | {c['heldout_gain']:+.3f} | "
                         f"{c['d_loglik_heldout']:+.1f} | {c['d_bic_train']:+.1f} | "
                         f"{'yes' if c['selected'] else ''} |")
        lines.append("")
    refit = section.get("refit")
    if refit and sel:
        inertia = np.diag(np.asarray(refit["inertia"])) * 1e6
        lines += [f"Refit with the effects: mass {refit['mass'] * 1e3:.2f} g, inertia diagonal "
                  f"({', '.join(f'{v:.2f}' for v in inertia)}) 1e-6 kg m^2.", ""]
    for f in section.get("figures", []):
        lines += [f"![{Path(f).stem}]({f})", ""]
    return "\n".join(lines)

