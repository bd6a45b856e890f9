"""How often the known-mass mode's error bars cover the truth: seeded flightgen flights
of a 0.5 kg quad (sines, 30 s at 100 Hz, sensor noise, no process noise), their thrust
and torques turned into per-rotor commands through a known curve, identified with the
mass known.

    python scripts/px4_known_mass_mc.py [FLIGHTS] [MOTOR_LAG_S] [em|imu]

MOTOR_LAG_S = 0 (default): aggressive sines, no effects in the truth. MOTOR_LAG_S > 0:
gentle sines (flightgen's controller does not hold aggressive ones with a lag) with a
first-order lag of that time constant on the wrench and rotor drag (0.1, 0.1, 0.2) N s/m.

Prints, per flight, each estimate's error against the truth in its total standard
errors and its verdict (the curve's thrust and slope at the flight's mean command u_m
against the true curve's there), then the share of |error| < 2 se and of trusted
estimates. With
``em``: the EM route too (``known_mass_em``), on the flight with its position removed
(the E-step sees velocity, attitude and rates), its thrust scale s against 1.
With ``imu``: the regression on the flight read as an ordinary log instead, its
velocity, attitude and position removed (accelerometer, gyro and motor commands only, as
``pinquad.io.imu_log`` reads a micro-SD log): no drag term, the same curve, time
constant and inertia.
The flight is built in pinquad's frames directly (the NED/FRD conversion is the readers'
and has its own tests)."""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np

from flightgen import QUAD_250, Effects, FlightSpec, Noise, generate
from pinquad.core.actuator_curve import ActuatorCurve
from pinquad.identification.known_mass import identify_known_mass
from pinquad.identification.known_mass_em import identify_known_mass_em
from pinquad.io.command_log import command_log

CURVE = (2.0, 8.0)
YAW_RATIO = 0.012


def rotors() -> tuple[np.ndarray, np.ndarray]:
    """QUAD_250's x layout (4, 2) [m] and spins."""
    h = QUAD_250.arm / math.sqrt(2.0)
    return np.array([[h, -h], [-h, -h], [-h, h], [h, h]]), np.array([1.0, -1.0, 1.0, -1.0])


def flight_commands(seed: int, lag: float):
    """A flightgen flight as a CommandLog (rows from 1 s on: the start-up transient
    dropped) and the truth (c_1, c_2, tau, I_xx, I_yy, I_zz)."""
    effects = Effects(motor_lag=lag, drag=(0.1, 0.1, 0.2)) if lag > 0 else Effects()
    spec = FlightSpec(duration=31.0, trajectory="sines", aggressive=lag == 0, log_rate=100,
                      vehicle=QUAD_250, seed=seed,
                      noise=Noise(thrust=0.0, torque=(0.0, 0.0, 0.0)), effects=effects)
    c = generate(spec).columns
    keep = c["t"] >= 1.0
    positions, spin = rotors()
    mix = np.vstack([np.ones(4), positions[:, 1], -positions[:, 0], YAW_RATIO * spin])
    wrench = np.column_stack([c["thrust"], c["torque_x"], c["torque_y"], c["torque_z"]])
    thrust = np.linalg.solve(mix, wrench[keep].T).T
    if thrust.min() <= 0.0:
        raise ValueError(f"seed {seed}: a rotor asked for negative thrust")
    c1, c2 = CURVE
    u = (-c1 + np.sqrt(c1 * c1 + 4.0 * c2 * thrust)) / (2.0 * c2)

    def cols(prefix: str, axes: str = "xyz") -> np.ndarray:
        return np.column_stack([c[f"{prefix}_{a}"] for a in axes])[keep]

    t_us = np.round(c["t"][keep] * 1e6)
    log = command_log(t_us, cols("vel"), cols("quat", "wxyz"), cols("gyro"), cols("acc"),
                      u, (0.0, 1.0), f"flightgen seed {seed}", position=cols("pos"))
    truth = (*CURVE, lag, *np.diag(QUAD_250.inertia_matrix))
    return log, truth


def _row(result, names, truth, covered, trusted) -> str:
    row = []
    for name, true in zip(names, truth, strict=True):
        est = next((e for e in result.estimates if e.name == name), None)
        if est is None:
            row.append(f"{name} -")
            continue
        z = (est.value - true) / est.stderr if est.stderr > 0 else math.inf
        covered[name] += abs(z) < 2.0
        trusted[name] += est.verdict == "trusted"
        rel = f"{(est.value / true - 1) * 100:+.1f} %" if true else f"{est.value:.4f}"
        why = f": {est.reasons[0][:90]}" if est.reasons else ""
        row.append(f"{name} {rel} {z:+.1f} se ({est.verdict}{why})")
    return "; ".join(row)


def imu_only(log):
    """The CommandLog with its velocity, attitude and position removed (NaN)."""
    nan = np.full_like(log.log.velocity, np.nan)
    return replace(log, log=replace(log.log, velocity=nan, euler=nan.copy(),
                                    position=nan.copy()))


def main(flights: int = 8, lag: float = 0.0, em: bool = False, imu: bool = False) -> None:
    positions, spin = rotors()
    curve = ActuatorCurve(command_range=(0.0, 1.0), yaw_ratio=YAW_RATIO,
                          yaw_ratio_se=0.05 * YAW_RATIO)
    names = ("thrust c_1", "thrust c_2", "thrust at mean u", "dT/du at mean u",
             "time constant", "I_xx", "I_yy", "I_zz")
    em_names = ("thrust scale s", "I_xx", "I_yy", "I_zz")
    covered = {n: 0 for n in names}
    trusted = {n: 0 for n in names}
    em_covered = {n: 0 for n in em_names}
    em_trusted = {n: 0 for n in em_names}
    print(f"{flights} flights, motor lag {lag} s{', IMU only' if imu else ''}; error / total "
          "se (verdict)")
    for seed in range(flights):
        log, truth = flight_commands(seed, lag)
        if imu:
            log = imu_only(log)
        result = identify_known_mass(log, QUAD_250.mass, positions, spin, curve)
        # the curve's thrust and slope at the fit's mean command u_m
        u_m = result.mean_command
        c1, c2 = CURVE
        truth = (c1, c2, c1 * u_m + c2 * u_m * u_m, c1 + 2.0 * c2 * u_m, *truth[2:])
        print(f"seed {seed}: " + _row(result, names, truth, covered, trusted))
        if em:
            blind = replace(log, log=replace(log.log, position=np.full_like(log.log.position,
                                                                            np.nan)))
            route = identify_known_mass_em(blind, QUAD_250.mass, positions, spin, result,
                                           curve)
            print(f"  EM ({route.seconds:.0f} s): " + _row(route, em_names, (1.0, *truth[5:]),
                                                           em_covered, em_trusted))
    print("\nwithin 2 total se: " + ", ".join(f"{n} {covered[n]}/{flights}" for n in names))
    print("trusted:           " + ", ".join(f"{n} {trusted[n]}/{flights}" for n in names))
    if em:
        print("EM within 2 total se: " + ", ".join(f"{n} {em_covered[n]}/{flights}"
                                                  for n in em_names))
        print("EM trusted:           " + ", ".join(f"{n} {em_trusted[n]}/{flights}"
                                                  for n in em_names))


if __name__ == "__main__":
    main(*(int(sys.argv[1]),) if len(sys.argv) > 1 else (),
         **({"lag": float(sys.argv[2])} if len(sys.argv) > 2 else {}),
         em=len(sys.argv) > 3 and sys.argv[3] == "em",
         imu=len(sys.argv) > 3 and sys.argv[3] == "imu")
