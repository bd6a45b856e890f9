"""Apparent inertia against frequency on a measured flight: a model-free look at how far
the rigid-body torque model holds, band by band.

For each body axis j the rotor torque tau_j [N m] (measured rotor speeds through the
actuator model, plus J_r sum_i spin_i omega_i' on the yaw axis) is compared with the
gyro's angular acceleration a_j = d(gyro_j)/dt [rad/s^2] through Welch spectra:

    H_j(f) = S_{a tau}(f) / S_{a a}(f)   [kg m^2],
    gamma_j^2(f) = |S_{a tau}|^2 / (S_{a a} S_{tau tau})   (coherence, 0..1).

Where I_jj a_j = tau_j holds and the torque is the only thing that moves the vehicle,
|H_j| = I_jj at every frequency with zero phase. Two things make |H_j| change with f: a
dynamic element the torque model misses, or, in closed loop, torques the model does not
have at all. With a disturbance d, a = (tau + d) / I, while the controller makes
tau = -C(s) x (x the attitude) from the same motion; in a band where d, not the
reference or the sensor noise the controller reacts to, drives the motion, tau follows
a through the controller and

    H(j Omega) -> -C(j Omega) / (j Omega)^2,

the controller's inverse, not the inertia: a gain falling with frequency, the torque
leading (a PD law gives 0 to 90 deg), and a coherence near 1 (tau is a deterministic
function of the motion). ``--simulate`` shows it on the simulator: the same closed loop
with the simulator's torque noise gives a flat |H| = I, with ten times that noise |H|
falls several-fold over 2-16 Hz, while direct EM on the same flights (whose E-step
models the disturbance) stays near the true inertia. :func:`unexplained_torque`
measures how large the missing torques are against the rotor torque, for measured and
simulated flights alike. Either way the band the inertia M-step uses then decides the
identified inertia. The gyroscopic term (omega x I omega) and the air-speed moments are
left out: it is a diagnostic, not an estimator. Phase > 0: the modelled torque leads the
acceleration (the gyro's filtering delays it; the 10 ms grid puts the torque bin half a
step late, which is undone here by centring both on the grid times).

``python -m pinquad.response [LOG ...]`` (``pinquad.cli.response``) prints |H| and the
coherence per axis at a few frequencies for each log, and draws |H_j(f)| of every log in
one figure (``pinquad.report.response``); ``python -m pinquad.response --simulate 1 10 30``
does the same for simulated closed-loop flights with the torque noise multiplied by each
factor, and prints what EM identifies on each.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.signal import csd, sosfiltfilt, welch

from pinquad.core.filters import band_sos
from pinquad.core.params import CRAZYFLIE21, PAPER_INITIAL_MASS
from pinquad.identification.identify import identify
from pinquad.models.sources import observations
from pinquad.realdata.identify import identify_real
from pinquad.realdata.observations import RealObservations, simulated_observations
from pinquad.realdata.raw import simulated_crazyflie
from pinquad.sim.simulator import flight_log

Array = NDArray[np.float64]

UNEXPLAINED_BAND = (2.0, 16.0)
"""Band [Hz] of :func:`unexplained_torque`."""


@dataclass(frozen=True)
class ApparentInertia:
    """The torque / angular-acceleration frequency response of one flight.

    name: log name; freq (F,) [Hz]; gain (F, 3) [kg m^2]: |H_j(f)|; phase (F, 3) [rad]:
    arg H_j(f); coherence (F, 3) [-]; rotor_inertia [kg m^2]: the J_r added to the yaw
    torque; seconds: length of the analysed span [s]; unexplained (3,) [-]:
    :func:`unexplained_torque` against a reference inertia (NaN: none given).
    """

    name: str
    freq: Array
    gain: Array
    phase: Array
    coherence: Array
    rotor_inertia: float
    seconds: float
    unexplained: Array = field(default_factory=lambda: np.full(3, np.nan))

    def at(self, hz: float) -> tuple[Array, Array, Array]:
        """(gain (3,), phase (3,), coherence (3,)) at the frequency bin nearest ``hz``."""
        k = int(np.argmin(np.abs(self.freq - hz)))
        return self.gain[k], self.phase[k], self.coherence[k]

    def band_gain(self, lo: float, hi: float) -> Array:
        """(3,) [kg m^2] median of |H_j| over the bins in [lo, hi] Hz."""
        sel = (self.freq >= lo) & (self.freq <= hi)
        return np.median(self.gain[sel], axis=0)


def _used_span(exclude: NDArray[np.bool_]) -> slice:
    """Grid steps from the first to the last used transition (take-off and landing cut)."""
    used = np.flatnonzero(~exclude[:-1])
    if used.size < 2:
        raise ValueError("fewer than two used transitions: nothing to analyse")
    return slice(int(used[0]), int(used[-1]) + 2)


def _span_signals(t: Array, dt: float, gyro: Array, torque: Array,
                  exclude: NDArray[np.bool_]) -> tuple[Array, Array, Array]:
    """(t (K,), a (K, 3) [rad/s^2], tau (K, 3) [N m]) over the used span: the gyro's
    central-difference angular acceleration (gaps interpolated) and the torque bins
    [t_k, t_k + dt) centred on t_k as (tau_{k-1} + tau_k) / 2."""
    span = _used_span(exclude)
    t = np.asarray(t, dtype=float)[span]
    gyro = np.asarray(gyro, dtype=float)[span]
    seen = np.isfinite(gyro).all(axis=1)
    if seen.sum() < 2:
        raise ValueError("no gyro samples in the used span")
    gyro = np.column_stack([np.interp(t, t[seen], gyro[seen, j]) for j in range(3)])
    acc = np.gradient(gyro, dt, axis=0)
    torque = np.asarray(torque, dtype=float)
    centred = torque.copy()
    centred[1:] = 0.5 * (torque[1:] + torque[:-1])
    return t, acc, centred[span]


def unexplained_torque(acc: Array, tau: Array, inertia: Array, dt: float,
                       band: tuple[float, float] = UNEXPLAINED_BAND) -> Array:
    """(3,) [-] per axis, the torque the model leaves over relative to the torque it has,
    both band-passed to ``band`` [Hz] (zero-phase Butterworth, order 2):

        u_j = rms(BP[I_jj a_j - tau_j]) / rms(BP[tau_j])

    with I the reference inertia (3,) [kg m^2]. It measures how large the torques the
    model does not have (disturbances: air, rotor aerodynamics, anything unmodelled) are
    against the rotor torque: in closed loop the controller answers them, and where they
    dominate |H| follows the controller rather than the inertia (module docstring)."""
    sos = band_sos(band, 1.0 / dt)
    left = sosfiltfilt(sos, np.asarray(inertia) * acc - tau, axis=0)
    have = sosfiltfilt(sos, tau, axis=0)
    return np.sqrt(np.mean(left**2, axis=0) / np.mean(have**2, axis=0))


def response_of_signals(name: str, t: Array, dt: float, gyro: Array, torque: Array,
                        exclude: NDArray[np.bool_], rotor_inertia: float = 0.0,
                        segment_s: float = 2.56, reference: Array | None = None
                        ) -> ApparentInertia:
    """:class:`ApparentInertia` of grid signals: t (N,) [s], gyro (N, 3) [rad/s] sampled
    at t_k, torque (N, 3) [N m] binned over [t_k, t_k + dt), exclude (N,) the transitions
    outside flight. Spectra: Welch, Hann segments of ``segment_s`` seconds, half overlap,
    over the span between the first and the last used transition. reference (3,)
    [kg m^2]: the inertia :func:`unexplained_torque` is measured against (NaN if None)."""
    t, acc, tau = _span_signals(t, dt, gyro, torque, exclude)
    fs = 1.0 / dt
    nper = min(int(round(segment_s * fs)), t.size)
    gain, phase, coh = [], [], []
    freq = np.zeros(0)
    for j in range(3):
        freq, s_at = csd(acc[:, j], tau[:, j], fs=fs, nperseg=nper)
        _, s_aa = welch(acc[:, j], fs=fs, nperseg=nper)
        _, s_tt = welch(tau[:, j], fs=fs, nperseg=nper)
        with np.errstate(divide="ignore", invalid="ignore"):
            h = s_at / s_aa
            coh.append(np.abs(s_at) ** 2 / (s_aa * s_tt))
        gain.append(np.abs(h))
        phase.append(np.angle(h))
    left = (np.full(3, np.nan) if reference is None
            else unexplained_torque(acc, tau, reference, dt))
    return ApparentInertia(name=name, freq=freq, gain=np.column_stack(gain),
                           phase=np.column_stack(phase), coherence=np.column_stack(coh),
                           rotor_inertia=float(rotor_inertia), seconds=float(t[-1] - t[0]),
                           unexplained=left)


def apparent_inertia(real: RealObservations, name: str = "", rotor_inertia: float = 0.0,
                     segment_s: float = 2.56, reference: Array | None = None
                     ) -> ApparentInertia:
    """:class:`ApparentInertia` of a measured flight (``realdata.RealObservations``): the
    rotor torques (plus J_r sum_i spin_i omega_i' on yaw) against the gyro
    (:func:`response_of_signals`)."""
    torque = np.asarray(real.obs.inputs, dtype=float)[:, 1:4].copy()
    if rotor_inertia and real.rotor_acc is not None:
        torque[:, 2] += rotor_inertia * real.rotor_acc
    try:
        return response_of_signals(name or Path(real.source).name, real.obs.t, real.obs.dt,
                                   np.asarray(real.log.gyro, dtype=float), torque,
                                   real.obs.exclude, rotor_inertia, segment_s, reference)
    except ValueError as exc:
        raise ValueError(f"{real.source}: {exc}") from None


@dataclass(frozen=True)
class SimulatedResponse:
    """The frequency response of a simulated closed-loop flight and what direct EM makes
    of the same flight.

    factor: torque disturbance as a multiple of the simulator's process noise (std);
    seed: the flight's generator seed; sensor: A, B or C; response: the ApparentInertia
    of the logged commanded torque against the logged gyro, reference = the true
    inertia; em_inertia (3,) [kg m^2]: EM's diagonal inertia (regressor M-step);
    band_inertia (3,) [kg m^2]: what the measured-flight pipeline (``realdata``: rotor
    speeds from the commanded wrench, ``identify_real`` with its band-passed
    inertia M-step and nuisance moments, no rotor inertia) finds on the same flight
    (NaN without pose samples, i.e. sensors A and C); truth (3,) [kg m^2]; crashed: the
    flight crashed.
    """

    factor: float
    seed: int
    sensor: str
    response: ApparentInertia
    em_inertia: Array
    band_inertia: Array
    band: tuple[float, float]
    truth: Array
    crashed: bool

    @property
    def em_rel_error(self) -> Array:
        """(3,) [-] EM inertia / truth - 1."""
        return self.em_inertia / self.truth - 1.0

    @property
    def band_rel_error(self) -> Array:
        """(3,) [-] the measured-flight pipeline's inertia / truth - 1."""
        return self.band_inertia / self.truth - 1.0


def simulated_response(factor: float, seed: int = 0, sensor: str = "B",
                       max_iterations: int = 200, band: tuple[float, float] = (3.0, 8.0)
                       ) -> SimulatedResponse:
    """Fly the simulated Crazyflie 2.1 (the offline command's scenario, the paper's scaled
    by 0.3, closed loop) with the torque process noise multiplied by ``factor``, compute
    its apparent inertia from the log's commanded torques and gyro, and identify the same
    log with EM (EKF + RTS E-step, regressor M-step, the offline command's start) and,
    with sensor B, with the measured-flight pipeline (``realdata.identify_real`` on
    ``realdata.raw_from_simulated``, started at the truth)."""
    vehicle = CRAZYFLIE21
    flight = simulated_crazyflie(factor, seed, sensor)
    truth = np.diag(vehicle.inertia).copy()
    response = response_of_signals(f"sim x{factor:g}", flight.t, float(flight.t[1] - flight.t[0]),
                                   flight.onboard.gyro, flight.inputs[:, 1:4], flight.contact,
                                   reference=truth)
    obs = observations(flight_log(flight), sensor)
    ident, _ = identify(obs, vehicle.mass * PAPER_INITIAL_MASS / 0.18, vehicle.inertia * 0.5,
                        vehicle.gravity, "rts", "regressor", max_iterations, False)
    band_inertia = np.full(3, np.nan)
    if sensor == "B":
        measured = identify_real(simulated_observations(flight), vehicle.mass,
                                 vehicle.inertia, information=False,
                                 fit_rotor_inertia=False, band=band)
        band_inertia = np.diag(measured.inertia).copy()
    return SimulatedResponse(factor=float(factor), seed=seed, sensor=sensor, response=response,
                             em_inertia=np.diag(ident.inertia).copy(), band_inertia=band_inertia, band=band,
                             truth=truth, crashed=bool(flight.crashed))
