"""Identification of the real Crazyflie from its micro-SD flight logs (IMRC Lab data).

The data live outside the repository (../shared/data/crazyflie); without them these
tests fail rather than skip, because they are the project's only real-vehicle check.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from pinquad.identification.identify import Identification
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.read import read_log
from pinquad.realdata.dataset import PUBLISHED_INERTIA, SCALE_MASS, default_guess
from pinquad.realdata.identify import identify_real, measured_fit
from pinquad.realdata.mass_balance import quasi_static_mass
from pinquad.realdata.observation_options import RealDataOptions
from pinquad.realdata.observations import RealObservations, build_observations
from pinquad.realdata.raw import RawFlight, raw_flight
from pinquad.realdata.thrust import thrust_coefficient
from pinquad.vehicle.actuators import ActuatorModel, ThrustCoefficient

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "crazyflie"
FLIGHTS = DATA / "imrc_brushed"
STAND = DATA / "thrust_stand"


def require_data() -> None:
    assert FLIGHTS.is_dir() and STAND.is_dir(), (
        f"the Crazyflie data are missing: expected flights in {FLIGHTS} and thrust-stand "
        f"CSVs in {STAND}")


def observations_of(path: Path, options: RealDataOptions, kf: ThrustCoefficient) -> RealObservations:
    """The EM observations of a shipped flight with the given options and kf (what
    ``realdata.vehicle_check.measured_observations`` builds with the vehicle's own)."""
    return build_observations(raw_flight(read_log(path)), options, kf)


@cache
def identified(name: str) -> Identification:
    require_data()
    kf = thrust_coefficient(STAND)
    real = observations_of(FLIGHTS / name, RealDataOptions(), kf)
    mass0, inertia0, _ = default_guess("crazyflie21")
    return identify_real(real, mass0, inertia0, max_iterations=100, information=False)


def test_kf_is_the_equal_weight_mean_of_the_stand_runs():
    require_data()
    kf = thrust_coefficient(STAND)
    assert len(kf.runs) == 2
    runs = [r.kf for r in kf.runs]
    assert kf.kf == pytest.approx(np.mean(runs), rel=1e-12)
    # two runs: the standard error of their mean is half their difference (~4.8 %)
    assert kf.kf_se == pytest.approx(abs(runs[0] - runs[1]) / 2, rel=1e-9)
    assert 0.03 < kf.rel_se < 0.07


def _stand_rows(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Rotor speeds (N, 4) [rev/min] and total thrust (N,) [N] of one thrust-stand CSV,
    the thrust less the load cell's reading with every rotor stopped (grams-force,
    g = 9.81 m/s^2)."""
    table = np.genfromtxt(path, delimiter=",", names=True)
    rpm = np.column_stack([table[f"rpm{i}"] for i in range(1, 5)])
    weight = table["weightg"]
    return rpm, (weight - np.median(weight[(rpm == 0).all(axis=1)])) * 9.81e-3


def _lagged(rpm: np.ndarray, thrust: np.ndarray, lag: int) -> tuple[np.ndarray, np.ndarray]:
    """(sum of the four omega^2 [(rad/s)^2], thrust [N]) of the rows with every rotor
    spinning, the thrust read ``lag`` rows after the rotor speeds."""
    rpm, thrust = rpm[:thrust.size - lag], thrust[lag:]
    spinning = (rpm > 0).all(axis=1)
    return ((rpm[spinning] * 2 * np.pi / 60) ** 2).sum(axis=1), thrust[spinning]


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least squares T = kf x through the origin."""
    return float(np.linalg.lstsq(x[:, None], y, rcond=None)[0][0])


def _independent_kf(paths: list[Path], blocks: int = 20) -> tuple[float, float]:
    """kf [N/(rad/s)^2] of the stand CSVs together by least squares, each CSV's weight
    shifted by the lag (0-60 rows) that leaves the smallest residual, and its standard
    error by a delete-one-block jackknife over ``blocks`` contiguous blocks per CSV
    (neighbouring rows share their errors, so a row-wise error would be too small)."""
    pieces = []
    for path in paths:
        rpm, thrust = _stand_rows(path)
        fits = [_lagged(rpm, thrust, lag) for lag in range(61)]
        x, y = min(fits, key=lambda xy: float(np.mean((xy[1] - _slope(*xy) * xy[0]) ** 2)))
        pieces += list(zip(np.array_split(x, blocks), np.array_split(y, blocks), strict=True))
    kf = _slope(np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces]))
    left_out = np.array([
        _slope(np.concatenate([p[0] for j, p in enumerate(pieces) if j != i]),
               np.concatenate([p[1] for j, p in enumerate(pieces) if j != i]))
        for i in range(len(pieces))])
    m = len(pieces)
    return kf, float(np.sqrt((m - 1) / m * np.sum((left_out - left_out.mean()) ** 2)))


