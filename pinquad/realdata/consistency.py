"""Flights of one vehicle against each other: does each flight's standard error cover the
scatter between the flights?

A flight's statistical standard error counts the noise the model knows. Flights of the
same vehicle under the same conditions (the same thrust map, the same rotor-speed
source) share mass and inertia. So when their estimates scatter further than those errors
allow, each flight carries an error the model does not know (yaw's torque model on the
Crazyflie: I_zz over the yaw flights spreads 71 % while each flight claims ~10 %). One
flight alone cannot show that; the table of ``python -m pinquad.realdata`` can.

Per parameter and group, over the flights whose verdict on it was "trusted" (or "model
not adequate" by the vehicle file's reference alone, ``identification.reference``: the
flight carried the parameter, the reference judges the number):

    mu   = sum_i w_i x_i / sum_i w_i,      w_i = 1 / s_i^2  (s_i: statistical standard error)
    chi2 = sum_i w_i (x_i - mu)^2          ~ chi2(L - 1) when the s_i are the real errors
    S    = max(1, sqrt(chi2 / (L - 1)))    (the Particle Data Group's scale factor)

and every flight of the group gets its statistical error scaled by S inside its total,

    se_total'^2 = se_total^2 + (S^2 - 1) s_i^2

(the common parts, kf and the yaw ratio, do not scatter between flights and stay as
they are), and its verdict judged again with it. A scaled error that covers too much of
the vehicle's possible range turns "trusted" into "not identifiable". A flight whose
statistical error is missing or degenerate is compared with its total instead
(``comparable_error``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq
from scipy.stats import chi2 as chi2_dist

from pinquad.identification.identify import Identification
from pinquad.identification.measured import MeasuredFit
from pinquad.identification.reference import only_the_reference
from pinquad.identification.verdict import (
    NOT_ADEQUATE,
    TRUSTED,
    Estimate,
    VerdictEvidence,
    judge,
    vehicle_range,
)
from pinquad.realdata.identify import measured_fit

Array = NDArray[np.float64]

PARAMETERS = ("mass", "I_xx", "I_yy", "I_zz")
UNITS = ((1e3, "g"), (1e6, "e-6 kg m^2"), (1e6, "e-6 kg m^2"), (1e6, "e-6 kg m^2"))


@dataclass(frozen=True)
class FlightRow:
    """One flight of the real-vehicle table: the log's name, its identification (run:
    ``realdata.identify_real``'s, with its ``MeasuredFit``; its stderr and verdict as the
    table judges them) and what the table adds. rotor_source: how J_r was obtained, in
    words; effects: the effects found on the flight with their evidence against the null
    (``pipeline.discover.measured_effects``; None: discovery not run);
    evidence: what the verdict was judged on besides the errors (so that
    :func:`between_flights` can judge again); vehicle: the vehicle whose range it was
    judged against; scatter_scale (4,): the between-flight scale factors S that multiply
    the statistical errors inside the run's stderr (None: not compared)."""

    name: str
    run: Identification
    rotor_source: str = ""
    effects: dict | None = None
    evidence: VerdictEvidence | None = None
    vehicle: str = "crazyflie21"
    scatter_scale: Array | None = None

    @property
    def fit(self) -> MeasuredFit:
        """The run's measured-flight block (kf, the error parts, J_r, the model-free mass)."""
        return measured_fit(self.run)

    @property
    def params(self) -> Array:
        """[m, I_xx, I_yy, I_zz] (4,) [kg, kg m^2]."""
        return np.r_[self.run.mass, np.diag(self.run.inertia)]


