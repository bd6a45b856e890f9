"""The yaw torque candidates (pinquad.yaw): the candidate fit recovers a rotor inertia and
a time offset put into a synthetic flight, the roll / pitch offset is measured without the
yaw axis, the rotor inertia from geometry explains most of a held-out yaw sweep, and the
command refuses a flight in both roles (the data must be present: fails, not skips)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pinquad.cli.yaw import main
from pinquad.core.vehicle_file import load_vehicle
from pinquad.realdata.yaw_candidates import (
    DT,
    Candidate,
    YawSignals,
    band_passed,
    fit_candidate,
    geometric_rotor_inertia,
    held_out_unexplained,
    rotor_parts,
    tilt_offset,
    yaw_signals,
)

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "crazyflie"


def _synthetic(seed: int, jr: float, delta: float, inertia: float = 29e-6,
               noise: float = 0.02) -> YawSignals:
    """40 s of random rotor speeds (4 rotors around 1800 rad/s) and the yaw acceleration
    they make with rotor inertia jr [kg m^2], the logged speeds lagging the rotors by
    -delta [s] (the acceleration is computed from the speeds at t + delta), plus white
    noise of ``noise`` x the acceleration's rms."""
    rng = np.random.default_rng(seed)
    n = int(40.0 / DT)
    kernel = np.hanning(41) / np.hanning(41).sum()
    omega = 1800.0 + np.column_stack([200.0 * np.convolve(rng.standard_normal(n), kernel,
                                                           mode="same") for _ in range(4)])
    spin = np.array([-1.0, 1.0, -1.0, 1.0])
    drag = 0.006 * 2e-8 * (omega**2 @ spin)
    racc = np.gradient(omega, DT, axis=0) @ spin
    t = np.arange(n) * DT
    true_drag = np.interp(t + delta, t, drag)
    true_racc = np.interp(t + delta, t, racc)
    acc = (true_drag + jr * true_racc) / inertia
    acc = acc + noise * np.std(acc) * rng.standard_normal(n)
    tilt = np.column_stack([np.interp(t + delta, t, drag), np.interp(t + delta, t, -drag)])
    return YawSignals(name=f"synthetic{seed}", acc=acc, rate=np.cumsum(acc) * DT, drag=drag,
                      rotor_acc=racc, speed=np.zeros(n), volt=np.zeros(n), mean_rpm=17000.0,
                      tilt_acc=tilt / 16e-6, tilt_torque=np.column_stack([drag, -drag]))


def test_fit_recovers_rotor_inertia_and_time_offset():
    fit = [band_passed(_synthetic(s, 3e-8, -0.004)) for s in (1, 2)]
    held = band_passed(_synthetic(3, 3e-8, -0.004))
    cand = Candidate("J_r + offset", (0, 1), (2e-8,) + (0.0,) * 6, "")
    params, share = fit_candidate(cand, fit)
    assert abs(params[0] - 3e-8) < 0.15e-8, params
    assert abs(params[1] + 0.004) < 0.0005, params
    assert share < 0.01
    assert held_out_unexplained(held, params) < 0.01
    drag_only = np.zeros(7)
    assert held_out_unexplained(held, drag_only) > 0.2


def test_tilt_offset_is_measured_on_roll_and_pitch():
    delta, shares = tilt_offset([_synthetic(s, 0.0, -0.006, noise=0.0) for s in (4, 5)])
    assert abs(delta + 0.006) < 0.0003, delta
    assert shares.shape == (2, 2) and np.all(shares < 0.01)


def test_geometry_rotor_inertia_explains_a_held_out_yaw_sweep():
    assert (DATA / "imrc_brushed").is_dir(), f"the Crazyflie data are missing: {DATA}"
    spec = load_vehicle("crazyflie21")
    sig = band_passed(yaw_signals(DATA / "imrc_brushed" / "jana05", 2.0043e-8, 0.006,
                                  [-1, 1, -1, 1], 10000.0, spec.arm))
    jr = geometric_rotor_inertia(rotor_parts(spec.aero.rotor_radius))[0]
    without = held_out_unexplained(sig, np.zeros(7))
    with_jr = held_out_unexplained(sig, np.array([jr] + [0.0] * 6))
    assert without > 0.8 and with_jr < 0.3, (without, with_jr)


def test_command_refuses_a_flight_in_both_roles_and_a_missing_log(capsys):
    assert (DATA / "imrc_brushed").is_dir(), f"the Crazyflie data are missing: {DATA}"
    assert main(["--data", str(DATA), "--fit", "jana00", "--held-out", "jana00"]) == 2
    assert "both fitted on and held out: jana00" in capsys.readouterr().err
    assert main(["--data", str(DATA), "--fit", "nosuchlog", "--held-out", "jana01"]) == 2
    assert "nosuchlog" in capsys.readouterr().err


def test_tilt_offset_of_a_brushless_log(capsys):
    log = DATA / "imrc_brushless" / "eckart00"
    assert log.exists(), f"the Crazyflie data are missing: {log}"
    assert main(["--tilt-offset", str(log)]) == 0
    row = capsys.readouterr().out.splitlines()[1].split("|")
    assert row[0].strip() == "eckart00" and -9.0 < float(row[2]) < -3.0, row