def test_kf_fits_agree_with_a_least_squares_fit_written_here():
    """Each stand run's kf and the pooled kf agree with a plain least-squares fit of the
    raw CSVs (tare, lag, lstsq through the origin) to within that fit's standard error:
    the two fit the same rows and differ only in the few the product rejects as
    transients, which moves kf by a small fraction of its standard error (here 1e-13 of
    it; a unit, tare or lag mistake moves it by several)."""
    require_data()
    kf = thrust_coefficient(STAND)
    paths = sorted(STAND.glob("*.csv"))
    assert [r.source for r in kf.runs] == [p.name for p in paths]
    for path, run in zip(paths, kf.runs, strict=True):
        want, se = _independent_kf([path])
        assert abs(run.kf - want) < se, (path.name, run.kf, want, se)
    want, se = _independent_kf(paths)
    assert 0.0 < se < 0.02 * want
    assert abs(kf.pooled - want) < se, (kf.pooled, want, se)


def _synthetic(n_sec: float = 4.0) -> RawFlight:
    """A 500 Hz flight that starts on the floor (rotors idle, z = 0.01 m), climbs to
    0.5 m and hovers, with a 90 Hz pose stream."""
    t = np.arange(0.0, n_sec, 0.002)
    n = t.size
    z = np.where(t < 1.0, 0.01, np.minimum(0.01 + 0.5 * (t - 1.0), 0.5))
    rpm = np.where(t[:, None] < 1.0, 3000.0, 19500.0) * np.ones((n, 4))
    rpm[:, 0] += 100.0 * np.sin(2 * np.pi * 3 * t)
    gyro = np.column_stack([0.1 * np.sin(2 * np.pi * t), np.zeros(n), 0.2 * np.ones(n)])
    nan3 = np.full((n, 3), np.nan)
    vel = np.zeros((n, 3))
    vel[:, 2] = np.gradient(z, t)
    log = FlightLog(t=t, position=nan3, velocity=vel, euler=nan3, gyro=gyro, accel=nan3,
                    rpm=rpm, meta=LogMeta(vehicle="crazyflie21", source="synthetic"))
    from pinquad.realdata.raw import PoseSamples

    tp = np.arange(0.0, n_sec, 1 / 90)
    pos = np.column_stack([np.zeros(tp.size), np.zeros(tp.size), np.interp(tp, t, z)])
    return RawFlight(log=log, pose=PoseSamples(t=tp, position=pos, euler=np.zeros((tp.size, 3))))


def test_resampling_to_100hz_and_ground_contact():
    raw = _synthetic()
    kf = thrust_coefficient(STAND) if STAND.is_dir() else None
    real = build_observations(raw, RealDataOptions(), kf)
    obs = real.obs
    assert obs.dt == 0.01 and obs.n == 400
    # a measured flight moves continuously between its bins (models.continuous)
    assert obs.continuous
    np.testing.assert_allclose(np.diff(obs.t), 0.01, atol=1e-12)
    # inputs: mean over [t_k, t_k + dt) of the 2 ms wrench samples
    thrust, torque = ActuatorModel(kf=real.kf.kf).wrench(raw.log.rpm)
    k = 250
    sel = (raw.log.t >= obs.t[k] - 1e-9) & (raw.log.t < obs.t[k] + 0.01 - 1e-9)
    assert sel.sum() == 5
    assert obs.inputs[k, 0] == pytest.approx(thrust[sel].mean(), rel=1e-12)
    np.testing.assert_allclose(obs.inputs[k, 1:], torque[sel].mean(axis=0), rtol=1e-9,
                               atol=1e-15)
    # gyro: centred bin mean
    gyro = obs.ys[:, 6:9]
    sel = np.abs(raw.log.t - obs.t[k]) < 0.005 - 1e-9
    np.testing.assert_allclose(gyro[k], raw.log.gyro[sel].mean(axis=0), atol=1e-12)
    # pose: the sample nearest each grid time within 5 ms, else missing
    pos_ok = np.isfinite(obs.ys[:, 2])
    assert 0.8 * 90 * 4 <= pos_ok.sum() <= 90 * 4 + 1
    # on the floor with idle rotors for 1 s (+ 0.3 s margin): excluded
    assert obs.exclude[:100].all()
    assert not obs.exclude[140:].any()
    assert any("ground contact" in line for line in real.excluded)
    # the model-free mass check: the used transitions start in the 0.5 m/s climb and end
    # in the hover, a mean vertical acceleration of -0.5 m/s over their duration; the
    # thrust is constant after t = 1 s (M1's +-100 rpm sine averages out)
    used = ~obs.exclude[: obs.n - 1]
    assert 1.0 < obs.t[np.argmax(used)] < 1.98  # the span starts in the climb
    mean_acc = -0.5 / (used.sum() * obs.dt)
    expected = thrust[raw.log.t > 1.0].mean() / (9.81 + mean_acc)
    assert quasi_static_mass(real) == pytest.approx(expected, rel=2e-3)


