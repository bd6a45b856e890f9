"""Compiled E-step for :class:`~pinquad.models.ssm.QuadSSM`: EKF + RTS smoother in two numba calls.

The same equations as the generic ``estimators.rts.smooth(QuadSSM(obs, theta), obs.ys)``,
in algebraically equal forms that need fewer operations, so the same result up to
rounding (the tests hold it to 1e-9 relative; the differences seen are ~1e-10, as
with the Joseph-form kernels these replaced), more than twenty times faster than the
generic path, because EM runs hundreds of E-steps on logs of thousands of steps and the
online estimator one per update.

This module is the Python side: which models take the compiled path, the arrays the
passes write into, and the public entry points ``smooth_quad``, ``loglik_quad`` and
``posterior_arrays``. The rest of the house:

    pinquad.models.kernel     a model's KernelDescription (kind + constant arrays), the
                              one argument the kernels take
    passes.py                 the EKF forward and RTS backward passes (the equations),
                              the per-step model pieces dispatched on the model kind
    quad_kernels.py           QuadSSM and the force-free warm-up KinematicSSM
    full_kernels.py           the ten-parameter FullQuadSSM's dynamic rows and Q
    effect_kernels.py         EffectSSM's lateral drag and wind forces
    linalg.py                 Cholesky factor and solve, copies
    agreement.py              the check that the kernels (run through the forward pass
                              itself) still compute what a model does

EM's force-free warm-up model (``KinematicSSM``) runs through the same passes with its
own transition kernel, and ``loglik_quad`` runs the forward pass alone (no stored
arrays) for the observed information's 33 likelihood evaluations.

No outlier gate (EM runs the generic path with ``gate_sigma=None`` too). Anything the
kernels do not cover (another model class, subclasses included, a gate, a model whose
behaviour has moved away from these kernels) goes to the generic smoother instead.
"""

from __future__ import annotations

import threading
import warnings
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from estimators.ekf import run_filter
from estimators.protocol import Posterior, StateSpaceModel
from estimators.rts import smooth as generic_smooth
from pinquad.core.conventions import wrap_angle
from pinquad.estep import passes
from pinquad.estep.agreement import agrees_cached
from pinquad.estep.passes import FilterArrays, PosteriorArrays, backward_into, forward_into
from pinquad.models.kernel import KINEMATIC, STATE_DIM, KernelDescription, kernel_description, kernel_kind

Array = NDArray[np.float64]

__all__ = ["Innovations", "Prepared", "filter_arrays", "innovations_quad", "loglik_quad",
           "posterior_arrays", "prepare", "smooth_quad"]


class Prepared(NamedTuple):
    """What the compiled passes take for one call: ys (N, m) C-contiguous float64, the
    model's KernelDescription, and its prior x0 (12,), P0 (12, 12)."""

    ys: Array
    desc: KernelDescription
    x0: Array
    p0: Array


def prepare(model: StateSpaceModel, ys: Array) -> Prepared | None:
    """The compiled passes' inputs if the kernels reproduce ``model``, else None (after
    a warning if the model's class is one the kernels cover but they no longer match).
    Raises ValueError if ys is not (N, meas_dim) with 0 < N <= obs.n."""
    if kernel_kind(model) is None:
        return None
    ys = np.ascontiguousarray(ys, dtype=float)
    obs = model.obs
    if ys.ndim != 2 or ys.shape[1] != model.meas_dim or not 0 < ys.shape[0] <= obs.n:
        raise ValueError(f"ys has shape {ys.shape}; expected (N, {model.meas_dim}) with "
                         f"0 < N <= {obs.n} for channels {obs.channels}")
    desc = kernel_description(model)
    if desc is not None and desc.kind == KINEMATIC and not desc.use_fixed:
        return None  # KinematicSSM without a fixed Q: the generic path raises its error
    if desc is None or not agrees_cached(model, desc):
        warnings.warn("QuadSSM no longer matches pinquad.estep's kernels; using the "
                      "generic smoother (update the fast path)", RuntimeWarning, stacklevel=3)
        return None
    x0, p0 = model.initial()
    return Prepared(ys, desc, np.ascontiguousarray(x0, dtype=float),
                    np.ascontiguousarray(p0, dtype=float))


# The forward pass's per-step arrays (filtered and predicted moments, F P), reused from
# call to call (per thread): fresh arrays of this size cost about as much in page faults
# (~1 ms per 800 steps) as the arithmetic that fills them (a 60 s, 500 Hz log: 162 ms
# per E-step with fresh arrays, 140 ms reused). They never leave this module, and are
# kept only up to _KEEP_STEPS steps (~210 MB, two minutes at 500 Hz; the posterior the
# E-step returns is two thirds of that again) so that a longer log's are not held after
# its E-step.
_workspace = threading.local()
_KEEP_STEPS = 60_000


def filter_arrays(n_steps: int) -> FilterArrays:
    """The forward pass's arrays for N = n_steps: this thread's reused ones (kept while
    N <= _KEEP_STEPS), else fresh ones."""
    arrays = getattr(_workspace, "arrays", None)
    if arrays is None or arrays[0].shape[0] != n_steps:
        arrays = passes.filter_arrays(n_steps)
        _workspace.arrays = arrays if n_steps <= _KEEP_STEPS else None
    return arrays


