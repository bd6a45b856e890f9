"""Standard errors of the effect coefficients: the block jackknife at the refit posterior
and the observed information of the EKF likelihood, the larger of the two reported.

The block jackknife (``selection.jackknife``) refits the coefficients on the residuals of
one posterior with one block left out at a time. It is robust to serial correlation
within a block, but it holds the smoothed states fixed, and those states were smoothed
with the model at the estimated coefficients: an E-step at other coefficients would move
them. The refit's map c -> c' (E-step at c, coefficients refitted on its posterior) has
slopes near 1 where the smoother absorbs a wrong coefficient into the states: 0.96 for a
gyro offset on a 100 Hz flightgen flight (the smoothed rates take 96 % of an offset
error), 0.3-0.37 for lateral drag at 500 Hz. The jackknife misses that missing
information and understated the error 3-25 fold on flightgen's Monte Carlo
(docs/trust.md).

The observed information of the likelihood itself does not: with the mass, inertia and
noise held at the refit's, and the state-dependent thrust and torque corrections at its
smoothed path (``refit.corrected_observations``),

    L(c) = log p(y | theta, c) = sum_k log N(nu_k(c); 0, S_k(c))

(the compiled EKF on the corrected observations, with ``EffectSSM``'s body x/y forces
for drag and wind), and Info = -d^2 L / dc dc^T by central differences
(``identification.fisher.central_differences``) with steps of about one standard error,
found by a few diagonal rounds from three jackknife standard errors. The reported
standard error of each coefficient is max(jackknife, sqrt(diag Info^-1)); the jackknife
alone where the information is not positive definite. The same central differences give
L's gradient, and the reported coefficients of an EM refit are those after one Newton
step to L's maximum inside the coefficients' physical domains (``information_fit``;
taken only where it raises L; ``projected_newton``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.library import lower_bounds
from pinquad.discovery.refit import corrected_observations, model_factory
from pinquad.estep.fast_smoother import loglik_quad
from pinquad.identification.fisher import central_differences, positive_definite_information, standard_errors
from pinquad.models.ssm import Observations, QuadSSM, Theta

Array = NDArray[np.float64]

STEP_ROUNDS = 4
"""Diagonal rounds of the step search at most (each 2 p likelihood evaluations)."""


def _split(x: Array, effects: Sequence[str], sizes: Sequence[int]) -> dict[str, Array]:
    out, i = {}, 0
    for e, s in zip(effects, sizes, strict=True):
        out[e] = np.array(x[i:i + s], dtype=float)
        i += s
    return out


@dataclass(frozen=True)
class InformationFit:
    """What the likelihood of the coefficients says at the refit.

    stderr: effect -> (p,) sqrt(diag Info^-1) (NaN where the information is not positive
    definite or the filter broke down at the estimate); maximiser: effect -> (p,) the
    coefficients after one Newton step on L(c), c + Info^-1 grad L, where that step was
    taken (the information positive definite and L higher there), else the coefficients
    given; gain [nats]: L(maximiser) - L(given) (0 when no step was taken)."""

    stderr: dict[str, Array]
    maximiser: dict[str, Array]
    gain: float = 0.0


def projected_newton(x0: Array, grad: Array, info: Array, lower: Array) -> Array:
    """The maximiser of the quadratic model L(x0) + g^T d - d^T Info d / 2 over the box
    x0 + d >= lower (x0 (p,) inside it; g (p,) the gradient; Info (p, p) positive
    definite; lower (p,), -inf: unbounded): the Newton step x0 + Info^-1 g when it stays
    inside, else the coordinates it would take below their bound held there and the
    step re-solved on the others, d_F = Info_FF^-1 (g_F - Info_FA d_A), until none
    crosses (at most p rounds: each holds one more coordinate). Coordinates already on
    their bound with the gradient pushing outwards are held from the start."""
    p = x0.size
    held = (x0 <= lower) & (grad <= 0)
    x1 = x0.copy()
    for _ in range(p + 1):
        d = np.zeros(p)
        d[held] = lower[held] - x0[held]
        free = ~held
        if free.any():
            rhs = grad[free] - info[np.ix_(free, held)] @ d[held]
            d[free] = np.linalg.solve(info[np.ix_(free, free)], rhs)
        x1 = x0 + d
        crossing = free & (x1 < lower)
        if not crossing.any():
            break
        held |= crossing
    return np.maximum(x1, lower)


def information_stderr(obs: Observations, theta: Theta, state: Array,
                       coefficients: dict[str, Array], effects: Sequence[str],
                       jackknife: dict[str, Array],
                       loglik: Callable[[QuadSSM, Array], float] = loglik_quad
                       ) -> dict[str, Array]:
    """Effect -> (p,) standard errors sqrt(diag Info^-1) of the coefficients of
    ``effects`` (``information_fit``'s stderr, without its Newton step)."""
    return information_fit(obs, theta, state, coefficients, effects, jackknife, loglik,
                           newton=False).stderr


def information_fit(obs: Observations, theta: Theta, state: Array,
                    coefficients: dict[str, Array], effects: Sequence[str],
                    jackknife: dict[str, Array],
                    loglik: Callable[[QuadSSM, Array], float] = loglik_quad,
                    newton: bool = True) -> InformationFit:
    """The observed information of L(c) = log p(y | theta, c) (module docstring) in the
    coefficients of ``effects`` (their units, ``library.SPECS``), its standard errors,
    and the Newton step to L's maximum.

    Why the step: the refit's coefficients come from residuals at a posterior smoothed
    WITH them, and where the smoother can absorb a coefficient's error into the states
    (a constant wind into a 0.2 mrad mean tilt, which the motion capture's attitude
    barely resists) that alternation stalls short of the maximum: on flightgen's 250 Hz
    wind flights 3-3.4 standard errors short, w_x 1.3-1.5 % low. L is close to quadratic
    in c there, so one step reaches it (a second moved it by < 0.01 standard errors).
    obs: the log's observations (uncorrected); theta: the refit's parameters, held;
    state (N, 12): the smoothed path at which the thrust and torque corrections are
    evaluated; jackknife: effect -> (p,) jackknife standard errors, whose triple starts
    the step search; newton: False skips the step (and its likelihood evaluation). The
    step stays inside the coefficients' physical domains (``projected_newton``)."""
    sizes = [np.size(coefficients[e]) for e in effects]
    x0 = np.concatenate([np.asarray(coefficients[e], dtype=float).ravel() for e in effects])

    def value(x: Array) -> float:
        c = dict(coefficients)
        c.update(_split(x, effects, sizes))
        corr = corrected_observations(obs, state, c)
        return loglik(model_factory(c)(corr, theta), corr.ys)

    unavailable = InformationFit({e: np.full(s, np.nan) for e, s in zip(effects, sizes,
                                                                        strict=True)},
                                 {e: np.asarray(coefficients[e], dtype=float) for e in effects})
    se0 = np.concatenate([np.asarray(jackknife[e], dtype=float).ravel() for e in effects])
    scale = np.maximum(np.abs(x0), 1e-9)
    steps = np.where(np.isfinite(se0) & (se0 > 0), 3.0 * se0, 1e-3 * scale)
    try:
        l0 = value(x0)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        # no likelihood at the estimate itself: no information, the jackknife stands;
        # discovery's answer does not fail for want of an error bar
        return unavailable
    for _ in range(STEP_ROUNDS):
        curvature = np.empty(x0.size)
        for i in range(x0.size):
            e = np.zeros(x0.size)
            e[i] = steps[i]
            try:
                curvature[i] = (value(x0 + e) - 2.0 * l0 + value(x0 - e)) / steps[i] ** 2
            except (np.linalg.LinAlgError, FloatingPointError, ValueError):
                curvature[i] = np.nan
        # a step whose curvature is lost in rounding (not negative) is too small
        target = np.where(curvature < 0, 1.0 / np.sqrt(np.abs(curvature)), 4.0 * steps)
        settled = np.all(np.abs(np.log(target / steps)) < np.log(3.0))
        steps = target
        if settled:
            break
    _, grad, hess = central_differences(value, x0, steps)
    info = -0.5 * (hess + hess.T)
    if not positive_definite_information(info):
        return unavailable
    stderr = _split(standard_errors(info), effects, sizes)
    maximiser, gain = unavailable.maximiser, 0.0
    if newton and np.all(np.isfinite(grad)):
        lower = np.concatenate([lower_bounds(e) for e in effects])
        x1 = projected_newton(x0, grad, info, lower)
        try:
            gain = value(x1) - l0
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            gain = math.nan
        if gain > 0:
            maximiser = _split(x1, effects, sizes)
        else:
            gain = 0.0
    return InformationFit(stderr, maximiser, float(gain))


def reported_stderr(jackknife: dict[str, Array], information: dict[str, Array]
                    ) -> dict[str, Array]:
    """Effect -> max(jackknife, information) per coefficient; the jackknife where the
    information gave none (NaN)."""
    out = {}
    for e, jack in jackknife.items():
        info = np.asarray(information.get(e, np.full(np.shape(jack), np.nan)), dtype=float)
        jack = np.asarray(jack, dtype=float)
        out[e] = np.where(np.isfinite(info), np.fmax(jack, info), jack)
    return out