def test_clean_log_mass_within_1p5_percent_of_the_scale():
    ident = identified("jana00")
    assert abs(ident.mass / SCALE_MASS - 1.0) < 0.015, ident.mass
    # the model-free check agrees: the rotor speeds and kf alone imply the scale's mass
    free = measured_fit(ident).quasi_static_mass
    assert abs(free / SCALE_MASS - 1.0) < 0.015, free
    # The scale is inside two total standard errors, which carry kf's ~5 %.
    assert abs(ident.mass - SCALE_MASS) < 2.0 * ident.stderr[0]
    assert ident.stderr[0] > 0.04 * ident.mass > 10 * measured_fit(ident).se_jack[0]
    # roll and pitch inertia within 10 % of the bifilar-pendulum values
    np.testing.assert_allclose(np.diag(ident.inertia)[:2], PUBLISHED_INERTIA[:2], rtol=0.10)
    assert np.all(np.isfinite(ident.stderr))
    assert ident.converged


def test_faulty_log_is_repaired_and_its_mass_is_near_the_scale():
    """jana20: motor 1's rpm reads 0 or half the speed; the halves are doubled, the rest
    rebuilt from its PWM. The mass is 2.5 % above the scale, not within the issue's
    1.5 %: all faulty flights sit 2-3 % above the clean ones, and the excess is in the
    measured speeds (M2-M4, and M1 where its doubled reading is there), so the repair does
    not cause it. This test holds the README's documented range for the faulty flights
    (+2.5 to +3.4 %; jana20 is the +2.5 % one, held to 3 %) and that the scale is within two total standard
    errors; test_faulty_log_mass_within_the_target asserts the 1.5 % target (xfail)."""
    ident = identified("jana20")
    rel = ident.mass / SCALE_MASS - 1.0
    assert abs(rel) < 0.03, rel
    assert abs(ident.mass - SCALE_MASS) < 2.0 * ident.stderr[0]
    assert any("rebuilt from its PWM" in note for note in ident.notes)
    assert any("battery voltage stuck" in note for note in ident.notes)
    np.testing.assert_allclose(np.diag(ident.inertia)[:2], PUBLISHED_INERTIA[:2], rtol=0.15)
    # The model-free check split by motor: M1's rebuilt share puts back exactly the
    # model-free mass, and the three measured motors alone already carry 3/4 of a vehicle
    # heavier than the scale's: M1 would need to carry less of the thrust than on any
    # clean log (jana00 has the lowest M1 share, 0.92).
    # (motor_split's arithmetic is checked against hand-computed numbers in
    # test_motor_split_of_a_hand_built_hover)
    split = measured_fit(ident).motor_split
    assert split is not None and split.rebuilt == (0,)
    clean = measured_fit(identified("jana00")).motor_split
    assert clean is not None and not clean.rebuilt
    assert split.share_for(SCALE_MASS) < clean.share[0] < split.share[0]
    # Where M1's half-count reading is there (doubled), no speed comes from PWM: the
    # mass these transitions balance agrees with the repaired flight's, so the excess
    # does not come from the PWM map either.
    assert any("counts one pulse in 2" in note for note in ident.notes)
    assert split.all_measured_rows > 500
    assert split.all_measured_mass == pytest.approx(measured_fit(ident).quasi_static_mass,
                                                    rel=0.01)
    # Without the repair every airborne row is implausible: nothing left to identify.
    with pytest.raises(ValueError, match="no usable actuation"):
        observations_of(FLIGHTS / "jana20", RealDataOptions(faults="exclude"),
                  thrust_coefficient(STAND))


