"""The E-step benchmark's contestants (used by ``python -m pinquad.bench``), run on
the cases of :mod:`pinquad.experiments.bench_cases`.

Missing measurement rows (NaN): our smoothers, and GTSAM, skip them. filterpy,
pykalman and dynamax only skip whole time steps (filterpy: z = None; pykalman: a masked
step; dynamax: nothing), so they get each step's missing rows as a zero row of H_k with
y = 0: a measurement that carries no information about x (its innovation covariance is
block-diagonal, so its gain is exactly zero), which leaves every mean and covariance as
it is. Each contestant is a :class:`Contestant` that turns a case into a zero-argument
callable returning the smoothed means (N, 12); building the library's inputs from the
case is not timed, the call is.

The peers' libraries (filterpy, pykalman, jax + dynamax, gtsam) are optional and heavy:
each is imported inside its ``prepare``, so that a worker process loads only the one it
times and an absent one is reported, not a crash.
"""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.rts import smooth as generic_smooth
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.experiments.bench_cases import TOLERANCE, EStepCase, mean_error

Array = NDArray[np.float64]


def zero_row_measurements(ys: Array, h: Array) -> tuple[Array, Array, list[Array]]:
    """NaN rows as uninformative zero rows: y (N, m) with NaN -> 0, per-step H_k (N, m, n)
    with the missing rows zeroed, and the list of H_k as shared per-pattern arrays."""
    missing = np.isnan(ys)
    y0 = np.where(missing, 0.0, ys)
    patterns: dict[bytes, Array] = {}
    h_list = []
    for k in range(ys.shape[0]):
        key = missing[k].tobytes()
        if key not in patterns:
            hk = h.copy()
            hk[missing[k]] = 0.0
            patterns[key] = hk
        h_list.append(patterns[key])
    return y0, np.stack(h_list), h_list


Runner = Callable[[], Array]


@dataclass(frozen=True)
class Contestant:
    """A smoother in the comparison: name, a label for the table, the Python modules it
    needs, and ``prepare(case) -> (run, info)`` where ``run()`` returns the smoothed
    means (N, 12) and info holds extra figures (e.g. a compile time [s]); ``note``
    explains how it gets the model."""

    name: str
    label: str
    modules: tuple[str, ...]
    prepare: Callable[[EStepCase], tuple[Runner, dict]]
    note: str = ""

    def missing(self) -> list[str]:
        """Required modules that are not installed."""
        return [m for m in self.modules if importlib.util.find_spec(m) is None]


def _prepare_ours(case: EStepCase) -> tuple[Runner, dict]:
    model, ys = case.model, case.ys
    return (lambda: smooth_quad(model, ys).mean), {}


def _prepare_generic(case: EStepCase) -> tuple[Runner, dict]:
    return (lambda: generic_smooth(case.lin, case.ys_lin).mean), {}


def _prepare_generic_quad(case: EStepCase) -> tuple[Runner, dict]:
    model, ys = case.model, case.ys
    return (lambda: generic_smooth(model, ys).mean), {}


def _prepare_gtsam(case: EStepCase) -> tuple[Runner, dict]:
    from estimators.factor_graph import smooth  # needs gtsam (optional, heavy)

    return (lambda: smooth(case.lin, case.ys_lin).mean), {}


def _block_inverse(n: int) -> Callable[[Array], Array]:
    """The pseudo-inverse of a matrix whose last row and column are exact zeros (the
    homogeneous coordinate's): the inverse of the leading n x n block, zero elsewhere."""

    def inv(p: Array) -> Array:
        out = np.zeros_like(p)
        out[:n, :n] = np.linalg.inv(p[:n, :n])
        return out

    return inv


