"""The Crazyflie actuator model: rotor speeds -> collective thrust and body torques.

Rotor thrust (quasi-static, per motor i, omega_i [rad/s] = RPM_i * 2 pi / 60):

    T_i = kf * omega_i^2                                  [N],  kf [N / (rad/s)^2]

X-layout mixer, motors M1 front-right (+h, -h), M2 back-right (-h, -h), M3 back-left
(-h, +h), M4 front-left (+h, +h) in body (x, y) with h = arm / sqrt(2) = 0.0325 m:

    F     = sum_i T_i                                     [N]    along body z
    tau_x = sum_i  y_i T_i                                [N m]  roll
    tau_y = sum_i -x_i T_i                                [N m]  pitch
    tau_z = sum_i spin_i * gamma * T_i                    [N m]  yaw

with gamma the torque/thrust ratio [m] and spin_i = +-1, alike on the diagonals (M1, M3)
and (M2, M4). The sign is read from the yaw flights by :func:`fit_yaw`: the measured yaw
acceleration falls when (T1 - T2 + T3 - T4) rises, so spin = (-1, +1, -1, +1)
(M1 and M3 turn counter-clockwise seen from above, their drag torque points down).

kf comes from the Bitcraze thrust stand (:func:`fit_thrust_stand`); run
``python -m pinquad.actuators [--data DIR]`` (``pinquad.cli.actuators``) to print the fits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, filtfilt

from pinquad.core.params import CRAZYFLIE21
from pinquad.core.vehicle_file import VehicleSpec, load_vehicle
from pinquad.io.logs import FlightLog, LogFormatError

Array = NDArray[np.float64]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
"""[rad/s] per [rev/min]."""
GRAM_FORCE = 9.81e-3
"""[N] per gram-force (the stand's ``weight[g]`` column, same g as the rest of pinquad)."""
CRAZYFLIE_SPEC = load_vehicle("crazyflie21")
"""The shipped brushed Crazyflie 2.1 file (``pinquad/data/crazyflie21.toml``): the
constants below are read from it."""
_CF_ACT = CRAZYFLIE_SPEC.actuators
assert _CF_ACT is not None, "pinquad/data/crazyflie21.toml has no [actuators] table"
CRAZYFLIE_ARM = CRAZYFLIE_SPEC.arm
"""Centre to motor axis [m] (firmware constant)."""
KF_CRAZYFLIE = _CF_ACT.kf
"""Thrust coefficient [N/(rad/s)^2]: the pooled thrust-stand fit of both Bitcraze CSVs
(2.056e-8), rounded. The two stand runs alone give 2.10e-8 and 1.91e-8: take +-5 % as the
real uncertainty (see :func:`fit_thrust_stand`)."""
YAW_RATIO_CRAZYFLIE = _CF_ACT.yaw_ratio
"""Yaw torque / thrust [m], published 0.0060-0.0070 m (the firmware uses 0.005964)."""
SPIN_CRAZYFLIE = tuple(float(v) for v in CRAZYFLIE_SPEC.spin)
"""Yaw-torque sign per motor M1..M4, as measured on the yaw flights (:func:`fit_yaw`)."""
YAW_PATTERN = np.array([1.0, -1.0, 1.0, -1.0])
"""Weights of the yaw-torque pattern T1 - T2 + T3 - T4."""


def rad_s_from_rpm(rpm: Array) -> Array:
    """Rotor speed [rad/s] from [rev/min] (any shape)."""
    return np.asarray(rpm, dtype=float) * RPM_TO_RAD_S


def motor_positions(arm: float = CRAZYFLIE_ARM) -> Array:
    """(4, 2) body (x, y) of M1..M4 [m] for the X layout with centre-to-motor ``arm``."""
    h = arm / math.sqrt(2.0)
    return np.array([[h, -h], [-h, -h], [-h, h], [h, h]])


# ----------------------------------------------------------------------------- mixer

@dataclass(frozen=True)
class ActuatorModel:
    """Rotor speeds -> thrust and body torques (equations in the module docstring).

    kf: thrust coefficient [N/(rad/s)^2]; arm: centre to motor axis [m];
    yaw_ratio: gamma, yaw torque per unit thrust [m]; spin: (4,) +-1, the sign of each
    motor's yaw torque (diagonal pairs alike, the two pairs opposite).
    """

    kf: float = KF_CRAZYFLIE
    arm: float = CRAZYFLIE_ARM
    yaw_ratio: float = YAW_RATIO_CRAZYFLIE
    spin: tuple[float, ...] = SPIN_CRAZYFLIE
    xy: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self) -> None:
        s = tuple(float(v) for v in self.spin)
        n = len(s) if self.xy is None else len(self.xy)
        if self.xy is None and len(s) != 4:
            raise ValueError(f"spin must have 4 entries for the X layout; got {s}")
        if len(s) != n or any(abs(v) != 1.0 for v in s) or sum(s) != 0.0:
            raise ValueError(f"spin must be one +-1 per rotor ({n}), as many +1 as -1; got {s}")
        if n == 4 and (s[0] != s[2] or s[1] != s[3]):
            raise ValueError(f"spin must be +-(1, -1, 1, -1) (opposite rotors alike); got {s}")
        object.__setattr__(self, "spin", s)

    @classmethod
    def from_spec(cls, spec: VehicleSpec, kf: float | None = None) -> ActuatorModel:
        """The mixer of a vehicle file (its rotor positions, spins, yaw ratio; kf from the
        file unless given). Raises ValueError if the file has no [actuators] table."""
        if spec.actuators is None:
            raise ValueError(f"{spec.source}: no [actuators] table (kf, kf_se, yaw_ratio): "
                             "rotor speeds cannot be turned into thrust and torques")
        return cls(kf=spec.actuators.kf if kf is None else kf, arm=spec.arm,
                   yaw_ratio=spec.actuators.yaw_ratio, spin=tuple(spec.spin.tolist()),
                   xy=tuple((float(x), float(y)) for x, y in spec.positions))

    @property
    def n_rotors(self) -> int:
        """Number of rotors."""
        return len(self.spin)

    @property
    def positions(self) -> Array:
        """(n, 2) motor (x, y) in the body frame [m]."""
        return motor_positions(self.arm) if self.xy is None else np.asarray(self.xy, float)

    def allocation(self) -> Array:
        """(4, n) matrix A with [F, tau_x, tau_y, tau_z] = A @ [T1..Tn] ([N], [N m])."""
        xy = self.positions
        return np.vstack([np.ones(self.n_rotors), xy[:, 1], -xy[:, 0],
                          self.yaw_ratio * np.asarray(self.spin)])

    def motor_thrust(self, rpm: Array) -> Array:
        """(..., 4) rotor thrusts T_i = kf omega_i^2 [N] from rotor speeds [rev/min]."""
        omega = rad_s_from_rpm(rpm)
        return self.kf * omega * omega

    def wrench(self, rpm: Array) -> tuple[Array, Array]:
        """Thrust (N,) [N] along body z and torque (N, 3) [N m, body] from rpm (N, n)."""
        rpm = np.atleast_2d(np.asarray(rpm, dtype=float))
        if rpm.shape[-1] != self.n_rotors:
            raise ValueError(f"rpm must have {self.n_rotors} columns (one per rotor); got "
                             f"shape {rpm.shape}")
        out = self.motor_thrust(rpm) @ self.allocation().T
        return out[:, 0], out[:, 1:]

    def apply(self, log: FlightLog) -> FlightLog:
        """The log with ``thrust`` and ``torque`` computed from its ``rpm`` (kept too)."""
        if log.rpm is None:
            raise ValueError(f"{log.meta.source}: the log has no rpm to convert")
        thrust, torque = self.wrench(log.rpm)
        return replace(log, thrust=thrust, torque=torque)


