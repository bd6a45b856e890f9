"""Detection (and optional repair) of implausible actuation in measured Crazyflie logs.

A rotor reading cannot be the true rotor speed when the vehicle keeps flying without
it: a multirotor that hovers needs all its rotors near hover speed, and on a quadcopter
the diagonal partners (M1, M3) and (M2, M4) carry nearly equal thrust because roll and
pitch torques stay small (tau_x, tau_y ~ 0 gives T1 ~ T3 and T2 ~ T4; the yaw command
only moves the two pairs against each other). The partners come from the vehicle's
geometry (:func:`diagonal_partners`: the rotor at the mirrored position that spins the
same way); on a vehicle with more rotors the torque balance does not pair them, so a
rotor without such a partner is not compared with one. Per row k and rotor i of n
(rpm in rev/min):

* airborne[k]:        median_j rpm_j >= flight_rpm (rotors at flight speed);
* dropout[k, i]:      airborne, rpm_i < dropout_rpm and the median of the other n - 1
                      >= flight_rpm (one rotor "stopped" while the vehicle flies);
* implausible[k, i]:  dropout, or airborne with rpm_i < partner_ratio * rpm_partner(i)
                      (far below its diagonal partner, if it has one; only the lower
                      reading is blamed), or rpm_i > max_rpm (beyond the motor's reach).

Real case (IMRC Lab jana20-jana29): motor 1 reads 0 in 21-88 % of the rows and about
half its partner's speed in most of the rest, and the battery voltage is stuck at
3700 mV. A motor whose readings are implausible in more than ``unreliable_fraction`` of
the airborne rows is declared unreliable as a whole: its remaining readings are not
trusted either. :func:`reconstruct_rpm` replaces untrusted readings from the motor
commands (PWM) through a per-log map learned on the trusted motors, except where the
channel reads a whole fraction of that rebuilt speed: jana20-29's M1 reads 1/2 of it
(median reading / rebuild 0.494-0.504), a sensor counting every other pulse, and those
readings are doubled and kept (:func:`pulse_divided_readings`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from pinquad.io.logs import FlightLog
from pinquad.io.timebase import uniform_step
from pinquad.vehicle.actuators import CRAZYFLIE_SPEC

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

QUAD_PARTNERS: tuple[int | None, ...] = (2, 3, 0, 1)
"""Each rotor's diagonal partner on a quadcopter in X or + layout (M1-M3, M2-M4, 0-based;
what :func:`diagonal_partners` gives for both layouts)."""


def diagonal_partners(positions: Array, spin: Sequence[float], rel_tol: float = 1e-6
                      ) -> tuple[int | None, ...]:
    """Per rotor, the index (0-based) of the rotor at its mirrored position -(x, y) that
    spins the same way, or None: positions (n, 2) [m], spin (n,) +-1. The torque
    balance makes such a pair carry nearly equal thrust (module docstring); a hexacopter's
    opposite rotors spin against each other and have none."""
    xy = np.asarray(positions, dtype=float)
    tol = rel_tol * float(np.max(np.hypot(xy[:, 0], xy[:, 1])))
    out: list[int | None] = []
    for i in range(xy.shape[0]):
        match = [j for j in range(xy.shape[0]) if j != i and spin[j] == spin[i]
                 and float(np.hypot(*(xy[j] + xy[i]))) <= tol]
        out.append(match[0] if len(match) == 1 else None)
    return tuple(out)


@dataclass(frozen=True)
class ActuationFaultReport:
    """Which rows of a log carry implausible rotor readings, and why.

    source: the log; airborne (N,) bool: rotors at flight speed (the definition in the
    module docstring); motor_mask (N, n) bool: implausible reading of rotor i in row k
    (n rotors: the log's rotor-speed columns); dropout_mask (N, n) bool: the subset
    reading ~0 rev/min; mask (N,) bool: any rotor implausible in that row; unreliable
    (n,) bool: motors whose channel as a whole
    should not be trusted; vbat_stuck: the battery voltage is constant over the whole
    log (a real battery sags under load and the ADC is noisy); vbat_value [V] the stuck
    value (NaN otherwise); notes: what was flagged and why, in words.
    """

    source: str
    airborne: BoolArray
    motor_mask: BoolArray
    dropout_mask: BoolArray
    mask: BoolArray
    unreliable: BoolArray
    vbat_stuck: bool
    vbat_value: float
    notes: tuple[str, ...]

    @property
    def counts(self) -> NDArray[np.int64]:
        """(n,) rows with an implausible reading, per motor."""
        return self.motor_mask.sum(axis=0).astype(np.int64)

    @property
    def dropout_counts(self) -> NDArray[np.int64]:
        """(n,) rows reading ~0 while flying, per motor."""
        return self.dropout_mask.sum(axis=0).astype(np.int64)

    @property
    def n_flagged(self) -> int:
        return int(self.mask.sum())

    @property
    def fraction(self) -> float:
        """Flagged rows / airborne rows (0 when never airborne)."""
        n_air = int(self.airborne.sum())
        return self.n_flagged / n_air if n_air else 0.0

    @property
    def trusted(self) -> BoolArray:
        """(N, n) readings that may be used: neither flagged nor from an unreliable motor."""
        return ~(self.motor_mask | self.unreliable[None, :])

    @property
    def clean(self) -> bool:
        return self.n_flagged == 0 and not self.vbat_stuck


def _row_median(x: Array) -> Array:
    """Median of each row over its finite entries; NaN (no warning) for an empty row."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(x, axis=1)


def detect_actuation_faults(log: FlightLog, flight_rpm: float | None = None,
                            dropout_rpm: float = 1000.0, partner_ratio: float = 0.7,
                            max_rpm: float | None = None, unreliable_fraction: float = 0.05,
                            partners: Sequence[int | None] | None = None
                            ) -> ActuationFaultReport:
    """Flag implausible rotor readings and a stuck battery voltage (see module docstring).

    Thresholds: flight_rpm [rev/min] and max_rpm [rev/min] (None: the shipped
    crazyflie21 file's ``[faults]``, which says why); dropout_rpm [rev/min];
    partner_ratio [1] (clean flights, including the yaw sweeps, stay above 0.85);
    unreliable_fraction [1] of airborne rows above which a motor's whole channel is
    distrusted. partners: each rotor's diagonal partner (:func:`diagonal_partners` of the
    vehicle's geometry; None: ``QUAD_PARTNERS`` for a log with four rotor speeds, no
    partner check otherwise). Raises ValueError if ``partners`` does not have one entry
    per rotor-speed column.
    """
    defaults = CRAZYFLIE_SPEC.faults
    flight_rpm = float(defaults.flight_rpm if flight_rpm is None else flight_rpm)  # type: ignore[arg-type]
    max_rpm = float(defaults.max_rpm if max_rpm is None else max_rpm)  # type: ignore[arg-type]
    n = log.n
    source = log.meta.source
    notes: list[str] = []
    if log.rpm is None:
        empty = np.zeros((n, 0), dtype=bool)
        return ActuationFaultReport(
            source=source, airborne=np.zeros(n, dtype=bool), motor_mask=empty,
            dropout_mask=empty, mask=np.zeros(n, dtype=bool),
            unreliable=np.zeros(0, dtype=bool), vbat_stuck=False, vbat_value=float("nan"),
            notes=("no rotor speeds in the log: nothing to check",))
    rpm = np.asarray(log.rpm, dtype=float)
    n_rotors = rpm.shape[1]
    if partners is None:
        partners = QUAD_PARTNERS if n_rotors == 4 else (None,) * n_rotors
    if len(partners) != n_rotors:
        raise ValueError(f"{source}: {n_rotors} rotor speeds per row but {len(partners)} "
                         "diagonal partners given (one per rotor)")
    finite = np.isfinite(rpm)
    rpm0 = np.where(finite, rpm, 0.0)
    airborne = _row_median(rpm) >= flight_rpm
    airborne &= finite.sum(axis=1) >= n_rotors - 1
    n_air = int(airborne.sum())

    dropout = np.zeros((n, n_rotors), dtype=bool)
    low_vs_partner = np.zeros((n, n_rotors), dtype=bool)
    for i in range(n_rotors):
        others = np.delete(rpm, i, axis=1)
        others_fly = _row_median(others) >= flight_rpm
        dropout[:, i] = airborne & finite[:, i] & (rpm0[:, i] < dropout_rpm) & others_fly
        p = partners[i]
        if p is None:
            continue
        partner = rpm0[:, p]
        low_vs_partner[:, i] = (airborne & finite[:, i] & (partner >= flight_rpm)
                                & (rpm0[:, i] < partner_ratio * partner))
    over = finite & (rpm0 > max_rpm)
    motor_mask = dropout | low_vs_partner | over
    mask = motor_mask.any(axis=1)
    frac = motor_mask[airborne].mean(axis=0) if n_air else np.zeros(n_rotors)
    unreliable = frac > unreliable_fraction

    for i in range(n_rotors):
        if not motor_mask[:, i].any():
            continue
        n_drop = int(dropout[:, i].sum())
        n_low = int((low_vs_partner[:, i] & ~dropout[:, i]).sum())
        n_over = int((over[:, i] & ~dropout[:, i] & ~low_vs_partner[:, i]).sum())
        parts = []
        if n_drop:
            parts.append(f"{n_drop} read < {dropout_rpm:.0f} rev/min while the other rotors "
                         "run at flight speed (the vehicle would fall: dropout)")
        if n_low:
            sel = low_vs_partner[:, i] & ~dropout[:, i]
            p = partners[i]
            assert p is not None
            ratio = float(np.median(rpm0[sel, i] / rpm0[sel, p]))
            parts.append(f"{n_low} more read below {partner_ratio:g} x the diagonal partner "
                         f"M{p + 1} (median ratio {ratio:.2f}; the vehicle would "
                         "roll and pitch away)")
        if n_over:
            parts.append(f"{n_over} read above {max_rpm:.0f} rev/min")
        verdict = (f" -> the whole M{i + 1} channel is unreliable and excluded"
                   if unreliable[i] else "")
        notes.append(f"motor M{i + 1}: {int(motor_mask[:, i].sum())} of {n_air} airborne rows "
                     f"({100.0 * frac[i]:.1f} %) implausible: " + "; ".join(parts) + verdict)
    if not mask.any():
        notes.append(f"rotor speeds plausible in all {n_air} airborne rows")
    if n_air < n:
        notes.append(f"{n - n_air} rows not airborne (median rotor speed below "
                     f"{flight_rpm:.0f} rev/min): not checked")

    vbat_stuck, vbat_value = False, float("nan")
    if log.vbat is not None:
        v = np.asarray(log.vbat, dtype=float)
        v = v[np.isfinite(v)]
        if v.size >= 2 and float(np.ptp(v)) == 0.0:
            vbat_stuck, vbat_value = True, float(v[0])
            notes.append(f"battery voltage constant at {vbat_value:.3f} V over all {v.size} rows "
                         "(a real battery sags under load and its reading is noisy): vbat is "
                         "not a measurement in this log")
    return ActuationFaultReport(
        source=source, airborne=airborne, motor_mask=motor_mask, dropout_mask=dropout,
        mask=mask, unreliable=unreliable, vbat_stuck=vbat_stuck, vbat_value=vbat_value,
        notes=tuple(notes))


def no_actuation_message(source: str, report: ActuationFaultReport, has_pwm: bool,
                         faults: str) -> str:
    """Why no grid step of a log kept a usable rotor-speed input, naming the channels
    and their flagged rows, and what the command line can do about it."""
    n = report.motor_mask.shape[0]
    parts = []
    for i in range(report.motor_mask.shape[1]):
        rows = np.flatnonzero(report.motor_mask[:, i])
        if rows.size or report.unreliable[i]:
            whole = " (more than 5 % of the airborne rows: the whole channel is distrusted)" \
                if report.unreliable[i] else ""
            where = f"rows {rows[0] + 1}-{rows[-1] + 1}" if rows.size else "no row"
            parts.append(f"rpm_{i + 1}: {rows.size} implausible reading(s), {where}{whole}")
    if has_pwm and faults == "exclude":
        advice = "rebuild them from the log's PWM commands: --faults repair (or repair-all)"
    elif has_pwm:
        advice = ("the PWM map could not rebuild them: try --faults repair-all, or cut the "
                  "log to the rows where every channel reads")
    else:
        advice = ("the log carries no PWM commands to rebuild them from: cut the log to the "
                  "rows where every channel reads, or give the micro-SD log with its PWM")
    return (f"{source}: no usable actuation sample in the whole log: "
            f"{'; '.join(parts) or 'every row lacks a rotor speed'} (of {n} rows); expected "
            f"finite, plausible rotor speeds in every channel; {advice}")


# ----------------------------------------------------------------------------- repair

@dataclass(frozen=True)
class RpmReconstruction:
    """Rotor speeds with untrusted readings replaced from the motor commands.

    Map, learned per log on the trusted readings of the trusted motors:

        rpm_i(t) = c0 + c1 * q_i(t) + c2 * q_i(t)^2,   q_i = lowpass_tau(pwm_i) / 1e4

    with lowpass_tau a first-order lag of time constant tau [s] (the motor and the
    speed sensor respond late to a command). The commanded duty maps to speed through the
    battery voltage, which is why the map is learned per log.

    A distrusted channel whose non-zero readings sit at a whole fraction 1/n of the
    rebuilt speed (the sensor counting one pulse in n; jana20-29's M1 reads 1/2) keeps
    its readings where they agree with that fraction: they are multiplied by n and used
    as measurements (:func:`pulse_divided_readings`).

    rpm (N, n) [rev/min]: the measured speeds of the n rotors with ``replaced`` entries
    substituted; replaced (N, n) bool: entries taken from the PWM map; coef (3,)
    c0 [rev/min], c1, c2 [rev/min per 1e4 PWM counts (squared)]; tau [s]; fit_rms
    [rev/min]: residual of the map on the training data; motors_used: motors (0-based)
    that trained the map; notes; divisions (n,): each replaced channel's
    :class:`PulseDivision` (None: not replaced or not checked; empty: none checked).
    """

    rpm: Array
    replaced: BoolArray
    coef: Array
    tau: float
    fit_rms: float
    motors_used: tuple[int, ...]
    notes: tuple[str, ...]
    divisions: tuple[PulseDivision | None, ...] = ()

    @property
    def rescaled(self) -> BoolArray:
        """(N, n) distrusted readings kept, multiplied by their channel's divisor."""
        out = np.zeros_like(self.replaced)
        for i, div in enumerate(self.divisions):
            if div is not None:
                out[:, i] = div.keep
        return out

    @property
    def divisor(self) -> tuple[int, ...]:
        """(n,) each channel's pulse divisor (1: none found)."""
        divisions = self.divisions or (None,) * self.rpm.shape[1]
        return tuple(1 if d is None else d.divisor for d in divisions)


@dataclass(frozen=True)
class PulseDivision:
    """Readings of one channel that count one pulse in ``divisor``.

    divisor: n (1 when none was found); ratio: median over the channel's non-zero
    readings of reading / rebuilt speed; keep (N,) bool: readings with
    |n reading / rebuilt - 1| < tolerance (whole counts; zero and partial counts fail).
    """

    divisor: int
    ratio: float
    keep: BoolArray
    tolerance: float = 0.1

    def describe(self, motor: int) -> str:
        """One line on what was found for ``motor`` (0-based)."""
        return (f"M{motor + 1} counts one pulse in {self.divisor} (median reading / PWM "
                f"rebuild {self.ratio:.3f} over its non-zero readings): "
                f"{int(self.keep.sum())} readings within {100 * self.tolerance:.0f} % of "
                f"1/{self.divisor} of the rebuilt speed multiplied by {self.divisor} and used "
                "as measured")


def pulse_divided_readings(reading: Array, rebuilt: Array, candidates: BoolArray,
                           tolerance: float = 0.1, max_divisor: int = 4) -> PulseDivision:
    """Whether a channel's distrusted readings (N,) [rev/min] are the rotor speed
    divided by a whole number: n = round(1 / median(reading / rebuilt)) over the
    ``candidates`` rows with a positive reading, accepted when 2 <= n <= max_divisor and
    |n median - 1| < tolerance / 2 (the median itself sits on the fraction).

    A speed sensor that misses every other pulse reads exactly half; the PWM rebuild
    (``rebuilt`` (N,), independent of the reading) tells which fraction.
    """
    none = PulseDivision(divisor=1, ratio=float("nan"), keep=np.zeros(reading.shape, bool),
                         tolerance=tolerance)
    sel = candidates & np.isfinite(reading) & (reading > 0) & (rebuilt > 0)
    if not sel.any():
        return none
    ratio = float(np.median(reading[sel] / rebuilt[sel]))
    n = int(round(1.0 / ratio)) if ratio > 0 else 0
    if not 2 <= n <= max_divisor or abs(n * ratio - 1.0) >= tolerance / 2:
        return replace(none, ratio=ratio)
    with np.errstate(divide="ignore", invalid="ignore"):
        keep = sel & (np.abs(n * reading / rebuilt - 1.0) < tolerance)
    return PulseDivision(divisor=n, ratio=ratio, keep=keep, tolerance=tolerance)


def _first_order_lag(x: Array, tau: float, dt: float) -> Array:
    """y' = (x - y) / tau, discretised with step dt and started at rest on x[0]."""
    if tau <= 0.0:
        return x
    a = dt / (tau + dt)
    y, _ = lfilter([a], [1.0, a - 1.0], x, zi=[x[0] * (1.0 - a)])
    return y


def reconstruct_rpm(log: FlightLog, pwm: Array, report: ActuationFaultReport,
                    taus: tuple[float, ...] = (0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.12, 0.15,
                                               0.2),
                    replace_motors: tuple[int, ...] | None = None,
                    rescue: bool = True) -> RpmReconstruction:
    """Replace untrusted rotor readings from the PWM commands (see :class:`RpmReconstruction`).

    pwm: (N, n) motor commands [0..65535] on the log's rows (``SdFlight.pwm``), one
    column per rotor-speed column of the log (any n).
    Replaced: every reading of an unreliable motor, and each flagged reading of the
    others; ``replace_motors`` (0-based) forces whole motors to be replaced instead
    (used to validate the map on clean logs against the measured speeds). tau [s] is
    argmin_tau rms(rpm - c0 - c1 q - c2 q^2) on the training data: the best of ``taus``,
    refined by a bounded search between its neighbours on the grid; the lag filter steps
    at the clock's step (``io.timebase.uniform_step``). With ``rescue``, a replaced
    channel whose readings are pulse-divided keeps them, multiplied back
    (:func:`pulse_divided_readings`).
    """
    if log.rpm is None:
        raise ValueError(f"{log.meta.source}: the log has no rpm to repair")
    rpm = np.asarray(log.rpm, dtype=float)
    pwm = np.asarray(pwm, dtype=float)
    if pwm.shape != rpm.shape:
        raise ValueError(f"{log.meta.source}: {pwm.shape[-1]} PWM commands per row but "
                         f"{rpm.shape[-1]} rotor speeds (pwm shape {pwm.shape}, rpm shape "
                         f"{rpm.shape}); expected one PWM column per rotor")
    n_rotors = rpm.shape[1]
    if replace_motors is None:
        replaced = report.motor_mask | report.unreliable[None, :]
    else:
        replaced = np.zeros_like(report.motor_mask)
        replaced[:, list(replace_motors)] = True
    whole = replaced.all(axis=0)
    train_motors = tuple(int(i) for i in range(n_rotors)
                         if not whole[i] and np.isfinite(pwm[:, i]).all())
    if not train_motors:
        raise ValueError(f"{log.meta.source}: no trusted motor with a PWM command to learn from")
    dt = uniform_step(log.t)  # the clock's step, not moved by the stamps' jitter
    train = (~replaced & report.airborne[:, None] & np.isfinite(rpm))[:, train_motors]

    def map_fit(tau: float) -> tuple[float, Array]:
        q = np.column_stack([_first_order_lag(pwm[:, i], tau, dt) for i in train_motors]) / 1e4
        qq = q[train]
        x = np.column_stack([np.ones(qq.size), qq, qq * qq])
        y = rpm[:, train_motors][train]
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        return float(np.sqrt(np.mean((y - x @ coef) ** 2))), coef

    # the coarse grid finds the basin, a bounded search between its neighbours the lag:
    # a lag taken from the grid would jump from one grid value to the next on a flat
    # residual when the stamps move by a few ms
    grid_rms = [map_fit(tau)[0] for tau in taus]
    place = int(np.argmin(grid_rms))
    lo, hi = taus[max(place - 1, 0)], taus[min(place + 1, len(taus) - 1)]
    tau = taus[place]
    if hi > lo:
        found = minimize_scalar(lambda v: map_fit(v)[0], bounds=(lo, hi), method="bounded",
                                options={"xatol": 1e-4})
        if found.fun < grid_rms[place]:
            tau = float(found.x)
    rms, coef = map_fit(tau)
    out = rpm.copy()
    divisions: list[PulseDivision | None] = [None] * n_rotors
    notes: list[str] = []
    for i in range(n_rotors):
        if replaced[:, i].any():
            if not np.isfinite(pwm[:, i]).all():
                raise ValueError(f"{log.meta.source}: motor M{i + 1} has no PWM command to "
                                 "reconstruct from")
            q = _first_order_lag(pwm[:, i], tau, dt) / 1e4
            speed = coef[0] + coef[1] * q + coef[2] * q * q
            out[replaced[:, i], i] = speed[replaced[:, i]]
            if not rescue:
                continue
            div = pulse_divided_readings(rpm[:, i], speed, replaced[:, i] & report.airborne)
            divisions[i] = div
            if div.divisor > 1:
                out[div.keep, i] = div.divisor * rpm[div.keep, i]
                replaced[div.keep, i] = False
                notes.append(div.describe(i))
    n_rep = replaced.sum(axis=0)
    rebuilt = ", ".join(f"M{i + 1}: {int(n_rep[i])} rows" for i in range(n_rotors) if n_rep[i])
    notes.insert(0, f"rotor speeds of {rebuilt} rebuilt from PWM (map learned on "
                    f"{', '.join(f'M{i + 1}' for i in train_motors)}: tau = "
                    f"{tau * 1e3:.0f} ms, residual {rms:.0f} rev/min)")
    return RpmReconstruction(rpm=out, replaced=replaced, coef=np.asarray(coef), tau=tau,
                             fit_rms=rms, motors_used=train_motors, notes=tuple(notes),
                             divisions=tuple(divisions))


def repair_log(log: FlightLog, pwm: Array | None = None,
               report: ActuationFaultReport | None = None) -> FlightLog:
    """The log with its faults handled: untrusted rotor speeds rebuilt from ``pwm`` (if
    given and needed), a stuck vbat dropped, and the report's notes added to meta.notes.

    Without pwm, untrusted readings cannot be rebuilt and are left as they are; the
    notes say so, and callers should use ``report.mask`` to exclude the rows. thrust and
    torque, if the log has them, are not recomputed (use ActuatorModel.apply afterwards).
    """
    report = report or detect_actuation_faults(log)
    notes = list(log.meta.notes) + list(report.notes)
    rpm = log.rpm
    needs = bool((report.motor_mask | report.unreliable[None, :]).any()) and rpm is not None
    if needs and pwm is not None:
        rec = reconstruct_rpm(log, pwm, report)
        rpm = rec.rpm
        notes += list(rec.notes)
    elif needs:
        notes.append("implausible rotor speeds left in place (no PWM to rebuild them): "
                     "exclude the rows flagged by the fault report")
    vbat = None if report.vbat_stuck else log.vbat
    return replace(log, rpm=rpm, vbat=vbat, meta=replace(log.meta, notes=tuple(notes)))
