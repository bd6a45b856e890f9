"""Actuator model: thrust-stand fit, X mixer, and the yaw-torque sign from the yaw flights."""

from __future__ import annotations

import math
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.params import CRAZYFLIE21
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.sdlog import read_sdlog
from pinquad.vehicle.actuators import (
    KF_CRAZYFLIE,
    SPIN_CRAZYFLIE,
    ActuatorModel,
    YawFit,
    fit_thrust_stand,
    fit_yaw,
    motor_positions,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "crazyflie"
STAND = DATA / "thrust_stand"
FLIGHTS = DATA / "imrc_brushed"
YAW_FLIGHTS = ("jana01", "jana04", "jana05")


def stand_files() -> list[Path]:
    assert STAND.is_dir(), f"the thrust-stand data are missing: expected {STAND}"
    files = sorted(STAND.glob("*.csv"))
    assert len(files) == 2, f"expected the two Bitcraze thrust-stand CSVs in {STAND}"
    return files


@cache
def flight(name: str) -> FlightLog:
    assert FLIGHTS.is_dir(), f"the Crazyflie flight data are missing: expected {FLIGHTS}"
    return read_sdlog(FLIGHTS / name)


@cache
def yaw_fit(name: str) -> YawFit:
    return fit_yaw(flight(name), ActuatorModel())


# ----------------------------------------------------------------------------- thrust stand

def test_kf_from_each_stand_run():
    for path in stand_files():
        fit = fit_thrust_stand(path)
        assert 1.8e-8 < fit.kf < 2.2e-8, (path.name, fit.kf)
        assert 0 < fit.kf_se < 0.02 * fit.kf
        assert fit.residual_rms < 0.01  # N, i.e. about 1 gram-force
        assert fit.n_used > 0.9 * fit.n_rows
        assert 10 <= fit.lag_rows <= 40, "the load cell trails the rotor speeds"
        assert any("0 rpm" in note for note in fit.excluded)


def test_kf_pooled_is_about_2e8():
    pooled = fit_thrust_stand(stand_files())
    assert pooled.kf == pytest.approx(2.0e-8, rel=0.05)
    assert KF_CRAZYFLIE == pytest.approx(pooled.kf, rel=0.01)
    assert pooled.n_rows == sum(fit_thrust_stand(p).n_rows for p in stand_files())
    assert 18000 < pooled.hover_rpm() < 21000


def test_stand_fit_recovers_synthetic_truth(tmp_path):
    rng = np.random.default_rng(3)
    n, kf, lag, tare_g = 1200, 2.3e-8, 12, -0.8
    level = np.repeat(np.linspace(5000, 22000, 30), n // 30)
    rpm = level[:, None] * (1 + 0.01 * rng.standard_normal((n, 4)))
    rpm[:40] = 0.0  # stopped at the start: the load-cell zero
    omega2 = ((rpm * 2 * np.pi / 60) ** 2).sum(axis=1)
    weight = np.full(n, tare_g) + 0.02 * rng.standard_normal(n)
    weight[lag:] += kf * omega2[:-lag] / 9.81e-3
    weight[500] += 20.0  # a knock on the stand
    lines = ["weight[g],pwm,vbat[V],rpm1,rpm2,rpm3,rpm4,v[V],i[A],p[W]"]
    for k in range(n):
        w = "nan" if k == 700 else f"{weight[k]:.4f}"
        lines.append(f"{w},0,3.9," + ",".join(f"{v:.0f}" for v in rpm[k]) + ",3.9,0.2,0.7")
    path = tmp_path / "stand.csv"
    path.write_text("\n".join(lines) + "\n")
    fit = fit_thrust_stand(path)
    assert fit.kf == pytest.approx(kf, rel=0.005)
    assert fit.lag_rows == lag
    assert fit.tare / 9.81e-3 == pytest.approx(tare_g, abs=0.02)
    assert any("missing" in e for e in fit.excluded)
    assert any("robust standard deviations" in e for e in fit.excluded)


def test_cli_prints_fits_and_fails_on_empty_dir(tmp_path):
    stand_files()
    ok = subprocess.run([sys.executable, "-m", "pinquad.actuators", "--data", str(STAND)],
                        capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert ok.returncode == 0, ok.stderr
    # two runs and the pooled fit, then the vehicle file's [actuators] section
    assert ok.stdout.count("  kf = ") == 3 and "pooled" in ok.stdout
    section = ok.stdout.split("[actuators]")[1]
    assert section.count("kf = ") == 1 and "kf_se = " in section
    bad = subprocess.run([sys.executable, "-m", "pinquad.actuators", "--data", str(tmp_path)],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert bad.returncode != 0
    assert "no thrust-stand CSV" in bad.stderr and str(tmp_path) in bad.stderr
    assert "Traceback" not in bad.stderr


# ----------------------------------------------------------------------------- mixer

def test_mixer_geometry_and_signs():
    model = ActuatorModel(kf=2e-8, yaw_ratio=0.006)
    xy = motor_positions(0.046)
    np.testing.assert_allclose(np.abs(xy), 0.0325, atol=3e-5)
    rpm = np.zeros((4, 4))
    rpm[np.arange(4), np.arange(4)] = 20000.0  # one motor at a time
    thrust, torque = model.wrench(rpm)
    t1 = 2e-8 * (20000 * 2 * np.pi / 60) ** 2
    np.testing.assert_allclose(thrust, t1)
    h = 0.046 / math.sqrt(2)
    # Lifting a right-hand motor (y < 0) gives a negative roll torque; lifting a front
    # motor (x > 0) a negative pitch torque (nose up, body y points left).
    np.testing.assert_allclose(torque[:, 0], t1 * h * np.array([-1, -1, 1, 1]))
    np.testing.assert_allclose(torque[:, 1], t1 * h * np.array([-1, 1, 1, -1]))
    np.testing.assert_allclose(torque[:, 2], t1 * 0.006 * np.array(SPIN_CRAZYFLIE))
    _, balanced = model.wrench(np.full((1, 4), 19000.0))
    np.testing.assert_allclose(balanced, 0.0, atol=1e-12)
    assert np.linalg.matrix_rank(model.allocation()) == 4
    with pytest.raises(ValueError):
        ActuatorModel(spin=(1.0, 1.0, -1.0, -1.0))


def test_mixer_on_hover_gives_weight():
    log = flight("jana10")  # circle at 0.5 m, clean
    fit = fit_thrust_stand(stand_files())
    thrust, torque = ActuatorModel(kf=fit.kf).wrench(log.rpm)
    weight = CRAZYFLIE21.mass * 9.81
    assert float(np.mean(thrust)) == pytest.approx(weight, rel=0.15)
    # On average the controller holds roll and pitch torques near zero.
    assert np.abs(torque[:, :2].mean(axis=0)).max() < 0.05 * weight * 0.0325
    applied = ActuatorModel(kf=fit.kf).apply(log)
    np.testing.assert_allclose(applied.thrust, thrust)


# ----------------------------------------------------------------------------- yaw sign

def test_yaw_sign_same_on_all_yaw_flights():
    fits = [yaw_fit(name) for name in YAW_FLIGHTS]
    signs = {f.sign for f in fits}
    assert len(signs) == 1, [(f.source, f.gain, f.gain_se) for f in fits]
    sign = signs.pop()
    assert fits[0].spin == SPIN_CRAZYFLIE, "the model's default spin must be the measured one"
    # Combined evidence (inverse-variance weighted gain) is far from zero.
    w = np.array([1 / f.gain_se**2 for f in fits])
    gain = float(np.sum(w * [f.gain for f in fits]) / w.sum())
    assert sign * gain / math.sqrt(1 / w.sum()) > 4.0
    for f in fits:
        assert 0.0005 < f.yaw_ratio < 0.012, f
        assert f.r2 > 0.3
        assert f.rotor_inertia > 0.0  # the rotors' own inertia adds to the drag torque


def test_yaw_fit_recovers_a_simulated_flight():
    rng = np.random.default_rng(11)
    dt, n = 0.002, 15000
    t = np.arange(n) * dt
    izz, gamma, kf, sign, damping = 29e-6, 0.006, 2e-8, -1, 0.8
    base = 19500.0
    # Smooth random yaw commands on the diagonal pairs.
    cmd = np.convolve(rng.standard_normal(n), np.ones(200) / 200, mode="same") * 8000
    rpm = base + np.column_stack([cmd, -cmd, cmd, -cmd]) + 50 * rng.standard_normal((n, 4))
    rpm_true = base + np.column_stack([cmd, -cmd, cmd, -cmd])
    omega = rpm_true * 2 * np.pi / 60
    u = kf * (omega**2) @ np.array([1, -1, 1, -1])
    wz = np.zeros(n)
    for k in range(n - 1):
        wz[k + 1] = wz[k] + dt * (sign * gamma * u[k] / izz - damping * wz[k])
    gyro = np.column_stack([np.zeros(n), np.zeros(n), wz + 0.01 * rng.standard_normal(n)])
    nan3 = np.full((n, 3), np.nan)
    log = FlightLog(t=t, position=nan3, velocity=nan3, euler=nan3, gyro=gyro,
                    accel=nan3, rpm=rpm, meta=LogMeta(source="simulated"))
    fit = fit_yaw(log, ActuatorModel(kf=kf), izz=izz, rotor_inertia=False)
    assert fit.sign == sign
    assert fit.yaw_ratio == pytest.approx(gamma, rel=0.05)
    assert fit.damping == pytest.approx(damping, rel=0.2)
    assert abs(fit.t_stat) > 10