def posterior_arrays(n_steps: int) -> PosteriorArrays:
    """Arrays for ``smooth_quad(..., out=...)``: mean (N, 12), cov (N, 12, 12),
    cross-covariances (N - 1, 12, 12)."""
    return passes.posterior_arrays(n_steps)


def _check_out(out: tuple[Array, Array, Array], n_steps: int) -> PosteriorArrays:
    shapes = ((n_steps, STATE_DIM), (n_steps, STATE_DIM, STATE_DIM),
              (max(n_steps - 1, 0), STATE_DIM, STATE_DIM))
    if len(out) != 3 or any(
            not (isinstance(a, np.ndarray) and a.shape == s and a.dtype == np.float64
                 and a.flags.c_contiguous and a.flags.writeable)
            for a, s in zip(out, shapes, strict=True)):
        raise ValueError(f"out must be three writeable C-contiguous float64 arrays of shapes "
                         f"{shapes} (see posterior_arrays)")
    return PosteriorArrays(*out)


def loglik_quad(model: StateSpaceModel, ys: Array) -> float:
    """log p(y | theta) [nats] of the EKF on a QuadSSM (or KinematicSSM, FullQuadSSM,
    EffectSSM): the compiled forward pass alone, equal to
    ``estimators.ekf.run_filter(model, ys).loglik`` up to rounding (the same kernel as
    ``smooth_quad``'s forward pass), for the observed information's finite differences.
    Models the kernels do not cover, and filters whose innovation covariance stops being
    positive definite, go to the generic filter."""
    prep = prepare(model, ys)
    if prep is not None:
        # store=False: the pass writes nothing into its arrays (one-step placeholders)
        loglik, bad = forward_into(prep.desc, prep.x0, prep.p0, prep.ys, False,
                                   passes.filter_arrays(1))
        if bad < 0:
            return float(loglik)
    return float(run_filter(model, ys).loglik)


class Innovations(NamedTuple):
    """The EKF's one-step-ahead innovations: nu (N, m) = y_k - H m_k|k-1 (Euler rows
    wrapped; NaN where y_k is not observed) and their covariances s (N, m, m) =
    H P_k|k-1 H^T + R (the full matrix, whichever rows are observed)."""

    nu: Array
    s: Array


def innovations_quad(model: StateSpaceModel, ys: Array) -> Innovations | None:
    """The innovations of the compiled forward pass (the EKF of ``smooth_quad``, equal to
    the generic ``estimators.ekf`` filter's up to rounding), or None when the kernels do
    not cover the model or an innovation covariance stopped being positive definite
    (the caller then runs the generic filter)."""
    prep = prepare(model, ys)
    if prep is None:
        return None
    work = passes.filter_arrays(prep.ys.shape[0])
    _, bad = forward_into(prep.desc, prep.x0, prep.p0, prep.ys, True, work)
    if bad >= 0:
        return None
    rows = prep.desc.state_of_row
    nu = prep.ys - work.p_mean[:, rows]
    angles = np.asarray(prep.desc.is_angle, dtype=bool)
    nu[:, angles] = wrap_angle(nu[:, angles])
    s = work.p_cov[:, rows][:, :, rows] + np.diag(prep.desc.meas_var)
    return Innovations(nu, s)


def smooth_quad(model: StateSpaceModel, ys: Array, gate_sigma: float | None = None, *,
                out: tuple[Array, Array, Array] | None = None) -> Posterior:
    """EKF + RTS smoother of a :class:`~pinquad.models.ssm.QuadSSM`, compiled (module docstring).

    A drop-in for ``estimators.rts.smooth`` (e.g. as ``run_em``'s smoother): ys (N, m)
    with NaN where not observed; returns the Posterior with method "rts", the filter's
    log-likelihood and no rejected rows. Anything the kernels do not reproduce (a model
    that is not exactly a QuadSSM, its force-free warm-up KinematicSSM, the ten-parameter
    FullQuadSSM or discovery's EffectSSM, other subclasses included, since they may
    override the dynamics; an outlier gate; a model whose behaviour no longer matches the
    kernels) is smoothed by the generic ``estimators.rts.smooth``, so the answer is always
    the generic path's; the last case also warns, as the fast path needs updating. A
    covariance that stops being positive definite also hands over to the generic path,
    which then raises or copes as it always does.

    out: arrays (``posterior_arrays(N)``) the compiled path writes the smoothed means,
    covariances and cross-covariances into, and the returned Posterior then holds,
    instead of fresh ones (a caller smoothing window after window reuses them and saves
    the page faults of fresh memory); the generic fallback ignores them.
    """
    if gate_sigma is not None:
        return generic_smooth(model, ys, gate_sigma=gate_sigma)
    prep = prepare(model, ys)
    if prep is None:
        return generic_smooth(model, ys)
    ys = prep.ys
    n_steps = ys.shape[0]
    post = posterior_arrays(n_steps) if out is None else _check_out(out, n_steps)
    work = filter_arrays(n_steps)
    loglik, bad = forward_into(prep.desc, prep.x0, prep.p0, ys, True, work)
    if bad < 0:
        bad = backward_into(work, post)
    if bad >= 0:
        # A covariance lost positive definiteness: the generic path then raises its own
        # error (innovation S) or carries on with an LU solve (predicted P^-); either way
        # its behaviour, not a new one, is the contract.
        return generic_smooth(model, ys)
    return Posterior(post.mean, post.cov, post.cross, float(loglik), "rts",
                     np.zeros(ys.shape, dtype=bool))