@dataclass(frozen=True)
class FlightScatter:
    """The scatter of one parameter over the flights of one group (module docstring).

    parameter: "mass", "I_xx", "I_yy" or "I_zz"; group: the flights' shared conditions,
    in words; logs (L,): their names; values (L,) [kg or kg m^2]; stderr (L,): their
    statistical standard errors (same unit); mean: the weighted mean; chi2 [-] on dof =
    L - 1 degrees of freedom; p_value: P(chi2(dof) >= chi2); scale: S >= 1.
    """

    parameter: str
    group: str
    logs: tuple[str, ...]
    values: Array
    stderr: Array
    mean: float
    chi2: float
    dof: int
    p_value: float
    scale: float
    model_error: float = 0.0

    def describe(self) -> str:
        factor, unit = UNITS[PARAMETERS.index(self.parameter)]
        each = ", ".join(f"{n} {factor * v:.4g} ± {factor * s:.2g}"
                         for n, v, s in zip(self.logs, self.values, self.stderr, strict=True))
        verdict = (f"statistical errors scaled by S = {self.scale:.2f}; model error between "
                   f"flights {100 * self.model_error:.1f} % of the value (``model_error``)"
                   if self.scale > 1.0 else "within their errors (S = 1)")
        return (f"{self.parameter}, {self.group} ({each} {unit}): weighted mean "
                f"{factor * self.mean:.4g} {unit}, chi2 {self.chi2:.1f} on {self.dof} dof "
                f"(p {self.p_value:.2g}): {verdict}")


def flight_scatter(parameter: str, group: str, logs: Sequence[str], values: Array,
                   stderr: Array) -> FlightScatter:
    """The ``FlightScatter`` of estimates ``values`` (L,) with statistical standard errors
    ``stderr`` (L,) > 0 (L >= 2), by the module docstring's equations."""
    x = np.asarray(values, dtype=float)
    s = np.asarray(stderr, dtype=float)
    if x.size < 2 or x.size != s.size or not np.all(s > 0):
        raise ValueError(f"{parameter}: need two or more estimates with positive standard "
                         f"errors; got {x.size} values, errors {s}")
    w = 1.0 / s**2
    mean = float(np.sum(w * x) / np.sum(w))
    chi2 = float(np.sum(w * (x - mean) ** 2))
    dof = x.size - 1
    return FlightScatter(parameter, group, tuple(logs), x, s, mean, chi2, dof,
                         float(chi2_dist.sf(chi2, dof)), max(1.0, math.sqrt(chi2 / dof)),
                         model_error(x, s))


def model_error(values: Array, stderr: Array) -> float:
    """The relative model error r [-] between flights: the spread each flight carries
    beyond its statistical error s_i, taken in proportion to the value, that makes the
    scatter what the errors say,

        sum_i (x_i - mu_r)^2 / (s_i^2 + r^2 mu_r^2) = L - 1,
        mu_r = sum_i x_i / (s_i^2 + r^2 mu_r^2) / sum_i 1 / (s_i^2 + r^2 mu_r^2)

    (0 when the flights scatter within their errors). A single flight's error budget
    carries it as its ``between_flights`` part (the vehicle file's ``[uncertainty]
    model_error``)."""
    x, s = np.asarray(values, dtype=float), np.asarray(stderr, dtype=float)
    dof = x.size - 1

    def excess(r: float) -> float:
        mu = float(np.mean(x))
        for _ in range(50):
            w = 1.0 / (s**2 + (r * mu) ** 2)
            mu = float(np.sum(w * x) / np.sum(w))
        return float(np.sum(w * (x - mu) ** 2)) - dof

    if excess(0.0) <= 0.0:
        return 0.0
    hi = 1.0
    while excess(hi) > 0.0 and hi < 1e3:
        hi *= 2.0
    return float(brentq(excess, 0.0, hi, xtol=1e-6))


def scaled_total(se_total: float, se_stat: float, scale: float) -> float:
    """sqrt(se_total^2 + (S^2 - 1) se_stat^2): the total standard error with its
    statistical part scaled by S (module docstring)."""
    return math.sqrt(se_total**2 + (scale**2 - 1.0) * se_stat**2)


def comparable_error(value: float, stat: float, total: float) -> float:
    """The error a flight is compared with: its statistical error, or its total where the
    statistical one is missing or degenerate, below 1e-6 of the value (a jackknife whose
    blocks all give the same estimate, pinned on the physical-consistency boundary
    I_zz = I_xx + I_yy, prints ~1e-20: as a weight it would swamp every other flight)."""
    if np.isfinite(stat) and stat > 1e-6 * abs(value):
        return float(stat)
    return float(total)