@pytest.mark.xfail(strict=True, reason="jana20 (faulty rpm, repaired) measured: EM mass "
                   "+2.5 % and model-free all-measured mass +2.3 % above the scale; every "
                   "faulty flight sits 2-3 % above the clean ones (README: +2.5 to +3.4 %)")
def test_faulty_log_mass_within_the_target():
    """The issue's target for the mass of every log, faulty or not: within 1.5 % of the
    scale's 34.7 g, by EM and by the model-free balance over the all-measured rows."""
    ident = identified("jana20")
    assert abs(ident.mass / SCALE_MASS - 1.0) < 0.015, ident.mass
    assert abs(measured_fit(ident).motor_split.all_measured_mass / SCALE_MASS - 1.0) < 0.015


def test_motor_split_of_a_hand_built_hover():
    """motor_split / quasi_static_mass on a hand-built level-and-tilted hover whose
    answers are known: mass m = 34.7 g held by F = m g / cos(roll); motor i carries
    omega_i^2 in the ratio 0.8 : 1 : 1.1 : 1.1 (shares of the four-motor mean); motor 0
    rebuilt from PWM in the first half of the rows. Then m_qs = m, the shares are the
    ratios, the measured motors carry (1 - 0.8 / 4) m, and m_qs over the second half
    (all measured) is m."""
    from types import SimpleNamespace

    from pinquad.realdata.mass_balance import motor_split

    n, g, m = 400, 9.81, 0.0347
    roll = np.where(np.arange(n) % 2 == 0, 0.0, 0.2)
    euler = np.column_stack([roll, np.zeros(n), np.zeros(n)])
    thrust = m * g / np.cos(roll)
    ratio = np.array([0.8, 1.0, 1.1, 1.1])
    rpm = np.sqrt(ratio)[None, :] * np.linspace(15000.0, 16000.0, n)[:, None]
    velocity = np.zeros((n, 3))
    velocity[:, 0] = 0.3  # steady lateral speed: no vertical acceleration
    fraction = np.r_[np.full(n // 2, 0.5), np.zeros(n - n // 2)]
    obs = SimpleNamespace(n=n, dt=0.01, t=0.01 * np.arange(n), exclude=np.zeros(n, bool),
                          inputs=np.column_stack([thrust, np.zeros((n, 3))]))
    log = SimpleNamespace(euler=euler, velocity=velocity, rpm=rpm,
                          meta=SimpleNamespace(gravity=g))
    real = SimpleNamespace(obs=obs, log=log, repaired=(0,), rebuilt_fraction=fraction)
    assert quasi_static_mass(real) == pytest.approx(m, rel=1e-12)
    split = motor_split(real)
    np.testing.assert_allclose(split.share, ratio, rtol=1e-12)
    assert split.rebuilt == (0,)
    assert split.measured_mass == pytest.approx(m * (1.0 - 0.8 / 4.0), rel=1e-12)
    assert split.mass_if(0.8) == pytest.approx(m, rel=1e-12)
    assert split.share_for(m) == pytest.approx(0.8, rel=1e-12)
    assert split.all_measured_rows == n - n // 2 - 1  # the last row starts no transition
    assert split.all_measured_mass == pytest.approx(m, rel=1e-12)
    # with no motor rebuilt every row is all-measured and the measured motors carry m
    full = motor_split(SimpleNamespace(obs=obs, log=log, repaired=(), rebuilt_fraction=None))
    assert full.measured_mass == pytest.approx(m, rel=1e-12)
    assert full.all_measured_rows == n - 1


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PINQUAD_CRAZYFLIE_DATA"] = str(DATA)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def test_offline_cli_identifies_a_real_log(tmp_path):
    require_data()
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--log", str(FLIGHTS / "jana00"), "--out",
         str(out), "--no-information", "--mstep", "regressor", "--no-discover"],
        capture_output=True, text=True, cwd=REPO, env=_env(), timeout=300)
    assert proc.returncode in (0, 3), proc.stderr
    assert "34.7" in proc.stdout
    report = json.loads((out / "report.json").read_text())
    # exit 3 exactly when the headline's verdict is not trusted (the report is written)
    assert proc.returncode == (0 if report["verdict"]["overall"] == "trusted" else 3)
    assert report["source"]["log_type"] == "rotor speeds (Crazyflie micro-SD log)"
    assert report["schema"] == "pinquad.report/1"
    assert report["source"]["kind"] == "log"
    for key in ("path", "sensor", "estep"):
        assert key in report["source"]
    est = report["estimates"]
    assert abs(est["mass"] / SCALE_MASS - 1) < 0.015
    assert np.asarray(est["inertia"]).shape == (3, 3)
    assert est["com"] is None
    assert len(est["stderr"]["inertia_diag"]) == 3 and est["stderr"]["mass"] > 0
    assert set(report["em"]) >= {"iterations", "loglik", "converged"}
    assert report["discovery"] == {"selected": [], "residual_rms_before": {},
                                   "residual_rms_after": {}, "validation": "not run",
                                   "not_run": "not asked for", "note": None, "unphysical": [],
                                   "ground_effect_floor": None}
    assert report["cycles"] == [] and report["excluded"]
    # the model-free mass check rides along: within 0.5 % of EM's mass on this clean log,
    # and with every rotor measured the measured motors carry all of it
    run = report["runs"][0]
    assert abs(run["model_free_mass"] / est["mass"] - 1) < 0.005
    assert run["motor_split"]["rebuilt_motors"] == []
    # the report carries the in-process model-free figures of the same log
    jana00 = measured_fit(identified("jana00"))
    assert run["model_free_mass"] == pytest.approx(jana00.quasi_static_mass, rel=1e-9)
    assert run["motor_split"]["measured_motors_mass"] == pytest.approx(
        jana00.motor_split.measured_mass, rel=1e-9)
    md = (out / "report.md").read_text()
    assert "model-free check" in md
    assert "- note: motion capture:" in md and "- excluded: total:" in md
    logs = report["run_logs"]["log"]
    assert (out / logs["log"]).is_file() and (out / logs["smoothed"]).is_file()
    smoothed = np.load(out / logs["smoothed"])
    assert smoothed.shape[1] == 12
    assert (out / "figures" / "trajectory.png").is_file()
    assert (out / "figures" / "residuals.png").is_file()