def _prepare_filterpy(case: EStepCase) -> tuple[Runner, dict]:
    """filterpy's KalmanFilter.batch_filter + rts_smoother.

    filterpy's RTS smoother has no control term (it predicts F x, not F x + B u), so the
    offsets c_k ride in homogeneous coordinates: the state [x; 1] (13) with
    F'_k = [[F_k, c_k], [0, 1]], Q'_k = blockdiag(Q_k, 0), H' = [H_k, 0], prior
    blockdiag(P0, 0). The predicted covariance is then singular in its last row and
    column, so the smoother is given filterpy's ``inv`` hook as the pseudo-inverse of
    that structure (the inverse of the 12 x 12 block; :func:`_block_inverse`), which
    costs what its default ``numpy.linalg.inv`` costs. filterpy predicts before it
    updates, so step 0 predicts with F = I, Q = 0 (giving the prior exactly) and step k
    with F'_{k-1}, Q'_{k-1}, as its smoother expects.
    """
    from filterpy.kalman import KalmanFilter

    lin = case.lin
    n, m = lin.state_dim, lin.meas_dim
    n_steps = case.n_steps
    y0, _, h_list = zero_row_measurements(case.ys_lin, lin.h)
    zs = list(y0)
    f_aug = np.zeros((n_steps, n + 1, n + 1))
    f_aug[0] = np.eye(n + 1)
    f_aug[1:, :n, :n] = lin.f
    f_aug[1:, :n, n] = lin.c
    f_aug[1:, n, n] = 1.0
    q_aug = np.zeros((n_steps, n + 1, n + 1))
    q_aug[1:, :n, :n] = lin.q
    fs, qs = list(f_aug), list(q_aug)
    h_aug = {id(h): np.hstack([h, np.zeros((m, 1))]) for h in h_list}
    hs = [h_aug[id(h)] for h in h_list]
    rs = [lin.r] * n_steps
    p0 = np.zeros((n + 1, n + 1))
    p0[:n, :n] = lin.p0
    x0 = np.append(lin.m0, 1.0)
    kf = KalmanFilter(dim_x=n + 1, dim_z=m)
    inv = _block_inverse(n)

    def run() -> Array:
        kf.x = x0.copy()
        kf.P = p0.copy()
        mu, cov, _, _ = kf.batch_filter(zs, Fs=fs, Qs=qs, Hs=hs, Rs=rs)
        xs, _, _, _ = kf.rts_smoother(mu, cov, Fs=fs, Qs=qs, inv=inv)
        return xs[:, :n]

    return run, {}


def _prepare_pykalman(case: EStepCase) -> tuple[Runner, dict]:
    """pykalman's KalmanFilter.smooth with time-varying F_k, c_k, Q_k and H_k."""
    from pykalman import KalmanFilter

    lin = case.lin
    y0, h_steps, _ = zero_row_measurements(case.ys_lin, lin.h)
    kf = KalmanFilter(transition_matrices=lin.f, observation_matrices=h_steps,
                      transition_covariance=lin.q, observation_covariance=lin.r,
                      transition_offsets=lin.c, observation_offsets=np.zeros(lin.meas_dim),
                      initial_state_mean=lin.m0, initial_state_covariance=lin.p0,
                      n_dim_state=lin.state_dim, n_dim_obs=lin.meas_dim)
    return (lambda: np.asarray(kf.smooth(y0)[0])), {}


DYNAMAX_BOOST = 1e-9
"""dynamax's ``psd_solve`` adds ``diagonal_boost`` (1e-9 by default) times I to every
matrix it solves with: the innovation covariance S (equivalent to R + 1e-9 I, 4e-5 of
our position variance) and the predicted covariance in the smoother. That regulariser
moves the smoothed means by ~1e-3 of the state scale, so the timed dynamax runs with the
boost set to 0 (the check then passes); the shipped default is checked and reported as
``dynamax_shipped``. The boost is one addition per solve: it does not change the time."""