# ----------------------------------------------------------------------------- statistics

def _ols(x: Array, y: Array) -> Array:
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return coef


def _jackknife_se(x: Array, y: Array, groups: NDArray[np.int64]) -> Array:
    """Delete-one-group jackknife standard errors of the OLS coefficients.

    Used instead of the textbook sigma^2 (X'X)^-1 because neighbouring samples share
    errors (a held load-cell reading, a low-passed signal, slow unmodelled effects):
    whole contiguous groups are left out, so that correlation is counted.
    """
    labels = np.unique(groups)
    k = labels.size
    if k < 3:
        return np.full(x.shape[1], np.nan)
    est = np.array([_ols(x[groups != g], y[groups != g]) for g in labels])
    return np.sqrt((k - 1) / k * ((est - est.mean(axis=0)) ** 2).sum(axis=0))


def _segments(n: int, k: int) -> NDArray[np.int64]:
    """Labels 0..k-1 of k contiguous, nearly equal segments of n samples."""
    return (np.arange(n) * k // max(n, 1)).astype(np.int64)


# ----------------------------------------------------------------------------- thrust stand

@dataclass(frozen=True)
class ThrustStandFit:
    """Through-origin least-squares fit of the stand's total thrust.

        T_total [N] = weight[g] * 9.81e-3 - tare = kf * sum_i omega_i^2,  omega in rad/s

    source: file name(s); kf [N/(rad/s)^2] and kf_se (delete-one-segment jackknife over
    contiguous segments of the run); residual_rms [N] of the rows used; n_rows / n_used:
    rows in the file(s) / rows in the fit; tare [N]: load-cell zero removed (median with
    all motors stopped); lag_rows: rows by which the load-cell reading trails the rotor
    speeds (chosen to minimise the residual); excluded: what was left out and why.
    """

    source: str
    kf: float
    kf_se: float
    residual_rms: float
    n_rows: int
    n_used: int
    tare: float
    lag_rows: int
    excluded: tuple[str, ...] = ()

    def hover_rpm(self, mass: float = CRAZYFLIE21.mass, gravity: float = 9.81) -> float:
        """Rotor speed [rev/min] at which four rotors carry ``mass`` [kg]."""
        return math.sqrt(mass * gravity / (4.0 * self.kf)) / RPM_TO_RAD_S


@dataclass(frozen=True)
class ThrustCoefficient:
    """The rotor thrust coefficient used for a real flight, and how well it is known.

    kf [N/(rad/s)^2]: the equal-weight mean of the per-run thrust-stand fits;
    kf_se [N/(rad/s)^2]: the standard error of that mean from the spread between runs
    (std(ddof=1) / sqrt(runs)); runs: each run's fit (``fit_thrust_stand`` per CSV);
    pooled [N/(rad/s)^2]: the row-weighted fit of all CSVs together, for comparison;
    note: how kf was chosen, in words; missing_stand: the folder where thrust-stand CSVs
    were looked for and none found (kf then a fallback with its assumed error), None when
    kf came from the stand or no stand folder was named.
    """

    kf: float
    kf_se: float
    runs: tuple[ThrustStandFit, ...]
    pooled: float
    note: str
    missing_stand: Path | None = None

    @property
    def rel_se(self) -> float:
        """kf_se / kf [1]."""
        return self.kf_se / self.kf


@dataclass(frozen=True)
class _StandRows:
    """Rows of one stand file prepared for the fit: x = sum omega^2 [(rad/s)^2] and
    y = tared total thrust [N], aligned for the load-cell lag; group: segment labels."""

    x: Array
    y: Array
    group: NDArray[np.int64]
    n_rows: int
    tare: float
    lag: int
    notes: tuple[str, ...]


_STAND_COLUMNS = ("weight[g]", "rpm1", "rpm2", "rpm3", "rpm4")


def read_thrust_stand(path: str | Path) -> tuple[Array, Array]:
    """Read a Bitcraze thrust-stand CSV: (weight (N,) [grams-force], rpm (N, 4) [rev/min]).

    Unparseable cells become NaN. Raises LogFormatError if a required column is missing.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            header = [h.strip() for h in fh.readline().strip().split(",")]
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read ({exc.strerror})") from None
    missing = [c for c in _STAND_COLUMNS if c not in header]
    if missing:
        raise LogFormatError(
            f"{path}: missing column(s) {', '.join(missing)}; expected a thrust-stand CSV with "
            f"{', '.join(_STAND_COLUMNS)}")
    cols = [header.index(c) for c in _STAND_COLUMNS]
    rows: list[list[float]] = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        fh.readline()
        for line in fh:
            if not line.strip():
                continue
            cells = line.split(",")
            row = []
            for c in cols:
                # A short or non-numeric row is kept as NaN so the fit can count it.
                try:
                    row.append(float(cells[c]))
                except (IndexError, ValueError):
                    row.append(math.nan)
            rows.append(row)
    if not rows:
        raise LogFormatError(f"{path}: no data rows after the header")
    data = np.asarray(rows, dtype=float)
    return data[:, 0], data[:, 1:5]


def _fit_origin(x: Array, y: Array) -> tuple[float, Array]:
    k = float(x @ y / (x @ x))
    return k, y - k * x


def _prepare_stand(path: Path, max_lag: int, n_segments: int) -> _StandRows:
    weight, rpm = read_thrust_stand(path)
    n = weight.size
    notes: list[str] = []
    finite = np.isfinite(weight) & np.isfinite(rpm).all(axis=1)
    if (~finite).any():
        notes.append(f"{int((~finite).sum())} rows with a missing or non-numeric value")
    stopped = finite & (rpm == 0).all(axis=1)
    if stopped.any():
        tare_g = float(np.median(weight[stopped]))
    else:
        tare_g = 0.0
        notes.append("no row with all motors stopped: load-cell zero taken as 0 g")
    thrust = (weight - tare_g) * GRAM_FORCE
    x_all = (rad_s_from_rpm(rpm) ** 2).sum(axis=1)
    # A rotor reading 0 is stopped or unmeasured, so the row says nothing about kf.
    spinning = finite & (rpm > 0).all(axis=1)

    def pairs(lag: int) -> tuple[Array, Array, NDArray[np.int64]]:
        idx = np.flatnonzero(spinning[: n - lag] & finite[lag:])
        return x_all[idx], thrust[idx + lag], idx

    # The load cell reports late (filtered and held for about ten rows); the lag that
    # best explains the data is found by scanning, not assumed.
    best_lag, best_rms = 0, math.inf
    for lag in range(0, min(max_lag, n - 2) + 1):
        x, y, _ = pairs(lag)
        if x.size < 10:
            continue
        _, res = _fit_origin(x, y)
        rms = float(np.sqrt(np.mean(res**2)))
        if rms < best_rms:
            best_lag, best_rms = lag, rms
    x, y, idx = pairs(best_lag)
    n_zero = int((finite & ~spinning).sum())
    if n_zero:
        notes.append(f"{n_zero} rows with at least one rotor at 0 rpm (stopped or unmeasured)")
    n_unpaired = int(spinning.sum()) - idx.size
    if n_unpaired:
        notes.append(f"{n_unpaired} rows with no load-cell reading after aligning the weight "
                     f"{best_lag} rows later (the end of the run)")
    group = _segments(n, n_segments)[idx]
    return _StandRows(x=x, y=y, group=group, n_rows=n, tare=tare_g * GRAM_FORCE,
                      lag=best_lag, notes=tuple(notes))


def _robust_fit(x: Array, y: Array, group: NDArray[np.int64], clip: float
                ) -> tuple[float, float, float, NDArray[np.bool_], int]:
    """Through-origin fit with iterative rejection of |residual| > clip robust sigmas
    (sigma from the median absolute deviation); returns kf, se, rms, keep, n_rejected."""
    keep = np.ones(x.size, dtype=bool)
    for _ in range(10):
        k, _ = _fit_origin(x[keep], y[keep])
        res = y - k * x
        sigma = 1.4826 * float(np.median(np.abs(res[keep] - np.median(res[keep]))))
        new = np.abs(res) <= clip * sigma if sigma > 0 else keep
        if np.array_equal(new, keep):
            break
        keep = new
    k, res = _fit_origin(x[keep], y[keep])
    se = float(_jackknife_se(x[keep, None], y[keep], group[keep])[0])
    return k, se, float(np.sqrt(np.mean(res**2))), keep, int((~keep).sum())


def fit_thrust_stand(paths: str | Path | Sequence[str | Path], max_lag: int = 60,
                     clip: float = 5.0, n_segments: int = 20) -> ThrustStandFit:
    """Fit kf from one or several thrust-stand CSVs (several = pooled).

    Per file: rows with a missing value are dropped; the load-cell zero (median weight
    with all motors stopped) is subtracted; rows with any rotor at 0 rpm are excluded;
    the weight is aligned to the rotor speeds by the lag (0..max_lag rows) that
    minimises the residual; then, on all rows together, T = kf * sum(omega^2) is fitted
    by ordinary least squares through the origin, rejecting rows whose residual exceeds
    ``clip`` robust standard deviations, until no row changes side. kf_se is a
    delete-one-segment jackknife (``n_segments`` contiguous segments per file).
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    files = [Path(p) for p in paths]
    if not files:
        raise ValueError("no thrust-stand file given")
    prepared = [_prepare_stand(p, max_lag, n_segments) for p in files]
    x = np.concatenate([r.x for r in prepared])
    y = np.concatenate([r.y for r in prepared])
    group = np.concatenate([r.group + i * n_segments for i, r in enumerate(prepared)])
    if x.size < 10:
        raise LogFormatError(
            f"{', '.join(str(p) for p in files)}: only {x.size} usable rows (spinning rotors "
            "and a load-cell reading); expected at least 10")
    kf, se, rms, keep, n_rej = _robust_fit(x, y, group, clip)
    excluded: list[str] = []
    for p, r in zip(files, prepared, strict=True):
        excluded.extend(f"{p.name}: {note}" for note in r.notes)
    if n_rej:
        excluded.append(f"{n_rej} rows whose residual exceeded {clip:g} robust standard "
                        "deviations (spin-up/spin-down transients the lag does not capture)")
    single = len(prepared) == 1
    return ThrustStandFit(
        source=", ".join(p.name for p in files), kf=kf, kf_se=se, residual_rms=rms,
        n_rows=sum(r.n_rows for r in prepared), n_used=int(keep.sum()),
        tare=prepared[0].tare if single else float("nan"),
        lag_rows=prepared[0].lag if single else -1, excluded=tuple(excluded))


# ----------------------------------------------------------------------------- yaw sign

@dataclass(frozen=True)
class YawFit:
    """Yaw torque from the rotor speeds, fitted on one flight.

    Model, per sample, with u = kf * sum_i p_i omega_i^2 [N], p = (1, -1, 1, -1)
    (the thrust pattern T1 - T2 + T3 - T4) and w = sum_i p_i omega_i [rad/s]:

        Izz * d(omega_z)/dt = s * (gamma * u + J_r * dw/dt) - d * omega_z + c

    i.e. the regression  d(omega_z)/dt = gain * u + b_w * dw/dt + b_d * omega_z + b_0
    with gain = s * gamma / Izz [rad/s^2 per N]. The J_r term is the reaction of the
    rotors' own angular acceleration (rotor inertia J_r [kg m^2]); d [N m s] is yaw
    damping (rotor drag at a yaw rate), c [N m] a constant offset (e.g. motor tilt).

    source: the log; sign: s = sign(gain), the yaw-torque sign of M1 and M3;
    gain, gain_se [rad/s^2 / N]; izz [kg m^2] used to turn the gain into a ratio;
    yaw_ratio = |gain| * izz [m] and its se; rotor_inertia = J_r [kg m^2] (NaN if not
    fitted) and its se; damping = -b_d [1/s]; r2: fraction of the variance of
    d(omega_z)/dt explained; n_used: samples in the fit; cutoff_hz: low-pass cut-off
    applied to omega_z and the regressors before differentiating; notes: exclusions.
    Standard errors: delete-one-block jackknife over contiguous time blocks.
    """

    source: str
    sign: int
    gain: float
    gain_se: float
    izz: float
    yaw_ratio: float
    yaw_ratio_se: float
    rotor_inertia: float
    rotor_inertia_se: float
    damping: float
    r2: float
    n_used: int
    cutoff_hz: float
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def t_stat(self) -> float:
        """gain / gain_se: how far the sign is from chance."""
        return self.gain / self.gain_se if self.gain_se > 0 else math.inf

    @property
    def ratio_over_izz(self) -> float:
        """|gain| = gamma / Izz [1/(kg m)], what the flight identifies without Izz."""
        return abs(self.gain)

    @property
    def spin(self) -> tuple[float, float, float, float]:
        """The spin tuple for :class:`ActuatorModel` implied by the fitted sign."""
        s = float(self.sign)
        return (s, -s, s, -s)


def _fill_nan(x: Array) -> Array:
    """Linear interpolation over NaNs (so a filter can run), NaN-free input unchanged."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return x
    idx = np.arange(x.size)
    out = x.copy()
    out[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return out


def fit_yaw(log: FlightLog, model: ActuatorModel | None = None,
            izz: float = float(CRAZYFLIE21.inertia[2, 2]), cutoff_hz: float = 10.0,
            rotor_inertia: bool = True, exclude: NDArray[np.bool_] | None = None,
            n_blocks: int = 10) -> YawFit:
    """Regress the yaw angular acceleration on the yaw-torque pattern (see :class:`YawFit`).

    omega_z (gyro z [rad/s]) and the regressors are low-passed with the same zero-phase
    2nd-order Butterworth filter (``cutoff_hz``), so the filter does not distort their
    relation, and then differentiated in time. Used: rows with finite gyro z and rpm,
    all rotors spinning (> 1000 rev/min), not in ``exclude`` (e.g. a fault mask), away
    from time-stamp gaps (> 2 median intervals) and the ends by 2 / cutoff_hz seconds.
    """
    model = model or ActuatorModel()
    if log.rpm is None:
        raise ValueError(f"{log.meta.source}: the log has no rpm; the yaw fit needs them")
    t = log.t
    n = log.n
    dt = log.dt
    fs = 1.0 / dt
    if n < 10 or not (0 < cutoff_hz < 0.5 * fs):
        raise ValueError(f"{log.meta.source}: need a longer log or 0 < cutoff < fs/2")
    notes: list[str] = []
    omega = rad_s_from_rpm(log.rpm)
    valid = np.isfinite(log.gyro[:, 2]) & np.isfinite(omega).all(axis=1)
    valid &= (log.rpm > 1000.0).all(axis=1)
    if exclude is not None:
        ex = np.asarray(exclude, dtype=bool)
        valid &= ~ex
        notes.append(f"{int(ex.sum())} rows excluded by the caller's mask")
    if valid.sum() < 20 * n_blocks:
        raise ValueError(f"{log.meta.source}: only {int(valid.sum())} rows with finite gyro z and "
                         f"spinning rotors; the yaw fit needs at least {20 * n_blocks}")
    b, a = butter(2, cutoff_hz / (0.5 * fs))

    def smooth(x: Array) -> Array:
        return filtfilt(b, a, _fill_nan(x))

    # Filter the regressors themselves (u is linear in omega^2, w in omega) so that the
    # filtered equation is the same linear relation as the raw one.
    omega_v = np.where(valid[:, None], omega, np.nan)
    u = smooth(model.kf * (omega_v**2) @ YAW_PATTERN)
    wdot = np.gradient(smooth(omega_v @ YAW_PATTERN), t)
    wz = smooth(np.where(valid, log.gyro[:, 2], np.nan))
    y = np.gradient(wz, t)

    # Rows near a gap, an invalid row or the ends see filter and difference transients.
    margin = max(1, int(round(2.0 / cutoff_hz * fs)))
    bad = ~valid
    gaps = np.flatnonzero(np.diff(t) > 2.0 * dt)
    bad[gaps] = bad[np.minimum(gaps + 1, n - 1)] = True
    bad[0] = bad[-1] = True
    near_bad = np.convolve(bad.astype(float), np.ones(2 * margin + 1), mode="same") > 0
    use = ~near_bad
    if use.sum() < 20 * n_blocks:
        raise ValueError(f"{log.meta.source}: only {int(use.sum())} usable rows for the yaw fit")
    notes.append(f"{int((~use).sum())} of {n} rows left out (invalid, stationary rotors, gaps "
                 f"or within {margin} rows of them or of the ends)")

    cols = [u[use]]
    if rotor_inertia:
        cols.append(wdot[use])
    cols += [wz[use], np.ones(int(use.sum()))]
    x = np.column_stack(cols)
    yy = y[use]
    coef = _ols(x, yy)
    se = _jackknife_se(x, yy, _segments(int(use.sum()), n_blocks))
    res = yy - x @ coef
    gain, gain_se = float(coef[0]), float(se[0])
    sign = 1 if gain > 0 else -1
    if rotor_inertia:
        jr, jr_se = float(coef[1]) * izz * sign, float(se[1]) * izz
    else:
        jr = jr_se = float("nan")
    return YawFit(
        source=log.meta.source, sign=sign, gain=gain, gain_se=gain_se, izz=izz,
        yaw_ratio=abs(gain) * izz, yaw_ratio_se=gain_se * izz, rotor_inertia=jr,
        rotor_inertia_se=jr_se, damping=-float(coef[-2]),
        r2=float(1.0 - res.var() / yy.var()), n_used=int(use.sum()), cutoff_hz=cutoff_hz,
        notes=tuple(notes))
