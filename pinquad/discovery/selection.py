"""Fitting and scoring candidate effects on the training blocks: the profiled maximum
likelihood of (pi, c) over summed expected Gram matrices, the motor-lag time constant by
grid plus golden section, the gyro offset as a mean, each candidate's held-out test
(SSE gain, BIC, held-out likelihood), the coefficients of a set of effects at a
posterior and their block-jackknife standard errors. The method is in
``pinquad.discovery.discover``'s docstring."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize, minimize_scalar

from estimators.protocol import Posterior
from pinquad.discovery.library import SPECS, lower_bounds
from pinquad.discovery.residuals import (
    Residuals,
    block_grams,
    compute_residuals,
    effect_columns,
    window_rms,
    window_steps,
)
from pinquad.discovery.result import CandidateScore, DiscoveryConfig
from pinquad.models.ssm import Observations, Theta

Array = NDArray[np.float64]

LAG_GRID = np.concatenate([[0.0], np.geomspace(0.002, 0.25, 28)])
"""Time constants tau_m [s] the motor-lag search starts from (0, then 2 ms to 0.25 s)."""


@dataclass(frozen=True)
class ProfiledFit:
    """The profiled ML fit of one summed Gram matrix: pi (4,) = [m (kg), I_xx, I_yy, I_zz
    (kg m^2)]; c (p,) the effects' coefficients; objective: J at the optimum; row_var (6,):
    the profiled wrench row variances s_j / n [N^2, (N m)^2]; n: transitions; c_free (p,):
    the coefficients of the fit without their domain (``profiled_fit``'s lower bounds;
    c itself when it was inside them, or no bounds were given)."""

    pi: Array
    c: Array
    objective: float
    row_var: Array
    n: int
    c_free: Array | None = None


def _objective(theta_full: Array, gram: Array, n: int) -> tuple[float, Array]:
    """J (module docstring of ``discover``) at theta_full = [pi, c, 1] and its gradient."""
    s = np.einsum("q,aqr,r->a", theta_full, gram, theta_full)
    s = np.maximum(s, 1e-300)
    val = 0.5 * n * float(np.sum(np.log(s))) - n * (3.0 * math.log(theta_full[0])
                                                     + float(np.sum(np.log(theta_full[1:4]))))
    grad = n * np.einsum("aqr,r,a->q", gram, theta_full, 1.0 / s)
    grad[0] -= 3.0 * n / theta_full[0]
    grad[1:4] -= n / theta_full[1:4]
    return val, grad


def profiled_fit(gram: Array, n: int, pi0: Array, p: int, hold_inertia: bool = False,
                 lower: Array | None = None) -> ProfiledFit:
    """Profiled ML over (log pi, c) of J (module docstring) for the summed Gram (6, q, q).

    hold_inertia: the inertia stays at ``pi0[1:4]`` and only (log m, c) move (J's inertia
    log det term is then constant): the measured-flight M-step fits the mass on the same
    full-band force rows, but its inertia on band-limited torque rows this fit must not
    undo. lower (p,) or None: each coefficient's lower bound (-inf: none; the effects'
    physical domains, ``domain.lower_bounds``). The fit is first made without them; if it
    lands below a bound, J is minimised again over the box c >= lower (L-BFGS-B from the
    projected point: coefficients on the edge stay there, the others and pi move to
    their best fit with them held), as the M-step projects the inertia onto its range;
    the free fit's coefficients are kept in ``c_free``."""
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
    c_free = th[4:4 + p].copy()
    if lower is not None and p and np.any(c_free < lower):
        lo_v = np.where(np.isfinite(lower), lower / scale_c, -np.inf)
        bounds = [(None, None)] * n_free + [(None if not np.isfinite(b) else float(b), None)
                                            for b in lo_v]
        start = out.x.copy()
        start[n_free:] = np.maximum(start[n_free:], lo_v)
        out = minimize(fun, start, jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"ftol": 1e-15, "gtol": 1e-10, "maxiter": 1000})
        th = unpack(out.x)
        th[4:4 + p] = np.maximum(th[4:4 + p], lower)
    s = np.einsum("q,aqr,r->a", th, gram, th)
    return ProfiledFit(th[0:4], th[4:4 + p], float(out.fun), s / n, n, c_free)


def _heldout_sse(fit: ProfiledFit, gram: Array) -> Array:
    th = np.concatenate([fit.pi, fit.c, [1.0]])
    return np.einsum("q,aqr,r->a", th, gram, th)


def _heldout_loglik(sse: Array, n_test: int, fit: ProfiledFit) -> float:
    return float(-0.5 * np.sum(sse / fit.row_var) - 0.5 * n_test * np.sum(np.log(fit.row_var))
                 + n_test * (3.0 * math.log(fit.pi[0]) + np.sum(np.log(fit.pi[1:4]))))


