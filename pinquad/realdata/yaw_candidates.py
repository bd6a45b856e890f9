"""What the yaw torque model lacks on the measured flights: candidate effects, each fitted
on some flights and judged on others.

The yaw row of a measured flight is I_zz r' = tau_z, with r the gyro's yaw rate [rad/s]
and the modelled torque [N m]

    tau_z(t) = gamma kf sum_i s_i omega_i(t + delta)^2 + J_r sum_i s_i omega_i'(t + delta)
               - D r(t) + kappa gamma kf sum_i s_i omega_i^2 (omega_i / omega_ref - 1)
               + nu gamma kf sum_i s_i omega_i^2 (V(t) - V_mean)

(s_i the spin signs, omega_i the logged rotor speeds [rad/s], gamma the yaw torque ratio
[m], kf the thrust coefficient [N/(rad/s)^2], V the battery voltage [V]). Each candidate
(:data:`CANDIDATES`) frees some of J_r [kg m^2], delta [s] (a time offset between the
logged rotor speeds and the gyro: delta > 0 when the logged speed lags the rotor), D [N m
s] (rotor yaw damping), kappa [-] (a torque ratio rising with speed) and nu [1/V] (one
changing with the battery), lambda_x, lambda_y [-] (roll and pitch rotor torques tau_x,
tau_y leaking into yaw, as rotors with unequal torque ratios make them), the others held
fixed, and is judged by two numbers on each held-out flight, both on the signals
band-passed to :data:`BAND` or a band given (zero-phase Butterworth, order 2):

- the unexplained share of the yaw acceleration on held-out blocks: the flight cut into
  2 s blocks, the flight's own gain g (1 / I_zz) fitted by least squares of r' on tau_z
  on the even blocks and judged on the odd ones and the other way round,
  u = sum_odd (r' - g tau_z)^2 / sum_odd r'^2, the two halves averaged;
- the apparent yaw inertia |H(f)| = |S_{r' tau}(f) / S_{r' r'}(f)| (Welch, 2.56 s Hann
  segments) as band medians over :data:`GAIN_BANDS`, and their spread max / min (1 is
  flat: the torque model and the inertia agree at every frequency), with the phase of H
  (> 0: the modelled torque leads the acceleration).

The candidate's own parameters are fitted on the fit flights only (each flight with its
own gain): argmin of the mean unexplained share over whole flights (bounded
Nelder-Mead from the candidate's fixed values, inside :data:`DOMAIN`). A number chosen
by looking at the held-out flights would be a sensitivity, not a result; the split is
fixed in advance (:data:`FIT_FLIGHTS`, :data:`HELD_OUT_FLIGHTS`).

Signals come from the micro-SD log at its own rate (about 500 Hz), resampled to a 2 ms
grid by linear interpolation, over the longest stretch with every rotor above the
vehicle's flight speed, 1 s trimmed at either end; yaw acceleration and rotor
accelerations are central differences. The flights must have every rotor speed measured
(the seven clean brushed logs): a rotor rebuilt from its PWM carries no acceleration of
its own.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize, minimize_scalar
from scipy.signal import csd, sosfiltfilt, welch

from pinquad.core.filters import band_sos
from pinquad.io.sdlog import read_sdflight

Array = NDArray[np.float64]

DT = 0.002
"""Analysis grid step [s] (the logs' ~500 Hz rate)."""
BAND = (2.0, 12.0)
"""Band [Hz] of the unexplained share and of the candidates' fit."""
GAIN_BANDS = ((2.0, 3.0), (3.0, 5.0), (5.0, 8.0), (8.0, 12.0))
"""Bands [Hz] of the apparent yaw inertia."""
INERTIA_BAND = (3.0, 8.0)
"""Band [Hz] of each flight's yaw inertia I_zz = S_{r' tau} / S_{r' r'} (the band the
measured-flight M-step uses)."""
BLOCK_S = 2.0
"""Length [s] of the alternating blocks of the held-out share."""
TRIM_S = 1.0
"""Seconds cut at either end of the flying stretch (take-off and landing)."""
FIT_FLIGHTS = ("jana00", "jana02", "jana04", "jana10")
"""Flights the candidates' parameters are fitted on: a fast and a slow figure-8, a yaw
sweep, the circle."""
HELD_OUT_FLIGHTS = ("jana01", "jana03", "jana05")
"""Flights the candidates are judged on: a yaw sweep at 0.7 m, the figure-8 of the
second controller, a yaw sweep at 0.5 m."""
OMEGA_REF = 2000.0
"""Reference rotor speed [rad/s] of the speed-dependent torque ratio (about hover)."""


@dataclass(frozen=True)
class YawSignals:
    """One flight's yaw signals on the 2 ms grid (K samples).

    name: log name; acc (K,) [rad/s^2]: the gyro's yaw acceleration; rate (K,) [rad/s];
    drag (K,) [N m]: gamma kf sum_i s_i omega_i^2; rotor_acc (K,) [rad/s^2]: sum_i s_i
    omega_i'; speed (K,) [N m]: gamma kf sum_i s_i omega_i^2 (omega_i / OMEGA_REF - 1);
    volt (K,) [N m V]: drag x (V - mean V) (zero if the battery is not logged);
    mean_rpm [rev/min]: mean rotor speed; tilt_acc (K, 2) [rad/s^2] and tilt_torque (K, 2)
    [N m]: roll and pitch acceleration and rotor torque kf sum_i (y_i, -x_i) omega_i^2
    (X layout, motors at arm / sqrt 2 on x and y), the check of the time offset on axes
    without rotor inertia.
    """

    name: str
    acc: Array
    rate: Array
    drag: Array
    rotor_acc: Array
    speed: Array
    volt: Array
    mean_rpm: float
    tilt_acc: Array
    tilt_torque: Array

    @property
    def seconds(self) -> float:
        return self.acc.size * DT


X_LAYOUT = np.array([[1.0, -1.0], [-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]]) / math.sqrt(2.0)
"""(x, y) of M1..M4 in units of the arm (front-right, back-right, back-left, front-left)."""


def yaw_signals(path: Path, kf: float, yaw_ratio: float, spin: Sequence[float],
                flight_rpm: float, arm: float) -> YawSignals:
    """:class:`YawSignals` of a micro-SD log (``io.sdlog``) with thrust coefficient kf
    [N/(rad/s)^2], yaw ratio gamma [m], spin signs (4,) and arm [m] of an X-layout
    quadcopter. Raises ValueError without
    rotor speeds or a flying stretch of at least 7 s."""
    flight = read_sdflight(path)
    log = flight.log
    if log.rpm is None:
        raise ValueError(f"{path}: no rotor speeds (rpm.m1..m4); the yaw candidates need them")
    rpm = np.asarray(log.rpm, dtype=float)
    gyro = np.asarray(log.gyro, dtype=float)
    flying = np.all(rpm > flight_rpm, axis=1) & np.isfinite(gyro[:, 2])
    idx = np.flatnonzero(flying)
    if idx.size < 2:
        raise ValueError(f"{path}: no row with every rotor above {flight_rpm:g} rev/min")
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts, ends = np.r_[0, breaks + 1], np.r_[breaks, idx.size - 1]
    k = int(np.argmax(ends - starts))
    t = np.asarray(log.t, dtype=float)
    t0, t1 = t[idx[starts[k]]] + TRIM_S, t[idx[ends[k]]] - TRIM_S
    if t1 - t0 < 5.0:
        raise ValueError(f"{path}: longest flying stretch {t1 - t0 + 2 * TRIM_S:.1f} s; "
                         "expected at least 7 s")
    grid = np.arange(t0, t1, DT)
    omega = np.column_stack([np.interp(grid, t, rpm[:, i]) for i in range(rpm.shape[1])])
    omega *= 2.0 * math.pi / 60.0
    rate = np.interp(grid, t, gyro[:, 2])
    tilt_rate = np.column_stack([np.interp(grid, t, gyro[:, j]) for j in range(2)])
    thrust = kf * omega**2
    tilt_torque = arm * np.column_stack([thrust @ X_LAYOUT[:, 1], -thrust @ X_LAYOUT[:, 0]])
    s = np.asarray(spin, dtype=float)
    drag = yaw_ratio * kf * (omega**2 @ s)
    speed = yaw_ratio * kf * ((omega**2 * (omega / OMEGA_REF - 1.0)) @ s)
    volt = np.zeros_like(drag)
    if log.vbat is not None and np.isfinite(log.vbat).any():
        vb = np.asarray(log.vbat, dtype=float)
        ok = np.isfinite(vb)
        v = np.interp(grid, t[ok], vb[ok])
        volt = drag * (v - v.mean())
    return YawSignals(name=Path(path).name, acc=np.gradient(rate, DT), rate=rate, drag=drag,
                      rotor_acc=np.gradient(omega, DT, axis=0) @ s, speed=speed, volt=volt,
                      mean_rpm=float(np.mean(omega) * 60.0 / (2.0 * math.pi)),
                      tilt_acc=np.gradient(tilt_rate, DT, axis=0), tilt_torque=tilt_torque)


PARAMS = ("J_r", "delta", "D", "kappa", "nu", "lambda_x", "lambda_y")
"""The torque model's parameters (module docstring), in this order."""
SCALE = np.array([1e-8, 1e-3, 1e-7, 1.0, 1.0, 0.01, 0.01])
"""The optimiser's unit of each parameter (kg m^2, s, N m s, -, 1/V, -, -)."""
DOMAIN = ((0.0, 2e-7), (-0.02, 0.02), (0.0, 1e-5), (-1.0, 1.0), (-1.0, 1.0), (-0.2, 0.2),
          (-0.2, 0.2))
"""Physical domain of each parameter: J_r >= 0 and at most ten times any rotor of this
size; a time offset within +-20 ms (five log rows either way is already far beyond the
rpm deck's one-revolution average and the gyro's filters); damping D >= 0 (a torque
against the yaw rate) up to 1e-5 N m s (r = 1 rad/s then costs a third of the hover yaw
torque of one rotor); the torque ratio changing by at most its own value over
OMEGA_REF or per volt; the roll / pitch leak at most a fifth of those torques (rotors
whose torque ratios differ by tens of percent). Without these bounds the scale-free
objective (each flight's own gain) lets a term replace the drag torque altogether."""


@dataclass(frozen=True)
class Candidate:
    """One hypothesis about the yaw torque.

    name: short label; free: indices into :data:`PARAMS` fitted on the fit flights;
    fixed (7,): the values of the others (and the start of the free ones); predicts:
    what it does to the frequency response, in words."""

    name: str
    free: tuple[int, ...]
    fixed: tuple[float, ...]
    predicts: str


def _spectrum(x: Array) -> Array:
    """The spectrum :func:`_shift` rotates: rfft of x followed by its mirror image (so
    that the periodic extension has no step)."""
    return np.fft.rfft(np.r_[x, x[::-1]])


def _shift(x: Array, delay: float, spec: Array | None = None) -> Array:
    """x(t + delay) for a signal on the grid, by a phase ramp in the Fourier domain
    (``spec``: :func:`_spectrum` of x, if already computed)."""
    if delay == 0.0:
        return x
    n = x.size
    f = np.fft.rfftfreq(2 * n, DT)
    spec = _spectrum(x) if spec is None else spec
    return np.fft.irfft(spec * np.exp(2j * np.pi * f * delay), 2 * n)[:n]


@dataclass(frozen=True)
class BandPassed:
    """A flight's :class:`YawSignals` band-passed to :data:`BAND` (each K,), and the
    block label (0 / 1) of each sample; the filter's edges (one period of the lowest
    corner) are cut."""

    name: str
    acc: Array
    drag: Array
    rotor_acc: Array
    rate: Array
    speed: Array
    volt: Array
    block: NDArray[np.int64]
    raw: YawSignals
    drag_spec: Array
    rotor_acc_spec: Array
    tilt: Array

    def torque(self, p: Array) -> Array:
        """(K,) [N m] the band-passed modelled yaw torque at parameters p (7,)."""
        jr, delta, damp, kappa, nu, lx, ly = p
        drag, racc = self.drag, self.rotor_acc
        if delta:
            drag = _shift(drag, delta, self.drag_spec)
            racc = _shift(racc, delta, self.rotor_acc_spec)
        tau = drag + jr * racc
        if damp:
            tau = tau - damp * self.rate
        if kappa:
            tau = tau + kappa * self.speed
        if nu:
            tau = tau + nu * self.volt
        if lx or ly:
            tau = tau + lx * self.tilt[:, 0] + ly * self.tilt[:, 1]
        return tau


def band_passed(sig: YawSignals, band: tuple[float, float] = BAND) -> BandPassed:
    """:class:`BandPassed` of a flight, filtered to ``band`` [Hz] (filtering commutes with
    the time shift and the linear combinations of :meth:`BandPassed.torque`, so it is
    done once)."""
    sos = band_sos(band, 1.0 / DT)
    edge = int(round(1.0 / band[0] / DT))
    cut = slice(edge, sig.acc.size - edge)

    def bp(x: Array) -> Array:
        return sosfiltfilt(sos, x)[cut]

    n = sig.acc.size - 2 * edge
    block = ((np.arange(n) * DT) // BLOCK_S).astype(np.int64) % 2
    drag, racc = bp(sig.drag), bp(sig.rotor_acc)
    return BandPassed(name=sig.name, acc=bp(sig.acc), drag=drag, rotor_acc=racc,
                      rate=bp(sig.rate), speed=bp(sig.speed), volt=bp(sig.volt), block=block,
                      raw=sig, drag_spec=_spectrum(drag), rotor_acc_spec=_spectrum(racc),
                      tilt=np.column_stack([bp(sig.tilt_torque[:, j]) for j in range(2)]))


def unexplained(acc: Array, tau: Array) -> float:
    """min_g sum (acc - g tau)^2 / sum acc^2 [-] (the flight's own gain g = 1 / I_zz)."""
    g = float(tau @ acc) / float(tau @ tau)
    return float(np.sum((acc - g * tau) ** 2) / np.sum(acc**2))


def held_out_unexplained(bp: BandPassed, p: Array) -> float:
    """The unexplained share on held-out blocks: g fitted on the even 2 s blocks and
    judged on the odd ones, and the other way round, averaged."""
    tau = bp.torque(p)
    out = []
    for test in (0, 1):
        tr, te = bp.block != test, bp.block == test
        g = float(tau[tr] @ bp.acc[tr]) / float(tau[tr] @ tau[tr])
        out.append(float(np.sum((bp.acc[te] - g * tau[te]) ** 2) / np.sum(bp.acc[te] ** 2)))
    return float(np.mean(out))


@dataclass(frozen=True)
class Response:
    """Apparent yaw inertia of one flight under one candidate.

    gain (B,) [kg m^2] and phase (B,) [deg]: band medians of |H| and arg H over
    :data:`GAIN_BANDS`; inertia [kg m^2]: sum Re S_{r' tau} / sum S_{r' r'} over
    :data:`INERTIA_BAND` (the torque regressed on the acceleration: what the torque
    model does not have, if it moves the vehicle, pulls it low); inertia_reverse
    [kg m^2]: sum S_{tau tau} / sum Re S_{r' tau} there (the acceleration regressed on
    the torque: pulled high by the same). The two bracket I_zz when the leftover torque
    is uncorrelated with the modelled one."""

    gain: Array
    phase: Array
    inertia: float
    inertia_reverse: float

    @property
    def spread(self) -> float:
        """max / min of the band gains (1: flat)."""
        return float(np.max(self.gain) / np.min(self.gain))


def response(sig: YawSignals, p: Array, segment_s: float = 2.56) -> Response:
    """:class:`Response` of the modelled torque at p (7,) against the yaw acceleration,
    from the unfiltered grid signals (Welch spectra)."""
    bp = modelled_torque(sig, p)
    nper = int(round(segment_s / DT))
    f, s_at = csd(sig.acc, bp, fs=1.0 / DT, nperseg=nper)
    _, s_aa = welch(sig.acc, fs=1.0 / DT, nperseg=nper)
    h = s_at / s_aa
    gain = np.array([np.median(np.abs(h[(f >= lo) & (f <= hi)])) for lo, hi in GAIN_BANDS])
    phase = np.array([np.degrees(np.median(np.angle(h[(f >= lo) & (f <= hi)])))
                      for lo, hi in GAIN_BANDS])
    sel = (f >= INERTIA_BAND[0]) & (f <= INERTIA_BAND[1])
    _, s_tt = welch(bp, fs=1.0 / DT, nperseg=nper)
    inertia = float(np.sum(s_at[sel].real) / np.sum(s_aa[sel]))
    reverse = float(np.sum(s_tt[sel]) / np.sum(s_at[sel].real))
    return Response(gain=gain, phase=phase, inertia=inertia, inertia_reverse=reverse)


def modelled_torque(sig: YawSignals, p: Array) -> Array:
    """(K,) [N m] the modelled yaw torque at p (7,) on the unfiltered grid."""
    jr, delta, damp, kappa, nu, lx, ly = p
    drag, racc = _shift(sig.drag, delta), _shift(sig.rotor_acc, delta)
    return (drag + jr * racc - damp * sig.rate + kappa * sig.speed + nu * sig.volt
            + lx * sig.tilt_torque[:, 0] + ly * sig.tilt_torque[:, 1])


@dataclass(frozen=True)
class CandidateResult:
    """A candidate fitted on the fit flights and judged on every flight.

    candidate; params (7,): fitted (free) and fixed values; fit_share: the summed
    objective's mean unexplained share over the fit flights; held_out (name -> share on
    held-out blocks); responses (name -> :class:`Response`)."""

    candidate: Candidate
    params: Array
    fit_share: float
    held_out: dict[str, float]
    responses: dict[str, Response]


def fit_candidate(cand: Candidate, fit: Sequence[BandPassed]) -> tuple[Array, float]:
    """(params (5,), mean unexplained share over ``fit``) of ``cand``: its free parameters
    minimise the mean of each fit flight's unexplained share (own gain per flight)."""
    base = np.asarray(cand.fixed, dtype=float)

    def full(v: Array) -> Array:
        p = base.copy()
        p[list(cand.free)] = v * SCALE[list(cand.free)]
        return p

    def objective(v: Array) -> float:
        p = full(v)
        return float(np.mean([unexplained(b.acc, b.torque(p)) for b in fit]))

    if not cand.free:
        return base, objective(np.zeros(0))
    free = list(cand.free)
    v0 = base[free] / SCALE[free]
    bounds = [(DOMAIN[i][0] / SCALE[i], DOMAIN[i][1] / SCALE[i]) for i in free]
    # a simplex one unit wide in every free direction (the default steps from a zero
    # start are too small to see the objective change)
    simplex = np.vstack([v0] + [v0 + np.eye(len(free))[k] for k in range(len(free))])
    simplex = np.clip(simplex, [b[0] for b in bounds], [b[1] for b in bounds])
    res = minimize(objective, v0, method="Nelder-Mead", bounds=bounds,
                   options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 2000,
                            "initial_simplex": simplex})
    return full(res.x), float(res.fun)


def evaluate(cand: Candidate, fit: Sequence[BandPassed], judged: Sequence[BandPassed]
             ) -> CandidateResult:
    """Fit ``cand`` on ``fit`` and judge it on every flight of ``judged`` (held-out
    blocks and the apparent inertia)."""
    params, share = fit_candidate(cand, fit)
    return CandidateResult(
        candidate=cand, params=params, fit_share=share,
        held_out={b.name: held_out_unexplained(b, params) for b in judged},
        responses={b.name: response(b.raw, params) for b in judged})


@dataclass(frozen=True)
class RotorPart:
    """One turning part of a rotor: J = shape m r^2 [kg m^2].

    name; mass [kg] and mass_se; radius [m]; shape [-] and shape_se: the factor of m r^2
    (1 for a thin cylindrical shell, 1/3 for a uniform blade from the axis); source: where
    the numbers come from."""

    name: str
    mass: float
    mass_se: float
    radius: float
    shape: float
    shape_se: float
    source: str

    @property
    def inertia(self) -> float:
        return self.shape * self.mass * self.radius**2

    @property
    def inertia_se(self) -> float:
        """Relative errors of mass and shape added in quadrature (the radius is known)."""
        return self.inertia * math.hypot(self.mass_se / self.mass, self.shape_se / self.shape)


def rotor_parts(propeller_radius: float) -> tuple[RotorPart, ...]:
    """The rotor's turning parts, the propeller of radius ``propeller_radius`` [m] (the
    vehicle file's ``[aero] rotor_radius``), with assumed masses (no weighing of these
    parts exists in the data set): the geometry fixes J_r only to about 40 %."""
    return (
        RotorPart("propeller", 0.30e-3, 0.10e-3, propeller_radius, 0.15, 0.05,
                  f"radius: the vehicle file's rotor_radius ({2e3 * propeller_radius:.0f} mm "
                  "propeller); mass 0.2-0.4 g, not weighed (the data set does not give it); "
                  "shape: a uniform blade from the axis gives 1/3, a chord narrowing to the "
                  "tip and the hub's mass near the axis lower it to 0.1-0.2"),
        RotorPart("motor rotor", 0.8e-3, 0.3e-3, 0.0030, 1.0, 0.0,
                  "7 x 16 mm coreless motor: the winding cup, shaft and commutator turn, the "
                  "magnet inside stands; cup radius about 3 mm, its mass 0.5-1.1 g of the "
                  "motor's (not weighed); a thin shell"),
    )


def geometric_rotor_inertia(parts: Sequence[RotorPart]) -> tuple[float, float]:
    """(J_r, its standard uncertainty) [kg m^2]: the parts' inertias summed, their
    uncertainties added in quadrature."""
    return (float(sum(p.inertia for p in parts)),
            float(math.sqrt(sum(p.inertia_se**2 for p in parts))))


def candidates(tilt_delta: float, geometry_jr: float) -> tuple[Candidate, ...]:
    """The hypotheses judged by :func:`evaluate` (module docstring), each with what it
    predicts for the frequency response; tilt_delta [s]: the time offset measured on the
    roll and pitch axes of the fit flights (:func:`tilt_offset`)."""
    zero = (0.0,) * 7
    geo = (geometry_jr,) + (0.0,) * 6
    geo_tilt = (geometry_jr, tilt_delta) + (0.0,) * 5
    return (
        Candidate("drag torque only", (), zero,
                  "|H| falls with f and the torque lags: a derivative term is missing"),
        Candidate("J_r from geometry (not fitted)", (), geo,
                  "adds a torque 90 deg ahead of the drag torque, growing with f"),
        Candidate("J_r fitted", (0,), geo, "as above, J_r chosen by the fit flights"),
        Candidate("J_r 22.4e-9 (realdata's pool, sensitivity)", (), (22.4e-9,) + (0.0,) * 6,
                  "the J_r python -m pinquad.realdata pools over all seven flights, the "
                  "held-out ones included: a sensitivity, not a held-out result"),
        Candidate("J_r 5e-8 (picked by eye, sensitivity)", (), (5e-8,) + (0.0,) * 6,
                  "the J_r chosen by looking at the yaw flights: a sensitivity"),
        Candidate("J_r + rpm time offset", (0, 1), geo,
                  "a pure delay: phase changes by 360 f delta deg, |H| barely"),
        Candidate("geometry J_r + roll/pitch offset", (), geo_tilt,
                  "nothing fitted on yaw: J_r from the rotor, the offset from roll and pitch"),
        Candidate("J_r fitted + roll/pitch offset", (0,), geo_tilt,
                  "the offset from roll and pitch, J_r chosen by the fit flights"),
        Candidate("J_r + yaw damping", (0, 2), geo,
                  "H = I - j D / (2 pi f): |H| above I at low f, torque lagging there"),
        Candidate("J_r + ratio with speed", (0, 3), geo,
                  "rescales the drag torque with speed: frequency-flat unless the speed "
                  "and the yaw motion are correlated"),
        Candidate("J_r + ratio with battery", (0, 4), geo,
                  "rescales the drag torque with the battery voltage: slow, nearly "
                  "frequency-flat"),
        Candidate("J_r + offset + damping", (0, 1, 2), geo, "the two above together"),
        Candidate("J_r + roll/pitch leak", (0, 5, 6), geo,
                  "rotors whose torque ratios differ: roll and pitch commands leak into "
                  "yaw, with the roll / pitch torques' own frequency content"),
    )


def tilt_offset(flights: Sequence[YawSignals], band: tuple[float, float] = BAND
                ) -> tuple[float, Array]:
    """(delta [s], per-flight-and-axis unexplained share (L, 2) at it): the one time offset
    between the rotor speeds and the gyro that best explains the band-passed roll and
    pitch accelerations of ``flights`` by their rotor torques shifted by delta (each
    flight and axis with its own gain). Roll and pitch carry no rotor-inertia term, so
    this offset is measured without the yaw axis at all."""
    sos = band_sos(band, 1.0 / DT)
    edge = int(round(1.0 / band[0] / DT))
    parts = []
    for sig in flights:
        cut = slice(edge, sig.acc.size - edge)
        for j in range(2):
            acc = sosfiltfilt(sos, sig.tilt_acc[:, j])[cut]
            tau = sosfiltfilt(sos, sig.tilt_torque[:, j])[cut]
            parts.append((acc, tau, _spectrum(tau)))

    def shares(delta: float) -> Array:
        return np.array([unexplained(a, _shift(t, delta, sp)) for a, t, sp in parts])

    res = minimize_scalar(lambda d: float(np.mean(shares(d))), bounds=DOMAIN[1],
                          method="bounded", options={"xatol": 1e-5})
    return float(res.x), shares(float(res.x)).reshape(len(flights), 2)


@dataclass(frozen=True)
class YawStudy:
    """The candidate table.

    fit, held_out: the flights of each role; band [Hz]; tilt_delta [s] and tilt_shares (L, 2): the
    roll / pitch time offset fitted on the fit flights and each fit flight's roll and
    pitch unexplained share at it; tilt_held_out [s]: the same offset fitted on the
    held-out flights alone (a check, used nowhere); results: one per candidate."""

    fit: tuple[str, ...]
    held_out: tuple[str, ...]
    band: tuple[float, float]
    tilt_delta: float
    tilt_shares: Array
    tilt_held_out: float
    results: tuple[CandidateResult, ...]


def yaw_study(signals: dict[str, YawSignals], geometry_jr: float,
              fit: Sequence[str] = FIT_FLIGHTS, held_out: Sequence[str] = HELD_OUT_FLIGHTS,
              band: tuple[float, float] = BAND) -> YawStudy:
    """Fit every candidate on the ``fit`` flights of ``signals`` and judge it on all of
    them (the held-out ones are those the table reads), everything band-passed to
    ``band`` [Hz]; geometry_jr [kg m^2]: the rotor inertia from the rotor's geometry
    (:func:`geometric_rotor_inertia`). Raises ValueError if a flight is in both roles or
    missing."""
    if set(fit) & set(held_out):
        raise ValueError(f"flights both fitted on and held out: {sorted(set(fit) & set(held_out))}")
    missing = [n for n in (*fit, *held_out) if n not in signals]
    if missing:
        raise ValueError(f"no signals for {', '.join(missing)}")
    bps = {n: band_passed(signals[n], band) for n in (*fit, *held_out)}
    delta, shares = tilt_offset([signals[n] for n in fit], band)
    check, _ = tilt_offset([signals[n] for n in held_out], band)
    judged = [bps[n] for n in (*held_out, *fit)]
    results = tuple(evaluate(c, [bps[n] for n in fit], judged) for c in candidates(delta, geometry_jr))
    return YawStudy(fit=tuple(fit), held_out=tuple(held_out), band=band, tilt_delta=delta,
                    tilt_shares=shares, tilt_held_out=check, results=results)