def test_truncated_real_log_exits_2_with_file_and_offset(tmp_path):
    require_data()
    data = (FLIGHTS / "jana00").read_bytes()
    bad = tmp_path / "jana00-cut"
    bad.write_bytes(data[: len(data) // 3])
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--log", str(bad), "--out",
         str(tmp_path / "run")], capture_output=True, text=True, cwd=REPO, env=_env(),
        timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert str(bad) in proc.stderr and "byte offset" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "run").exists()


def test_rotor_acceleration_signs_and_gaps():
    """sum_i spin_i omega_i' [rad/s^2] from rpm, NaN next to a log gap."""
    from pinquad.realdata.rotor_acceleration import rotor_acceleration

    t = np.arange(0.0, 1.0, 0.002)
    t[300:] += 0.05  # a 50 ms gap between rows 299 and 300
    rpm = np.column_stack([19000.0 + 600.0 * t, np.full(t.size, 19000.0),
                           np.full(t.size, 19000.0), 19000.0 - 300.0 * t])
    acc = rotor_acceleration(t, rpm, (-1.0, 1.0, -1.0, 1.0))
    expected = (-600.0 - 300.0) * 2.0 * np.pi / 60.0
    ok = np.isfinite(acc)
    assert not ok[299] and not ok[300] and ok.sum() == t.size - 2
    np.testing.assert_allclose(acc[ok], expected, rtol=1e-9)


def test_yaw_flight_rotor_inertia_is_identified_and_positive():
    """The M-step fits J_r of the yaw reaction torque J_r sum_i spin_i omega_i' on a yaw
    sweep: positive (the sign the physics gives) and of the size of a 45 mm propeller and
    a 7 mm motor (1e-9..1e-7 kg m^2)."""
    ident = identified("jana04")
    jr = measured_fit(ident).rotor_inertia
    assert 1e-9 < jr < 1e-7, jr


def _synthetic_band(inertia, jr, k=1500, seed=0):
    """Band-passed regression data of a log whose yaw torque is t_z + jr e: the rotor drag
    torque t_z = x_z . I - jr e - nuisance, plus noise."""
    from pinquad.mstep.band import BandStats

    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 10.0, (k, 3, 3))
    e = rng.normal(0.0, 5e3, (k, 1))
    z = rng.normal(0.0, 1.0, (k, 7))
    t = np.einsum("kjp,p->kj", x, inertia) + rng.normal(0.0, 2e-6, (k, 3))
    t -= z @ rng.normal(0.0, 1e-5, (7, 3))
    t[:, 2] -= jr * e[:, 0]
    return BandStats(x=x, t=t, z=z, rows=np.arange(k), e=e)