def _prepare_dynamax(case: EStepCase, boost: float = 0.0) -> tuple[Runner, dict]:
    """dynamax's lgssm_smoother, jit-compiled ahead of time for this N (compile time in
    the info), in float64, with ``psd_solve``'s diagonal boost set to ``boost`` while it
    is traced (:data:`DYNAMAX_BOOST`). Time-varying parameters: entry t of F, b, Q is
    the step t-1 -> t (entry 0 is unused); H_t carries the zero rows. The compiled
    function returns the smoothed means, covariances and cross-moments (all of them, so
    that XLA cannot drop work ours does)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    from dynamax.linear_gaussian_ssm import inference
    from dynamax.linear_gaussian_ssm.inference import (
        ParamsLGSSM,
        ParamsLGSSMDynamics,
        ParamsLGSSMEmissions,
        ParamsLGSSMInitial,
        lgssm_smoother,
    )

    lin = case.lin
    n = lin.state_dim
    y0, h_steps, _ = zero_row_measurements(case.ys_lin, lin.h)
    f = np.concatenate([np.eye(n)[None], lin.f])
    b = np.concatenate([np.zeros((1, n)), lin.c])
    q = np.concatenate([np.eye(n)[None], lin.q])
    params = ParamsLGSSM(
        initial=ParamsLGSSMInitial(mean=jnp.asarray(lin.m0), cov=jnp.asarray(lin.p0)),
        dynamics=ParamsLGSSMDynamics(weights=jnp.asarray(f), bias=jnp.asarray(b),
                                     input_weights=None, cov=jnp.asarray(q)),
        emissions=ParamsLGSSMEmissions(weights=jnp.asarray(h_steps), bias=None,
                                       input_weights=None, cov=jnp.asarray(lin.r)))
    emissions = jnp.asarray(y0)

    def smoother(p: ParamsLGSSM, y: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        post = lgssm_smoother(p, y)
        return post.smoothed_means, post.smoothed_covariances, post.smoothed_cross_covariances

    shipped = inference.psd_solve

    def psd_solve(a: jax.Array, rhs: jax.Array) -> jax.Array:
        return shipped(a, rhs, diagonal_boost=boost)

    t0 = time.perf_counter()
    inference.psd_solve = psd_solve
    try:
        compiled = jax.jit(smoother).lower(params, emissions).compile()
    finally:
        inference.psd_solve = shipped
    compile_s = time.perf_counter() - t0

    def run() -> Array:
        out = compiled(params, emissions)
        jax.block_until_ready(out)
        return np.asarray(out[0])

    return run, {"compile_s": compile_s}


def _prepare_dynamax_shipped(case: EStepCase) -> tuple[Runner, dict]:
    return _prepare_dynamax(case, boost=DYNAMAX_BOOST)


CONTESTANTS: dict[str, Contestant] = {c.name: c for c in (
    Contestant("ours", "ours (compiled EKF+RTS)", ("numba",), _prepare_ours,
               "pinquad.estep.fast_smoother.smooth_quad on the nonlinear QuadSSM (it also "
               "evaluates f, its Jacobian and Q_k at every step)"),
    Contestant("generic", "ours, generic RTS on LTV", (), _prepare_generic,
               "estimators.rts.smooth (Python loop) on the linearised model"),
    Contestant("filterpy", "filterpy KF+RTS", ("filterpy",), _prepare_filterpy,
               "KalmanFilter.batch_filter + rts_smoother, offsets in homogeneous "
               "coordinates (13 states), missing rows as zero rows of H_k"),
    Contestant("pykalman", "pykalman smooth", ("pykalman",), _prepare_pykalman,
               "KalmanFilter.smooth, time-varying F_k, c_k, Q_k, H_k (zero rows)"),
    Contestant("dynamax", "dynamax (jit)", ("jax", "dynamax"), _prepare_dynamax,
               "lgssm_smoother under jax.jit (float64, psd_solve boost 0), time-varying "
               "F, b, Q, H (zero rows); compile time reported separately"),
    Contestant("gtsam", "ours, GTSAM batch", ("gtsam",), _prepare_gtsam,
               "estimators.factor_graph.smooth on the linearised model (Gauss-Newton; "
               "exact in one step on a linear model)"),
)}
"""Every contestant by name; "ours" is the reference the others are checked against."""

EXTRA_CONTESTANTS: dict[str, Contestant] = {
    "generic_quad": Contestant("generic_quad", "ours, generic RTS on QuadSSM", (),
                               _prepare_generic_quad,
                               "estimators.rts.smooth on the nonlinear QuadSSM"),
    "dynamax_shipped": Contestant("dynamax_shipped", "dynamax, default psd_solve boost",
                                  ("jax", "dynamax"), _prepare_dynamax_shipped,
                                  "as dynamax, with psd_solve's default diagonal boost "
                                  "1e-9 I (expected to differ)"),
}
"""Contestants available by name but not run by default."""


def contestant(name: str) -> Contestant:
    """A contestant by name (:data:`CONTESTANTS` or :data:`EXTRA_CONTESTANTS`)."""
    if name in CONTESTANTS:
        return CONTESTANTS[name]
    return EXTRA_CONTESTANTS[name]


@dataclass(frozen=True)
class CheckResult:
    """A contestant's agreement with ours on one case: ``error`` (:func:`mean_error`),
    None if it was not run, with ``status`` "ok", "mismatch", "absent" or "error" and a
    ``message``."""

    name: str
    status: str
    error: float | None
    message: str = ""


def check_all(case: EStepCase, names: list[str] | None = None) -> list[CheckResult]:
    """Run ours and each named contestant once on ``case`` and compare the smoothed
    means (to :data:`TOLERANCE`); absent libraries are reported, not failed."""
    run_ours, _ = _prepare_ours(case)
    ref = run_ours()
    out = []
    for name in names or [n for n in CONTESTANTS if n != "ours"]:
        peer = contestant(name)
        missing = peer.missing()
        if missing:
            out.append(CheckResult(name, "absent", None, "not installed: " + ", ".join(missing)))
            continue
        try:
            run, _ = peer.prepare(case)
            err = mean_error(run(), ref)
        except Exception as exc:  # a peer's failure is a finding, not a crash
            out.append(CheckResult(name, "error", None, f"{type(exc).__name__}: {exc}"))
            continue
        ok = math.isfinite(err) and err <= TOLERANCE
        out.append(CheckResult(name, "ok" if ok else "mismatch", err,
                               "" if ok else f"smoothed means differ by {err:.2e} > "
                               f"{TOLERANCE:.0e} of the state scale"))
    return out