def _group(r: FlightRow) -> str:
    split = r.fit.motor_split
    rebuilt = split.rebuilt if split is not None else ()
    if rebuilt:
        return "rotor speeds of motor(s) " + ", ".join(f"M{i + 1}" for i in rebuilt) + \
            " rebuilt from PWM"
    return "measured rotor speeds"


@dataclass(frozen=True)
class FlightEstimate:
    """What the comparison needs of one flight: name; group (the flights it is compared
    with); values (4,), errors (4,) (``comparable_error``) and totals (4,) of [m, I_xx,
    I_yy, I_zz] [kg, kg m^2]; trusted (4,): the verdict on each."""

    name: str
    group: str
    values: Array
    errors: Array
    totals: Array
    trusted: NDArray[np.bool_]


def scaled_totals(flights: Sequence[FlightEstimate]
                  ) -> tuple[list[Array], list[Array], list[FlightScatter]]:
    """Per flight, the scale factors S (4,) and the totals (4,) with the statistical part
    scaled (``scaled_total``; NaN errors leave a total as it is), and the scatter of every
    (group, parameter) with two or more trusted estimates (module docstring)."""
    scatters: list[FlightScatter] = []
    scale = [np.ones(4) for _ in flights]
    for group in sorted({f.group for f in flights}):
        members = [i for i, f in enumerate(flights) if f.group == group]
        for j, name in enumerate(PARAMETERS):
            trusted = [i for i in members if flights[i].trusted[j]
                       and flights[i].errors[j] > 0]
            if len(trusted) < 2:
                continue
            sc = flight_scatter(name, group, [flights[i].name for i in trusted],
                                np.array([flights[i].values[j] for i in trusted]),
                                np.array([flights[i].errors[j] for i in trusted]))
            scatters.append(sc)
            for i in members:
                scale[i][j] = sc.scale
    totals = [np.array([scaled_total(float(f.totals[j]), float(f.errors[j]), float(s[j]))
                        if np.isfinite(f.errors[j]) and np.isfinite(f.totals[j])
                        else float(f.totals[j]) for j in range(4)])
              for f, s in zip(flights, scale, strict=True)]
    return scale, totals, scatters


def between_flights(results: Sequence[FlightRow]
                    ) -> tuple[list[FlightRow], list[FlightScatter]]:
    """The flights with their totals scaled and verdicts judged again where flights of the
    same group scatter beyond their errors (module docstring), and the scatter of every
    (parameter, group) with two or more trusted estimates. A flight without its verdict
    or its evidence (``FlightRow.evidence``) is left as it is."""
    judged = [r for r in results if r.run.verdict is not None and r.evidence is not None]
    flights = [FlightEstimate(
        r.name, _group(r), r.params, np.array([_error(r, j) for j in range(4)]),
        np.asarray(r.run.stderr, dtype=float),
        np.array([_carried(r.run.verdict.parameters[j]) for j in range(4)]))  # type: ignore[union-attr]
        for r in judged]
    scale, totals, scatters = scaled_totals(flights)
    new = {r.name: (s, t) for r, s, t in zip(judged, scale, totals, strict=True)
           if np.any(s != 1.0)}
    out = []
    for r in results:
        if r.name not in new:
            out.append(r)
            continue
        s, total = new[r.name]
        verdict = judge(r.run.mass, r.run.inertia, total, r.evidence, vehicle_range(r.vehicle))
        out.append(replace(r, run=replace(r.run, stderr=total, verdict=verdict),
                           scatter_scale=s.copy()))
    return out, scatters


def _carried(p: Estimate) -> bool:
    """A parameter the flight carried: trusted, or not adequate by the vehicle's reference
    alone (``identification.reference``: the reference judges the number; the scatter of
    such numbers between flights is what the model misses)."""
    return p.verdict == TRUSTED or (p.verdict == NOT_ADEQUATE and only_the_reference(p.reasons))


def _error(r: FlightRow, j: int) -> float:
    return comparable_error(float(r.params[j]), float(r.fit.se_stat[j]),
                            float(r.run.stderr[j]))