@dataclass(frozen=True)
class ModelFit:
    """A set of wrench effects fitted on a set of blocks: linear coefficients by effect,
    the lag time constant (or None), the fit, and the held-out SSE per row (6,);
    sampling (s,): the nuisance coefficients of ``residuals.sampling_columns``
    (empty when the fit went without them); free: the linear coefficients by effect of
    the fit without the effects' domains (the same as ``coefficients`` unless the fit
    was bounded and a coefficient met its bound)."""

    coefficients: dict[str, Array]
    lag: float | None
    fit: ProfiledFit
    heldout_sse: Array
    n_test: int
    heldout_sse_window: Array
    train_var_window: Array
    sampling: Array = field(default_factory=lambda: np.zeros(0))
    free: dict[str, Array] = field(default_factory=dict)


def fit_model(res: Residuals, effects: Sequence[str], train: NDArray[np.bool_], pi0: Array,
               window: int = 10, hold_inertia: bool = False,
               sampling: tuple[int, ...] = (), bounded: bool = False) -> ModelFit:
    """Fit pi and the wrench effects' coefficients on the blocks ``train`` (B,) bool
    (``hold_inertia``: mass and coefficients, the inertia held at ``pi0``'s; ``sampling``:
    the nuisance columns of ``residuals.sampling_columns`` with these indices fitted alongside,
    in every model the selection compares, so the actuation's change within a logged
    interval is never credited to an effect; ``bounded``: each coefficient kept inside
    its physical domain, ``library.lower_bounds``, by ``profiled_fit``; the motor lag's
    search starts at 0 and is inside it already)."""
    wrench_effects = [e for e in effects if e != "gyro_bias"]
    n_train = int(np.isin(res.block, np.flatnonzero(train)).sum())
    n_test = int(np.isin(res.block, np.flatnonzero(~train)).sum())
    phi, _ = effect_columns(res, wrench_effects, None)
    n_nuisance = len(sampling)
    if n_nuisance:
        phi = np.concatenate([res.sampling[:, :, list(sampling)], phi], axis=2)
    p = phi.shape[2]
    lower = None
    if bounded:
        lower = np.concatenate([np.full(n_nuisance, -np.inf)]
                               + [lower_bounds(e) for e in wrench_effects if e != "motor_lag"])

    def fit_at(lag: float | None) -> tuple[ProfiledFit, Array]:
        _, fixed = effect_columns(res, [], lag)
        g = block_grams(res, phi, fixed)
        return (profiled_fit(g[train].sum(axis=0), n_train, pi0, p, hold_inertia, lower),
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
    _, fixed = effect_columns(res, [], lag)
    gw = block_grams(res, phi, fixed, window)
    th = np.concatenate([fit.pi, fit.c, [1.0]])
    sse_w = np.einsum("q,baqr,r->ba", th, gw, th)
    coeffs: dict[str, Array] = {}
    free: dict[str, Array] = {}
    c_free = fit.c if fit.c_free is None else fit.c_free
    j = n_nuisance
    for e in wrench_effects:
        if e == "motor_lag":
            coeffs[e] = np.array([lag])
            free[e] = coeffs[e].copy()
            continue
        n_c = SPECS[e].n_coefficients
        coeffs[e] = fit.c[j:j + n_c].copy()
        free[e] = c_free[j:j + n_c].copy()
        j += n_c
    return ModelFit(coeffs, lag, fit, _heldout_sse(fit, g_test), n_test,
                     sse_w[~train].sum(axis=0), sse_w[train].sum(axis=0),
                     fit.c[:n_nuisance].copy(), free)


def gyro_fit(res: Residuals, train_steps: NDArray[np.bool_]) -> tuple[Array, Array, Array]:
    """Gyro bias (3,) = mean training residual; held-out SSE (3,) without and with it."""
    e = res.gyro_res
    ok = ~np.isnan(e)
    tr = ok & train_steps[:, None]
    te = ok & ~train_steps[:, None]
    bias = np.array([float(np.mean(e[tr[:, i], i])) if tr[:, i].any() else 0.0 for i in range(3)])
    sse0 = np.array([float(np.sum(e[te[:, i], i] ** 2)) for i in range(3)])
    sse1 = np.array([float(np.sum((e[te[:, i], i] - bias[i]) ** 2)) for i in range(3)])
    return bias, sse0, sse1


def folds(train: NDArray[np.bool_], cfg: DiscoveryConfig) -> tuple[NDArray[np.bool_], ...]:
    """The training blocks of each fold the selection scores on: ``train``, then (with
    ``cfg.two_fold``) its complement, so every block is held out once."""
    return (train, ~train) if cfg.two_fold else (train,)


def base_fits(res: Residuals, current: Sequence[str], pi0: Array, cfg: DiscoveryConfig,
              train: NDArray[np.bool_]) -> tuple[ModelFit, ...]:
    """The fits of the effects ``current`` alone, one per fold (``folds``), that
    ``score_candidate`` compares each candidate with (the same for every candidate of a
    round: fit them once)."""
    window = window_steps(cfg, res.data.dt)
    return tuple(fit_model(res, current, fold, pi0, window, sampling=cfg.sampling_nuisance)
                 for fold in folds(train, cfg))


@dataclass(frozen=True)
class FoldScore:
    """One fold's test of a candidate: heldout_with / heldout_without: the held-out
    windowed SSE on the candidate's rows with and without it, each row scaled by the
    training variance [-]; d_loglik: held-out Gaussian log-likelihood gain [nats];
    d_bic: training 2 dJ - p log n; coefficients (p,) fitted on the fold's training
    blocks."""

    heldout_with: float
    heldout_without: float
    d_loglik: float
    d_bic: float
    coefficients: Array


def _gyro_fold(res: Residuals, train: NDArray[np.bool_], cfg: DiscoveryConfig) -> FoldScore:
    train_steps = train[res.gyro_block]
    bias, sse0, sse1 = gyro_fit(res, train_steps)
    ok = ~np.isnan(res.gyro_res)
    tr = ok & train_steps[:, None]
    var0 = np.array([np.mean(res.gyro_res[tr[:, i], i] ** 2) for i in range(3)])
    var1 = np.array([np.var(res.gyro_res[tr[:, i], i]) for i in range(3)])
    n_tr = tr.sum(axis=0)
    n_te = (ok & ~train_steps[:, None]).sum(axis=0)
    window = window_steps(cfg, res.data.dt)
    steps = np.arange(res.gyro_res.shape[0])
    te_steps = ~train_steps
    w0 = np.array([window_rms(res.gyro_res[te_steps, i], res.gyro_block[te_steps],
                               steps[te_steps], window) for i in range(3)])
    w1 = np.array([window_rms(res.gyro_res[te_steps, i] - bias[i], res.gyro_block[te_steps],
                               steps[te_steps], window) for i in range(3)])
    d_bic = float(np.sum(n_tr * np.log(var0 / var1)) - 3 * math.log(max(n_tr.sum(), 2)))
    ll0 = -0.5 * np.sum(sse0 / var0 + n_te * np.log(var0))
    ll1 = -0.5 * np.sum(sse1 / var1 + n_te * np.log(var1))
    return FoldScore(float(np.sum(w1**2)), float(np.sum(w0**2)), float(ll1 - ll0), d_bic, bias)


def _wrench_fold(res: Residuals, current: Sequence[str], cand: str, pi0: Array,
                 cfg: DiscoveryConfig, train: NDArray[np.bool_], base: ModelFit | None
                 ) -> FoldScore:
    window = window_steps(cfg, res.data.dt)
    if base is None:
        base = fit_model(res, current, train, pi0, window, sampling=cfg.sampling_nuisance)
    ext = fit_model(res, [*current, cand], train, pi0, window, sampling=cfg.sampling_nuisance)
    rows = list(SPECS[cand].rows)
    w = 1.0 / base.train_var_window[rows]
    p = SPECS[cand].n_coefficients
    d_bic = 2.0 * (base.fit.objective - ext.fit.objective) - p * math.log(base.fit.n)
    d_ll = (_heldout_loglik(ext.heldout_sse, ext.n_test, ext.fit)
            - _heldout_loglik(base.heldout_sse, base.n_test, base.fit))
    return FoldScore(float(np.sum(ext.heldout_sse_window[rows] * w)),
                     float(np.sum(base.heldout_sse_window[rows] * w)), float(d_ll),
                     float(d_bic), np.asarray(ext.coefficients[cand], dtype=float))


def score_candidate(res: Residuals, current: Sequence[str], cand: str, pi0: Array, rnd: int,
                    cfg: DiscoveryConfig, train: NDArray[np.bool_],
                    base: tuple[ModelFit, ...] | None = None) -> CandidateScore:
    """Test adding ``cand`` to the effects ``current`` (module docstring of ``discover``),
    two-fold: fitted on ``train`` and tested on the rest, then the other way round
    (``folds``), the evidence summed over the folds, gain = 1 - sum_f SSE_f(with) /
    sum_f SSE_f(without), d_loglik = sum_f, d_bic = sum_f, coefficients the folds' mean.
    An effect whose signal sits in a few blocks (one low pass over the floor) is then
    judged on it whichever fold holds it. base: ``base_fits``'s fits when already
    computed (else fitted here)."""
    fold_trains = folds(train, cfg)
    bases = base if base is not None else (None,) * len(fold_trains)
    parts = [_gyro_fold(res, f, cfg) if cand == "gyro_bias"
             else _wrench_fold(res, current, cand, pi0, cfg, f, b)
             for f, b in zip(fold_trains, bases, strict=True)]
    without = sum(q.heldout_without for q in parts)
    gain = 1.0 - sum(q.heldout_with for q in parts) / without if without > 0 else math.nan
    d_ll = float(sum(q.d_loglik for q in parts))
    d_bic = float(sum(q.d_bic for q in parts))
    coefs = np.mean([q.coefficients for q in parts], axis=0)
    passed = bool(gain >= cfg.min_heldout_gain and d_bic > 0 and d_ll > 0)
    if cand == "motor_lag" and coefs[0] < shortest_lag(cfg, res.data.dt):
        passed = False  # shorter than a motor's or than the log resolves
    return CandidateScore(cand, rnd, float(gain), d_ll, d_bic,
                          tuple(float(v) for v in coefs), passed)


def shortest_lag(cfg: DiscoveryConfig, dt: float) -> float:
    """The shortest motor lag [s] the selection names on a log of interval dt [s]:
    max(min_lag_intervals dt, min_lag_seconds) (``DiscoveryConfig``)."""
    return max(cfg.min_lag_intervals * dt, cfg.min_lag_seconds)


def estimate_coefficients(obs: Observations, post: Posterior, theta: Theta, effects: Sequence[str],
                           cfg: DiscoveryConfig, train: NDArray[np.bool_],
                           hold_inertia: bool = False, sampling: tuple[int, ...] = (),
                           bounded: bool = False
                           ) -> tuple[dict[str, Array], Residuals, ModelFit]:
    """The coefficients of ``effects`` (name -> (p,)) fitted on the training blocks
    ``train`` (B,) at the posterior ``post``, with the residuals and the model fit they
    came from (``hold_inertia``: the inertia held at ``theta``'s; ``sampling``: the
    nuisance columns fitted alongside, as in ``fit_model``; the refit passes
    ``cfg.sampling_nuisance`` once its posterior has the effects in the model: at the
    base posterior, which bent the states to absorb the missing effect, a free nuisance
    took 20 % of a held-input drag flight's drag coefficient, at the refit's 2 %;
    ``bounded``: inside the effects' physical domains, as ``fit_model``)."""
    res = compute_residuals(obs, post, theta.gravity, cfg.block_seconds)
    coeffs, mf = coefficients_at(res, theta, effects, train, hold_inertia, sampling, bounded)
    return coeffs, res, mf


def coefficients_at(res: Residuals, theta: Theta, effects: Sequence[str],
                    train: NDArray[np.bool_], hold_inertia: bool = False,
                    sampling: tuple[int, ...] = (), bounded: bool = False
                    ) -> tuple[dict[str, Array], ModelFit]:
    """``estimate_coefficients`` on residuals already computed at the posterior (the
    coefficients by effect and the model fit): the block jackknife refits them on
    other training blocks of the same residuals."""
    train = train[: res.n_blocks]
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    mf = fit_model(res, effects, train, pi0, hold_inertia=hold_inertia, sampling=sampling,
                   bounded=bounded)
    coeffs = dict(mf.coefficients)
    if "gyro_bias" in effects:
        coeffs["gyro_bias"] = gyro_fit(res, train[res.gyro_block])[0]
    return coeffs, mf


def jackknife(obs: Observations, post: Posterior, theta: Theta, effects: Sequence[str],
               cfg: DiscoveryConfig, train: NDArray[np.bool_], hold_inertia: bool = False,
               sampling: tuple[int, ...] = ()) -> dict[str, Array]:
    """Block-jackknife standard errors of the coefficients (robust to the residuals'
    serial correlation within a block). The residuals at ``post`` do not depend on the
    blocks left out: they are computed once and each draw refits on its blocks. The
    draws are fits without the effects' domains: the spread of the free estimator, which
    a bound would collapse for a coefficient on its edge."""
    res = compute_residuals(obs, post, theta.gravity, cfg.block_seconds)
    blocks = np.flatnonzero(train)
    draws: dict[str, list[Array]] = {e: [] for e in effects}
    for b in blocks:
        t = train.copy()
        t[b] = False
        c, _ = coefficients_at(res, theta, effects, t, hold_inertia, sampling)
        for e in effects:
            draws[e].append(c[e])
    nb = blocks.size
    out = {}
    for e in effects:
        d = np.asarray(draws[e])
        out[e] = np.sqrt((nb - 1) / nb * np.sum((d - d.mean(axis=0)) ** 2, axis=0))
    return out