def test_pooled_rotor_inertia_recovers_a_shared_value_and_leaves_each_log_out():
    from pinquad.realdata.rotor_inertia import band_fit, pooled_rotor_inertia

    jr = 15e-9
    inertias = [np.array([16e-6, 17e-6, iz]) for iz in (12e-6, 20e-6, 28e-6)]
    stats = {f"log{i}": _synthetic_band(inertia, jr, seed=i)
             for i, inertia in enumerate(inertias)}
    pooled = pooled_rotor_inertia(stats)
    assert pooled.value == pytest.approx(jr, rel=0.02)
    assert set(pooled.leave_one_out) == set(stats) == set(pooled.per_flight)
    for name, value in pooled.leave_one_out.items():
        assert value == pytest.approx(jr, rel=0.05)
        assert pooled.for_log(name) == (value, "leave-one-out")
    assert pooled.for_log("other") == (pooled.value, "pooled")
    assert 0.0 < pooled.se < 0.05 * jr
    for bs, inertia in zip(stats.values(), inertias, strict=True):
        fitted, _, var = band_fit(bs, pooled.value)
        np.testing.assert_allclose(fitted, inertia, rtol=0.02)
        assert var < band_fit(bs, 0.0)[2]
    assert "leave-one-out" in pooled.describe() and "jackknife" in pooled.describe()


def test_fixed_rotor_inertia_is_taken_back_out_of_the_band_stats():
    """jana02 identified with a J_r fitted elsewhere (fixed, 15e-9): the stored band-passed
    regression has the drag torque alone, band_fit at that J_r gives the EM's inertia
    back, and the J_r term explains yaw motion it was not fitted on."""
    from pinquad.realdata.rotor_inertia import band_fit

    require_data()
    jr = 15e-9
    real = observations_of(FLIGHTS / "jana02", RealDataOptions(rotor_inertia=jr), thrust_coefficient(STAND))
    mass0, inertia0, _ = default_guess("crazyflie21")
    run = identify_real(real, mass0, inertia0, max_iterations=100, information=False,
                        keep_band_stats=True)
    fit = measured_fit(run)
    assert fit.rotor_inertia == jr
    inertia, _, var = band_fit(fit.band_stats, jr, np.diag(run.inertia))
    np.testing.assert_allclose(inertia, np.diag(run.inertia), rtol=0.01)
    assert var < 0.9 * band_fit(fit.band_stats, 0.0)[2]


def test_pooled_cli_needs_two_pool_logs():
    from pinquad.cli.realdata import main

    require_data()
    assert main(["--data", str(DATA), "--only", "jana00", "--pool", "jana00"]) == 2
    with pytest.raises(SystemExit):
        main(["--data", str(DATA), "--rotor-inertia", "lots"])


def test_table_compares_the_flights_with_each_other(capsys):
    """``python -m pinquad.realdata`` on two clean logs: the table ends with the flights
    against each other (``realdata.consistency``), one line per parameter both trusted,
    and a flight's error marked [xS] exactly where that comparison scaled it."""
    from pinquad.cli.realdata import main

    require_data()
    assert main(["--data", str(DATA), "--only", "jana00", "jana02", "--rotor-inertia", "0",
                 "--no-discover", "--no-information", "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert "flights against each other" in out
    rows = [ln.split("|") for ln in out.splitlines() if ln.startswith("| jana0")]
    assert len(rows) == 2
    seen_scaled = False
    for name, column in (("mass", 4), ("I_xx", 6), ("I_yy", 7)):
        lines = [ln for ln in out.splitlines()
                 if ln.startswith(f"- {name}, measured rotor speeds")]
        assert len(lines) == 1 and "jana00" in lines[0] and "jana02" in lines[0]
        scale = re.search(r"scaled by S = ([\d.]+)", lines[0])
        seen_scaled |= scale is not None
        for row in rows:
            cell = row[column]
            if scale is None:
                assert "[x" not in cell, (cell, lines[0])
            else:
                assert f"[x{float(scale.group(1)):.1f}]" in cell, (cell, lines[0])
    # on these two logs I_xx scatters beyond its errors (18.8 +- 1.2 against 16.0 +- 0.25)
    assert seen_scaled
