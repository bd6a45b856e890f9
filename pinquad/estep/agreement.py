"""The guard between the compiled kernels and the Python models: whether the kernels
still compute what a model computes (``pinquad.models`` may grow new terms), checked at
a probe state and cached per code identity.

Checked, at the first and the last transition (and the first reset and the first
restart one, if any), to
1e-12 of each array's largest entry (Q's off-diagonal entries are cancellation noise of
order 1e-16 of its diagonal, in either evaluation order): the transition x + dt f, its
Jacobian F and Q, as the forward pass itself computes them (``kernel_step``); and
exactly: H (a row selector onto ``state_of_row``), R = diag(meas_var), and the wrapped
residual of Euler rows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.kernels import wrap
from pinquad.estep.passes import filter_arrays, forward_into
from pinquad.models import ssm
from pinquad.models.kernel import KINEMATIC, STATE_DIM, KernelDescription
from pinquad.models.ssm import QuadSSM

Array = NDArray[np.float64]

_PROBE = np.array([0.3, -0.2, 0.5, 0.4, -0.5, 0.6, 0.2, -0.3, 0.4, 0.5, -0.6, 0.7])

# The methods (and the module functions they call) that define what a QuadSSM computes;
# the agreement check is a guard against this code drifting from the kernels, so its
# verdict holds for as long as none of these objects is replaced.
MODEL_METHODS = ("initial", "transition", "euler_step", "body_acceleration", "process_cov",
                 "measure", "meas_cov", "residual")
_checked: dict[tuple, bool] = {}


def _close(ours: Array, ref: Array) -> bool:
    """Equal to rounding, on the scale of the whole array."""
    return bool(np.all(np.abs(ours - ref) <= 1e-12 * max(float(np.max(np.abs(ref))), 1e-300)))


def kernel_step(desc: KernelDescription, x: Array, k: int) -> tuple[Array, Array, Array]:
    """(x + dt f (12,), F (12, 12), Q_k (12, 12)) of transition k -> k+1 at state x, from
    the forward pass itself (two steps, nothing observed): from P_0 = 0 the predicted
    covariance is Q_k (symmetrised), from P_0 = I the stored product F P_0 is F (through
    the block-pattern product, so an entry outside the pattern shows as a mismatch)."""
    step = desc._replace(inputs=desc.inputs[k:k + 2], resets=desc.resets[k:k + 2],
                         restarts=desc.restarts[k:k + 2])
    ys = np.full((2, desc.meas_var.shape[0]), np.nan)
    x = np.ascontiguousarray(x, dtype=float)
    work = filter_arrays(2)
    forward_into(step, x, np.zeros((STATE_DIM, STATE_DIM)), ys, True, work)
    x_next, q = work.p_mean[1].copy(), work.p_cov[1].copy()
    forward_into(step, x, np.eye(STATE_DIM), ys, True, work)
    return x_next, work.fps[0].copy(), q


def agrees_with_model(model: QuadSSM, desc: KernelDescription) -> bool:
    """Whether the kernels, given ``desc``, compute what ``model`` computes (module
    docstring)."""
    n_steps = model.obs.n
    x = np.asarray(model.obs.x0, dtype=float) + _PROBE
    resets = desc.resets
    probes = {0, max(n_steps - 2, 0)}
    for marked in (resets & ~desc.restarts, desc.restarts):
        if marked[:max(n_steps - 1, 0)].any():
            probes.add(int(np.flatnonzero(marked[:n_steps - 1])[0]))
    for k in probes:
        ref_x, ref_jac = model.transition(x, k)
        x_next, jac, q = kernel_step(desc, x, k)
        ref_q = model.process_cov(x, k)
        y_pred, h = model.measure(x, k)
        if not (_close(x_next, ref_x) and _close(jac, ref_jac) and _close(q, ref_q)
                and np.array_equal(y_pred, x[desc.state_of_row])
                and np.array_equal(h[np.arange(h.shape[0]), desc.state_of_row],
                                   np.ones(h.shape[0]))
                and np.count_nonzero(h) == h.shape[0]
                and np.array_equal(model.meas_cov(k), np.diag(desc.meas_var))):
            return False
    y = y_pred + np.linspace(-7.0, 7.0, y_pred.shape[0])
    res = y - y_pred
    ours = np.array([wrap(r) if a else r for r, a in zip(res, desc.is_angle, strict=True)])
    return bool(np.array_equal(model.residual(y, y_pred), ours))


def code_key(model: QuadSSM, desc: KernelDescription) -> tuple | None:
    """Identity of the code behind ``model`` and of the kernel variant it needs (channels,
    fixed or structured Q, continuous or Euler positions, kinematic or dynamic, resets,
    restarts, drag, wind); None when an
    instance overrides a method (then every call is checked)."""
    if any(name in vars(model) for name in MODEL_METHODS):
        return None
    cls = type(model)
    return (cls, cls.__init__, *(getattr(cls, name) for name in MODEL_METHODS),
            ssm.state_derivative_and_jacobian, ssm.wrap_angle, ssm.continuous_step,
            ssm.kinematic_noise, model.obs.channels, desc.use_fixed,
            desc.continuous, desc.kind == KINEMATIC, bool(desc.resets.any()),
            bool(desc.restarts.any()), bool(desc.drag.any()), bool(desc.wind.any()))


def agrees_cached(model: QuadSSM, desc: KernelDescription) -> bool:
    """``agrees_with_model``, run once per code identity (``code_key``) and process: it
    costs ~2 ms of Python per call, a fifth of an online update."""
    key = code_key(model, desc)
    if key is None:
        return agrees_with_model(model, desc)
    if key not in _checked:
        _checked[key] = agrees_with_model(model, desc)
    return _checked[key]
