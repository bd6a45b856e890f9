"""Known-mass identification of a flight logged with motor commands (a PX4 log, or an
IMU-only log: accelerometer, gyro and motor commands): the thrust curve, the motor time
constant and the inertia, by regression (not EM). Several segments of one log, or of
several logs of one vehicle, are fitted as one (``Stack``): the curve, time constant and
inertia shared, each log's drag, damping and gyroscopic coefficient its own; filters,
lags and derivatives run per segment.

With the mass m [kg] known (a scale), the body z specific force a_z [m/s^2] fixes the
scale of the actuator curve (``pinquad.core.actuator_curve``):

    m a_z = sum_i (c_1 u'_i + c_2 u'_i^2) - d_z v_bz              [N]

u'_i: command u_i through the first-order motor lag of time constant tau (exact
zero-order-hold discretisation, a = exp(-dt / tau)); v_bz [m/s]: body-z velocity (a
linear drag d_z [N s/m] that would otherwise be read as thrust; an IMU-only log has no
velocity, and no drag column). c_1 is kept only when
the data carry it (|c_1| > 2 standard errors). tau is chosen by the profile likelihood of
this regression over a grid (Gaussian residuals: -N_eff/2 log RSS(tau); its standard
error from where the profile falls by 1/2).

The inertia: with T_i from the curve, the roll and pitch torques tau_x = sum_i y_i T_i,
tau_y = -sum_i x_i T_i [N m] and, when the yaw ratio k is given, tau_z = k sum_i spin_i T_i.
Both sides band-passed by the same zero-phase Butterworth filter (``band`` [Hz]: below it
slow torque offsets such as a centre-of-mass offset, above it noise), per axis

    tau_a = I_aa domega_a/dt + b_a omega_a + g_a omega_b omega_c   [N m]

(b_a [N m s]: rotational damping; g_a [kg m^2]: the gyroscopic coefficient, I_bb - I_cc
for a rigid body, left free since the other moments are what is being estimated), least
squares. Without the yaw ratio I_zz is not
identified (only I_zz / k is) and says so.

Standard errors: the statistical part from a heteroscedasticity-and-autocorrelation
consistent (Newey-West) covariance, since the residuals of a flight are not white; and
the parts of what was assumed: the mass (``mass_rel_se``), the rotor positions
(``arm_rel_se``; I_zz: the yaw ratio's ``yaw_ratio_se``, else the house default), the
time constant (refit at tau +- its se) and, for the inertia, the
curve's coefficients (their covariance carried through). On an IMU-only log, the rotor
drag the regression cannot see: every estimate is fitted again (time constant profiled,
curve, inertia) with a body-z drag d_z at its bound (the vehicle file's ``[aero] drag``
D_z, else ``drag_rate_max`` m), its velocity v_bz reconstructed from the specific force
(``vertical_velocity``), and the change is the part ``rotor_drag``: drag lowers the
curve's slope by a factor of about |i w m / (i w m + d_z)| at the flight's frequencies
w, and nothing else in such a log tells how much. The naive regression beside it
(no lag, no drag, no filter, raw finite-difference domega/dt) shows what these change.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, lfilter, sosfiltfilt

from pinquad.core.actuator_curve import ActuatorCurve
from pinquad.core.conventions import rotation_from_euler
from pinquad.identification.budget import DEFAULT_ARM, DEFAULT_YAW_TORQUE
from pinquad.identification.verdict import (
    DEFAULT_THRESHOLDS,
    BandHalves,
    Estimate,
    ExplainedShare,
    VerdictEvidence,
    VerdictThresholds,
    judge_estimate,
)
from pinquad.io.command_log import CommandLog

Array = NDArray[np.float64]


@dataclass(frozen=True)
class KnownMassSettings:
    """What the estimator assumes and demands.

    mass_rel_se [-]: relative standard uncertainty of the given mass; arm_rel_se [-]: of
    the rotor positions; band (lo, hi) [Hz]: the torque regression's band; lags (L,) [s]:
    the time constants profiled; thresholds: what a trusted estimate demands
    (``verdict.VerdictThresholds``: max_rel_se, min_fit_share, max_band_shift);
    drag_rate_max [1/s]: on a log without velocity, the largest body-z rotor drag per unit
    mass d_z / m assumed when the vehicle file declares none (its error part, module
    docstring).
    """

    mass_rel_se: float = 0.01
    arm_rel_se: float = DEFAULT_ARM
    band: tuple[float, float] = (0.3, 2.0)
    lags: Array = field(default_factory=lambda: np.arange(0.0, 0.2001, 0.0025))
    thresholds: VerdictThresholds = DEFAULT_THRESHOLDS
    drag_rate_max: float = 0.5


@dataclass(frozen=True)
class KnownMassResult:
    """Known-mass identification of one log: estimates (thrust curve c_1, c_2, drag d_z,
    the curve's thrust and slope at the mean command, time constant, I_xx, I_yy, I_zz),
    the vertical fit's explained share and the torque fits' per axis, the naive
    regression's inertia (3,) [kg m^2, NaN: not estimated] and shares, the given mass
    [kg] and its assumed standard uncertainty mass_se [kg], the band [Hz], notes, and the
    mean command u_m [-] where the curve's thrust and slope are given."""

    estimates: tuple[Estimate, ...]
    force_share: float
    torque_share: tuple[float, ...]
    naive_inertia: Array
    naive_share: tuple[float, ...]
    mass: float
    mass_se: float
    band: tuple[float, float]
    notes: tuple[str, ...] = ()
    mean_command: float = float("nan")

    def get(self, name: str) -> Estimate:
        """The estimate called ``name``."""
        return next(e for e in self.estimates if e.name == name)


def motor_lag(command: Array, tau: float, dt: float) -> Array:
    """u' of tau du'/dt = u - u' under a zero-order hold, from u'(0) = u(0):
    u'_{k+1} = a u'_k + (1 - a) u_k, a = exp(-dt / tau). (N, k) -> (N, k)."""
    if tau <= 0.0:
        return command
    a = math.exp(-dt / tau)
    # v_k = a v_{k-1} + (1 - a) u_k from v_0 = u_0; then u'_k = v_{k-1} (the hold's step)
    held, _ = lfilter([1.0 - a], [1.0, -a], command, axis=0, zi=a * command[:1])
    out = np.empty_like(held)
    out[0], out[1:] = command[0], held[:-1]
    return out


def _cross_covariances(a: Array, b: Array, lags: int) -> Array:
    """G[k, i, j] = sum_t a[t + k, i] b[t, j] for k = 0..lags, by FFT: (lags + 1, p, q)."""
    n = a.shape[0]
    size = 1 << (2 * n - 1).bit_length()
    fa = np.fft.rfft(a, size, axis=0)
    fb = np.fft.rfft(b, size, axis=0)
    full = np.fft.irfft(fa[:, :, None] * np.conj(fb[:, None, :]), size, axis=0)
    return full[: lags + 1]


def newey_west(x: Array, resid: Array, min_lag: int = 0) -> tuple[Array, int]:
    """Coefficient covariance (p, p) of least squares x (N, p) with residuals (N,), HAC
    with Bartlett weights up to lag L: past the last lag (below N / 4) where the
    residuals' autocorrelation is still 0.05 or more in size, and at least ``min_lag``
    (a band-passed residual oscillates: its autocorrelation crosses zero long before it
    dies out). The lagged sums are taken by FFT. Returns (cov, L)."""
    n = resid.shape[0]
    r = resid - resid.mean()
    acf = _cross_covariances(r[:, None], r[:, None], n // 4)[:, 0, 0] / (r @ r)
    big = np.flatnonzero(np.abs(acf[: n // 4]) >= 0.05)
    lag = int(min(max(big[-1] + 1 if big.size else 0, min_lag), n // 4))
    xe = x * resid[:, None]
    gammas = _cross_covariances(xe, xe, lag)
    weights = 1.0 - np.arange(lag + 1) / (lag + 1.0)
    g = np.einsum("k,kij->ij", weights[1:], gammas[1:])
    s = xe.T @ xe + g + g.T
    bread = np.linalg.inv(x.T @ x)
    return bread @ s @ bread, lag


def effective_rows(resid: Array, lag: int) -> float:
    """N / (1 + 2 sum_{l=1..L} rho_l): rows of independent information in residuals."""
    n = resid.shape[0]
    r = resid - resid.mean()
    rho = _cross_covariances(r[:, None], r[:, None], lag)[1:, 0, 0] / (r @ r)
    return n / max(1.0 + 2.0 * float(np.sum(rho)), 1.0)


@dataclass(frozen=True)
class Stack:
    """Rows of several flight segments stacked for one regression: bounds ((start, stop)
    per segment, in stacked rows) and group (N,) int: which log each row is from (each
    log's nuisance terms, drag and rotational damping, are its own; the vehicle's are
    shared). Filters, lags and derivatives run per segment, never across a seam."""

    bounds: tuple[tuple[int, int], ...]
    group: NDArray[np.int64]

    @property
    def n_groups(self) -> int:
        """Number of logs (nuisance groups)."""
        return int(self.group.max()) + 1

    def each(self, fn, arr: Array) -> Array:
        """fn applied to each segment's rows of ``arr`` (N, ...), stacked again."""
        return np.concatenate([fn(arr[a:b]) for a, b in self.bounds], axis=0)

    def per_group(self, col: Array) -> Array:
        """(N,) -> (N, G): ``col`` in the column of its row's group, 0 elsewhere."""
        out = np.zeros((col.shape[0], self.n_groups))
        out[np.arange(col.shape[0]), self.group] = col
        return out


@dataclass(frozen=True)
class _Curve:
    coef: Array          # (c_1, c_2, d_z per group) with c_1 = 0 when not carried
    cov: Array           # (2 + G, 2 + G) statistical
    linear: bool
    rss: float
    share: float
    resid: Array


def _curve_fit(m: float, a_z: Array, v_bz: Array | None, u: Array, linear: bool | None,
               stack: Stack, rss_only: bool = False) -> _Curve:
    """The vertical-force regression (module docstring), a drag d_z per log; without the
    body-z velocity (``v_bz`` None: an IMU-only log) no drag columns, each d_z reported
    as 0 with no variance. ``rss_only``: the fit and its residual sum of squares only
    (the time constant's profile), no covariance (zeros)."""
    y = m * a_z
    drag = [] if v_bz is None else list(stack.per_group(-v_bz).T)
    cols = [u.sum(axis=1), (u * u).sum(axis=1), *drag]
    x = np.column_stack(cols if linear is not False else cols[1:])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ coef
    if rss_only:
        return _Curve(coef, np.zeros((x.shape[1], x.shape[1])), True, float(resid @ resid),
                      1.0 - float(resid.var() / y.var()), resid)
    cov, _ = newey_west(x, resid)
    if linear is None and abs(coef[0]) < 2.0 * math.sqrt(cov[0, 0]):
        return _curve_fit(m, a_z, v_bz, u, False, stack)
    linear_kept = linear is not False
    if not linear_kept:
        coef, cov = np.r_[0.0, coef], np.pad(cov, ((1, 0), (1, 0)))
    if v_bz is None:
        g = stack.n_groups
        coef, cov = np.r_[coef, np.zeros(g)], np.pad(cov, ((0, g), (0, g)))
    return _Curve(coef, cov, linear_kept, float(resid @ resid),
                  1.0 - float(resid.var() / y.var()), resid)


def vertical_velocity(a_z: Array, dt: float) -> Array:
    """The body-z velocity v_bz [m/s] (N,) of one segment of evenly spaced specific force
    a_z [m/s^2] (N,), row spacing dt [s], without a velocity measurement: near level
    flight dv_bz/dt = a_z - g, integrated with the segment's mean removed (g, the
    accelerometer's bias) and high-passed above 0.02 Hz (second-order Butterworth, zero
    phase: the integral's drift). Tilt and the rotation of horizontal velocity into body
    z are left out; it serves to size the effect of a drag, not to correct for one."""
    v = np.cumsum(a_z - a_z.mean()) * dt
    if v.shape[0] <= 15:  # too short for the filter: the drift is a line
        return v - np.polyval(np.polyfit(np.arange(v.shape[0]), v, 1), np.arange(v.shape[0]))
    return sosfiltfilt(butter(2, 0.02, "highpass", fs=1.0 / dt, output="sos"), v)


def _thrust(curve: Array, u: Array) -> Array:
    return curve[0] * u + curve[1] * u * u


def _torques(thrust: Array, positions: Array, spin: Array, yaw_ratio: float | None) -> Array:
    tz = thrust @ spin * (yaw_ratio if yaw_ratio is not None else np.nan)
    return np.column_stack([thrust @ positions[:, 1], -(thrust @ positions[:, 0]), tz])


def _inertia_fit(torque: Array, gyro: Array, dt: float, band: tuple[float, float],
                 stack: Stack) -> tuple[Array, Array, Array]:
    """Per axis (I, statistical se, explained share) of the band-passed torque against
    domega/dt and omega (module docstring; damping and gyroscopic coefficient per log);
    NaN for an axis without torque."""
    sos = butter(4, band, btype="band", fs=1.0 / dt, output="sos")

    def bandpass(a: Array) -> Array:
        return sosfiltfilt(sos, a, axis=0)

    w = stack.each(bandpass, gyro)
    wd = stack.each(lambda a: np.gradient(a, dt, axis=0), w)
    # the gyroscopic term (I_bb - I_cc) omega_b omega_c with a free coefficient: it needs
    # the other moments, not yet known (the product is formed before filtering)
    cross = stack.each(bandpass, np.column_stack([gyro[:, 1] * gyro[:, 2],
                                                  gyro[:, 2] * gyro[:, 0],
                                                  gyro[:, 0] * gyro[:, 1]]))
    value, se, share = np.full(3, np.nan), np.full(3, np.nan), np.full(3, np.nan)
    for a in range(3):
        if not np.isfinite(torque[:, a]).all():
            continue
        y = stack.each(bandpass, torque[:, a])
        x = np.column_stack([wd[:, a], stack.per_group(w[:, a]), stack.per_group(cross[:, a])])
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        resid = y - x @ coef
        # at least two periods of the band's lowest frequency
        cov, _ = newey_west(x, resid, min_lag=math.ceil(2.0 / (band[0] * dt)))
        value[a], se[a] = coef[0], math.sqrt(cov[0, 0])
        share[a] = 1.0 - float(resid.var() / y.var())
    return value, se, share


def _naive(m: float, a_z: Array, u: Array, gyro: Array, dt: float, positions: Array,
           spin: Array, stack: Stack) -> tuple[Array, tuple[float, ...]]:
    """No lag, no drag, no filter: c from m a_z = sum(c_1 u + c_2 u^2), torque against
    the finite-difference domega/dt with an offset."""
    x = np.column_stack([u.sum(axis=1), (u * u).sum(axis=1)])
    c, *_ = np.linalg.lstsq(x, m * a_z, rcond=None)
    torque = _torques(_thrust(c, u), positions, spin, None)
    wd = stack.each(lambda a: np.gradient(a, dt, axis=0), gyro)
    out, share = np.full(3, np.nan), []
    for a in range(2):
        xa = np.column_stack([wd[:, a], np.ones_like(wd[:, a])])
        coef, *_ = np.linalg.lstsq(xa, torque[:, a], rcond=None)
        resid = torque[:, a] - xa @ coef
        out[a] = coef[0]
        share.append(1.0 - float(resid.var() / torque[:, a].var()))
    return out, tuple(share)


NO_YAW_RATIO = ("I_zz", "I_zz needs the yaw torque coefficient (actuator_curve.yaw_ratio [m] "
                "in the vehicle file): motor commands give yaw torque only up to that factor")
"""Why I_zz has no value when the vehicle file gives no yaw torque coefficient: motor
commands fix the yaw torque only up to that factor (I_zz / k is all a log carries)."""


def yaw_inertia_without_ratio(thresholds: VerdictThresholds = DEFAULT_THRESHOLDS) -> Estimate:
    """I_zz without the yaw torque coefficient: no value (``NO_YAW_RATIO``), not
    identifiable (``verdict.judge_estimate``)."""
    return judge_estimate("I_zz", float("nan"), "kg m^2", {},
                          VerdictEvidence(undetermined=(NO_YAW_RATIO,)), thresholds)


def stack_segments(segments: Sequence[CommandLog], groups: Sequence[int] | None = None
                   ) -> tuple[Stack, float]:
    """The ``Stack`` of ``segments`` (each a CommandLog of evenly spaced rows, all of one
    row spacing) and that spacing dt [s]; groups (S,): the log each segment is from
    (default: all from one). Raises ValueError naming the log on uneven rows or
    different spacings."""
    dts = []
    for seg in segments:
        steps = np.diff(seg.log.t)
        dt = float(np.median(steps))
        if np.abs(steps - dt).max() > 0.01 * dt:
            raise ValueError(f"{seg.log.meta.source}: rows are not evenly spaced (steps "
                             f"{steps.min():.4g} to {steps.max():.4g} s); expected one row "
                             f"per {dt:.4g} s")
        dts.append(dt)
    if max(dts) - min(dts) > 0.01 * min(dts):
        raise ValueError(f"{segments[0].log.meta.source}: row spacings {min(dts):.4g} to "
                         f"{max(dts):.4g} s across the logs; expected one spacing")
    groups = [0] * len(segments) if groups is None else list(groups)
    sizes = np.array([seg.log.n for seg in segments])
    ends = np.cumsum(sizes)
    bounds = tuple((int(e - n), int(e)) for e, n in zip(ends, sizes, strict=True))
    return Stack(bounds, np.repeat(np.asarray(groups, dtype=np.int64), sizes)), dts[0]


def identify_known_mass(flight: CommandLog | Sequence[CommandLog], mass: float,
                        positions: Array, spin: Array, curve: ActuatorCurve | None = None,
                        settings: KnownMassSettings | None = None,
                        groups: Sequence[int] | None = None, drag_z: float | None = None
                        ) -> KnownMassResult:
    """Known-mass identification of ``flight`` (module docstring): one log, or several
    segments (of one log or of several logs of the same vehicle: ``groups`` (S,) the log
    of each segment; the curve, time constant and inertia shared, each log's drag and
    damping its own); mass [kg], rotor positions (k, 2) [m, body] and spin (k,) in the
    logs' motor order, the vehicle's actuator curve (its yaw_ratio used when given),
    drag_z [N s/m]: the vehicle's body-z rotor drag (``[aero] drag`` D_z), the bound of
    the ``rotor_drag`` part on an IMU-only log (None: ``drag_rate_max`` times the mass).
    Raises ValueError naming the log when its rows are not evenly spaced, its motors and
    rotors disagree, or a signal is missing."""
    curve = curve or ActuatorCurve()
    settings = settings or KnownMassSettings()
    segments = (flight,) if isinstance(flight, CommandLog) else tuple(flight)
    src = segments[0].log.meta.source
    for seg in segments:
        if seg.n_motors != positions.shape[0]:
            raise ValueError(f"{seg.log.meta.source}: {seg.n_motors} motor command columns "
                             f"but the vehicle has {positions.shape[0]} rotors")
    stack, dt = stack_segments(segments, groups)
    shortest = 4.0 / settings.band[0]
    span = sum(seg.log.t[-1] - seg.log.t[0] for seg in segments)
    if span < shortest:
        raise ValueError(f"{src}: {span:.1f} s of flight; the torque band's "
                         f"low edge {settings.band[0]:g} Hz needs at least {shortest:.0f} s")
    # no velocity, no attitude (an IMU-only log): no drag column
    imu_only = any(seg.imu_only for seg in segments)
    for seg in segments:
        log = seg.log
        for name, arr in (("velocity", log.velocity), ("attitude", log.euler),
                          ("gyro", log.gyro), ("acceleration", log.accel),
                          ("motor command", seg.command)):
            if not (imu_only and name in ("velocity", "attitude")) and \
                    not np.isfinite(arr).all():
                raise ValueError(f"{log.meta.source}: {name} is missing in some rows; "
                                 "expected every row")
    v_bz = None if imu_only else np.concatenate([
        np.einsum("nij,ni->nj", rotation_from_euler(seg.log.euler), seg.log.velocity)[:, 2]
        for seg in segments])
    a_z = np.concatenate([seg.log.accel[:, 2] for seg in segments])
    u = np.concatenate([seg.command for seg in segments])
    gyro = np.concatenate([seg.log.gyro for seg in segments])

    def lag(tau: float) -> Array:
        return stack.each(lambda c: motor_lag(c, tau, dt), u)

    # the time constant: profile of the vertical-force regression
    fits = [_curve_fit(mass, a_z, v_bz, lag(tau), True, stack, rss_only=True)
            for tau in settings.lags]
    rss = np.array([f.rss for f in fits])
    best = int(np.argmin(rss))
    tau = float(settings.lags[best])
    top = _curve_fit(mass, a_z, v_bz, lag(tau), None, stack)
    _, lag_rows = newey_west(np.ones((a_z.shape[0], 1)), top.resid)
    n_eff = effective_rows(top.resid, lag_rows)
    drop = 0.5 * n_eff * np.log(rss / rss[best])
    inside = np.flatnonzero(drop <= 0.5)
    tau_lo, tau_hi = float(settings.lags[inside[0]]), float(settings.lags[inside[-1]])
    tau_se = max(tau_hi - tau_lo, float(np.diff(settings.lags[:2])[0])) / 2.0
    tau_edge = inside[-1] == len(settings.lags) - 1  # 0 is physics' end, not the grid's
    if curve.time_constant is not None:  # given: the curve is fitted through it
        tau, tau_se, tau_edge = curve.time_constant, 0.0, False
        top = _curve_fit(mass, a_z, v_bz, lag(tau), None, stack)
    alt = [_curve_fit(mass, a_z, v_bz, lag(max(tau + s * tau_se, 0.0)), top.linear, stack)
           for s in (-1.0, 1.0)]
    tau_part = np.abs(alt[1].coef - alt[0].coef) / 2.0
    # an IMU-only log cannot see rotor drag: everything fitted again with the drag at its
    # bound, velocity from the specific force; the change is the rotor_drag part
    drag_bound = (drag_z if drag_z is not None else settings.drag_rate_max * mass) \
        if imu_only else 0.0
    tau_d, drag_shift = tau, np.zeros_like(top.coef)
    if drag_bound > 0.0:
        a_drag = a_z + drag_bound / mass * stack.each(lambda a: vertical_velocity(a, dt), a_z)
        if curve.time_constant is None:
            rss_d = [_curve_fit(mass, a_drag, None, lag(t), True, stack, rss_only=True).rss
                     for t in settings.lags]
            tau_d = float(settings.lags[int(np.argmin(rss_d))])
        drag_shift = _curve_fit(mass, a_drag, None, lag(tau_d), top.linear, stack).coef \
            - top.coef

    notes = list(dict.fromkeys(n for seg in segments for n in seg.notes))  # once each
    if curve.thrust is not None:
        notes.append(f"the vehicle file's thrust curve {curve.thrust.tolist()} N is not used: "
                     "the curve is identified from this flight")
    # each number (name, value, unit, error parts by source), judged once all the
    # findings of the fit are in (``verdict.judge_estimate``)
    numbers: list[tuple[str, float, str, dict[str, float]]] = []
    undetermined: list[tuple[str, str]] = []
    n_groups = stack.n_groups
    drags = [("drag d_z" if n_groups == 1 else f"drag d_z [log {g + 1}]", "N s/m")
             for g in range(n_groups)]
    if imu_only:
        bound_src = "the vehicle file's [aero] drag" if drag_z is not None else \
            f"{settings.drag_rate_max:g} /s times the mass, no [aero] drag in the vehicle file"
        notes.append("no velocity in the log: no body-z drag term (d_z not estimated; a drag "
                     "the flight excites is read as thrust, lowering the curve's slope); the "
                     f"error part rotor_drag is each estimate's change with d_z = "
                     f"{drag_bound:.3g} N s/m ({bound_src})")
    for i, (name, unit) in enumerate((("thrust c_1", "N"), ("thrust c_2", "N"), *drags)):
        if i == 0 and not top.linear:
            notes.append("thrust c_1 (linear term): not carried by this log (|c_1| < 2 se): "
                         "the curve is T = c_2 u^2")
            continue
        if i >= 2 and imu_only:
            continue
        parts = {"statistical": math.sqrt(top.cov[i, i]),
                 "mass": abs(top.coef[i]) * settings.mass_rel_se,
                 "time_constant": float(tau_part[i]),
                 **({"rotor_drag": abs(float(drag_shift[i]))} if imu_only else {})}
        numbers.append((name, float(top.coef[i]), unit, parts))
    # the curve's scale where the flight flew: T(u_m) = c_1 u_m + c_2 u_m^2 and its slope
    # dT/du = c_1 + 2 c_2 u_m at the mean command u_m; c_1 and c_2 trade against each
    # other, these two do not (the slope is what turns command differences into torque)
    u_m = float(lag(tau).mean())
    notes.append(f"mean command u = {u_m:.3f}: the curve's thrust and slope dT/du there")
    rest = np.zeros(n_groups)
    for name, grad in (("thrust at mean u", np.r_[u_m, u_m * u_m, rest]),
                       ("dT/du at mean u", np.r_[1.0, 2.0 * u_m, rest])):
        value = float(grad @ top.coef)
        parts = {"statistical": math.sqrt(float(grad @ top.cov @ grad)),
                 "mass": abs(value) * settings.mass_rel_se,
                 "time_constant": abs(float(grad @ (alt[1].coef - alt[0].coef))) / 2.0,
                 **({"rotor_drag": abs(float(grad @ drag_shift))} if imu_only else {})}
        numbers.append((name, value, "N", parts))
    if curve.time_constant is None:
        numbers.append(("time constant", tau, "s", {"statistical": tau_se, **(
            {"rotor_drag": abs(tau_d - tau)} if imu_only else {})}))
        if tau_edge:
            undetermined.append(("time constant", (
                f"the profile likelihood's interval reaches the end of the searched "
                f"{settings.lags[0]:.3f}-{settings.lags[-1]:.3f} s")))
        elif tau == 0.0:
            undetermined.append(("time constant", (
                f"the profile likelihood puts the time constant at 0, below "
                f"{settings.lags[inside[-1] + 1]:.3g} s: no motor lag resolvable at "
                f"{dt * 1e3:.0f} ms rows")))
    else:
        notes.append(f"time constant {tau:.4g} s: given by the vehicle file")

    # the inertia from the curve's torques
    lagged = lag(tau)

    def inertia_at(coef: Array, lag_u: Array, band: tuple[float, float]):
        torque = _torques(_thrust(coef, lag_u), positions, spin, curve.yaw_ratio)
        return _inertia_fit(torque, gyro, dt, band, stack)

    inertia, inertia_se, share = inertia_at(top.coef, lagged, settings.band)
    jac = np.zeros((3, 2))
    for j in range(2):
        step = np.zeros(top.coef.shape[0])
        step[j] = math.sqrt(max(top.cov[j, j], 1e-24))
        jac[:, j] = (inertia_at(top.coef + step, lagged, settings.band)[0] - inertia) / step[j]
    curve_part = np.sqrt(np.einsum("aj,jk,ak->a", jac, top.cov[:2, :2], jac))
    tau_inertia = [inertia_at(f.coef, lag(max(tau + s * tau_se, 0.0)), settings.band)[0]
                   for s, f in zip((-1.0, 1.0), alt, strict=True)]
    tau_inertia_part = np.abs(tau_inertia[1] - tau_inertia[0]) / 2.0
    drag_inertia_part = np.abs(inertia_at(top.coef + drag_shift, lag(tau_d), settings.band)[0]
                               - inertia) if imu_only else np.zeros(3)
    lo, hi = settings.band
    mid = math.sqrt(lo * hi)
    low_half = inertia_at(top.coef, lagged, (lo, mid))
    high_half = inertia_at(top.coef, lagged, (mid, hi))
    yaw_rel = DEFAULT_YAW_TORQUE if curve.yaw_ratio is None or curve.yaw_ratio_se is None \
        else curve.yaw_ratio_se / curve.yaw_ratio
    explained = [ExplainedShare(("thrust c_1", "thrust c_2", "thrust at mean u",
                                 "dT/du at mean u", "time constant"),
                                "the curve explains", "the vertical force", top.share)]
    halves = []
    for a, name in enumerate(("I_xx", "I_yy", "I_zz")):
        if a == 2 and curve.yaw_ratio is None:
            numbers.append(("I_zz", float("nan"), "kg m^2", {}))
            undetermined.append(NO_YAW_RATIO)
            continue
        explained.append(ExplainedShare((name,), f"{name}: the torques explain",
                                        "the band-passed torque variance", float(share[a])))
        halves.append(BandHalves(name, (float(low_half[0][a]), float(low_half[1][a])),
                                 (float(high_half[0][a]), float(high_half[1][a])),
                                 (lo, mid, hi)))
        # roll and pitch torques rest on the rotor positions, yaw torque on the yaw ratio
        lever = ({"arm_length": abs(inertia[a]) * settings.arm_rel_se} if a < 2 else
                 {"yaw_torque_coefficient": abs(inertia[a]) * yaw_rel})
        parts = {"statistical": float(inertia_se[a]),
                 "mass": abs(inertia[a]) * settings.mass_rel_se, **lever,
                 "thrust_curve": float(curve_part[a]),
                 "time_constant": float(tau_inertia_part[a]),
                 **({"rotor_drag": float(drag_inertia_part[a])} if imu_only else {})}
        numbers.append((name, float(inertia[a]), "kg m^2", parts))
    evidence = VerdictEvidence(explained=tuple(explained), band_halves=tuple(halves),
                               undetermined=tuple(undetermined))
    estimates = [judge_estimate(*number, evidence, settings.thresholds) for number in numbers]
    naive, naive_share = _naive(mass, a_z, u, gyro, dt, positions, spin, stack)
    return KnownMassResult(tuple(estimates), top.share,
                           tuple(float(s) for s in share[:2 if curve.yaw_ratio is None else 3]),
                           naive, naive_share, mass, mass * settings.mass_rel_se,
                           settings.band, tuple(notes), mean_command=u_m)
