"""A vehicle from a file in the simulated world: the 250 mm + quad of
docs/vehicles/quad250_plus.toml flown, logged with rotor speeds and identified from its
CSV log as a user's log is; the vehicle file against the log; --vehicle on the
measured-flight commands; the shipped vehicles' constants only in their files."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.cli import axis_inertia, offline, realdata, realdiscovery, response
from pinquad.core.paper_results import OFFLINE_INERTIA_BOUND, OFFLINE_MASS_BOUND
from pinquad.core.params import vehicle_from_spec
from pinquad.core.vehicle_file import load_vehicle
from pinquad.experiments.vehicle_file_mc import (
    FILE_VEHICLE_BAND,
    fly_vehicle_file,
    short_scenario,
    vehicle_file_cycle,
)
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.read import read_log, with_vehicle
from pinquad.pipeline.identify import LogOptions
from pinquad.realdata.identify import identify_real, measured_fit
from pinquad.realdata.observation_options import RealDataOptions, options_for_vehicle
from pinquad.realdata.observations import build_observations
from pinquad.realdata.raw import raw_flight
from pinquad.realdata.vehicle_check import measured_vehicle, over_max_thrust
from pinquad.sim.rotor_log import rotor_speeds
from pinquad.vehicle.actuators import ActuatorModel
from pinquad.vehicle.model import load_model

ROOT = Path(__file__).resolve().parents[1]
QUAD = ROOT / "docs" / "vehicles" / "quad250_plus.toml"


def test_inverse_mixer_gives_back_the_wrench():
    act = ActuatorModel.from_spec(load_vehicle(str(QUAD)))
    wrench = np.array([[4.9, 0.01, -0.02, 0.003], [6.0, -0.05, 0.03, -0.01]])
    thrust, torque = act.wrench(rotor_speeds(wrench, act))
    np.testing.assert_allclose(np.column_stack([thrust, torque]), wrench, rtol=1e-12, atol=1e-15)


def test_plus_quad_from_its_file_identified_from_its_rotor_speeds(tmp_path):
    """One short seeded flight (two of the paper's waypoints at 0.3 scale, seed 0),
    logged with rpm_1..rpm_4, identified from the CSV through the file's mixer and kf:
    mass and every inertia entry within the bounds pinquad's offline experiment meets
    (0.065 %, 3 %; measured -0.02 %, +0.04 / -1.84 / -0.43 % with the 0-45 Hz band,
    -0.28 / -2.22 / -0.49 % with the earlier 0.2-45 Hz). Before the take-off's
    stopped-rotor bins became resets this flight's I_yy and I_zz were inside only the
    paper's wider sensor-B ranges (docs/vehicles.md)."""
    spec = load_vehicle(str(QUAD))
    options = LogOptions(msteps=("regressor",), band=FILE_VEHICLE_BAND, information=False)
    cycle = vehicle_file_cycle(spec, 0, tmp_path / "quad.csv", short_scenario(0.3, 2), options)
    log = read_log(tmp_path / "quad.csv")
    assert log.rpm is not None and log.rpm.shape[1] == 4 and log.thrust is None
    assert Path(log.meta.vehicle) == QUAD.resolve()  # the sidecar names the file
    assert not cycle.crashed and cycle.max_miss < 0.02
    err = cycle.rel_error
    assert abs(err[0]) <= OFFLINE_MASS_BOUND, err
    assert np.all(np.abs(err[1:]) <= OFFLINE_INERTIA_BOUND), err


def _rpm_log(rpm: np.ndarray, vehicle: str) -> FlightLog:
    n = rpm.shape[0]
    nan3 = np.full((n, 3), np.nan)
    return FlightLog(t=0.01 * np.arange(n), position=nan3, velocity=nan3, euler=nan3,
                     gyro=nan3, accel=nan3, rpm=rpm,
                     meta=LogMeta(vehicle=vehicle, source="test.csv"))


def test_log_faster_than_the_files_max_thrust_is_an_input_error():
    spec = load_vehicle(str(QUAD))
    rpm = np.full((200, 4), 12000.0)
    rpm[:10, 2] = 30000.0  # 5 % of rotor 3's rows above the 27,000 rev/min of 6 N
    with pytest.raises(ValueError, match=r"column rpm_3 reads above 27009 rev/min.*5\.0 %"):
        over_max_thrust(_rpm_log(rpm, str(QUAD)), 6.0, spec.actuators.kf, QUAD)
    with pytest.raises(ValueError, match="rpm_3"):
        measured_vehicle(_rpm_log(rpm, str(QUAD.resolve())))
    rpm[:10, 2] = 12000.0
    measured_vehicle(_rpm_log(rpm, str(QUAD.resolve())))  # within the file: no error


def test_six_speeds_with_the_shipped_four_rotor_vehicle_is_an_input_error(tmp_path):
    log = _rpm_log(np.full((300, 6), 15000.0), "crazyflie21")
    with pytest.raises(ValueError, match=r"6 rotor speeds"):
        measured_vehicle(with_vehicle(log, "crazyflie21", ROOT, "test"))


def test_fault_thresholds_come_from_the_file_or_from_it_derived():
    cf = load_vehicle("crazyflie21")
    defaults = RealDataOptions()
    # the brushed Crazyflie's thresholds and PWM-repair uncertainty live in its file only
    assert (defaults.flight_rpm, defaults.max_rpm, defaults.repair_rel_se) == (
        cf.faults.flight_rpm, cf.faults.max_rpm, cf.faults.repair_rel_se)
    quad = options_for_vehicle(load_vehicle(str(QUAD)))
    hover = np.sqrt(0.5 * 9.81 / (4 * 7.5e-7)) * 60 / (2 * np.pi)
    assert quad.flight_rpm == pytest.approx(0.5 * hover)
    assert quad.max_rpm == pytest.approx(np.sqrt(6.0 / 7.5e-7) * 60 / (2 * np.pi))
    assert quad.faults == "exclude" and quad.repair_rel_se == ()


@pytest.mark.parametrize("command, argv", [
    (realdata.main, ["--vehicle", "missing.toml"]),
    (response.main, ["--vehicle", "missing.toml"]),
    (axis_inertia.main, ["--vehicle", "missing.toml"]),
    (realdiscovery.main, ["--vehicle", "missing.toml"]),
])
def test_measured_commands_take_a_vehicle_file(command, argv, capsys):
    assert command(argv) == 2
    err = capsys.readouterr().err
    assert "--vehicle" in err and "missing.toml" in err and "Traceback" not in err


def test_vehicle_file_monte_carlo_refuses_a_file_without_actuators(tmp_path, capsys):
    bare = tmp_path / "bare.toml"
    bare.write_text(QUAD.read_text().split("[actuators]")[0])
    assert offline.main(["--vehicle", str(bare), "--cycles", "1", "--out", str(tmp_path / "r")]) == 2
    assert "no [actuators] table" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_file_vehicle_has_no_urdf_but_flies():
    veh = vehicle_from_spec(load_vehicle(str(QUAD)))
    model = load_model(veh)
    assert model.inertias[1].mass == pytest.approx(0.5)
    np.testing.assert_allclose(np.diag(model.inertias[1].inertia), [3.0e-3, 3.2e-3, 5.5e-3])


def test_bins_without_a_trusted_input_are_resets_for_the_e_step():
    """A simulated take-off asks some rotors for negative thrust (logged stopped, flagged
    as implausible, input interpolated): those transitions are resets, so the E-step does
    not fly the made-up torque (it put seed 3's I_zz +9.8 % instead of +3.7 %); every
    transition with a logged input is not."""
    spec = load_vehicle(str(QUAD.resolve()))
    log, _ = fly_vehicle_file(spec, 3, short_scenario(0.3, 1))
    base, kf = measured_vehicle(log)
    real = build_observations(raw_flight(log), base, kf)
    stopped = (log.rpm == 0.0).any(axis=1) & (np.median(log.rpm, axis=1) > base.flight_rpm)
    assert stopped.sum() >= 3  # the take-off's stopped rotors
    resets = real.obs.resets
    assert resets.shape == (real.obs.n,)
    np.testing.assert_array_equal(np.flatnonzero(resets), np.flatnonzero(stopped))
    assert np.all(real.obs.exclude[resets])


def test_files_rotor_inertia_zero_fixes_j_r_and_an_absent_key_fits_it():
    """quad250_plus.toml gives rotor_inertia = 0 (the simulated world flies none): the
    identification reports J_r = 0, fixed; the same file without the key fits J_r on the
    flight (a nonzero value). Three E-steps on a one-waypoint flight: only who decides
    J_r is tested here, not its value."""
    spec = load_vehicle(str(QUAD.resolve()))
    assert spec.actuators.rotor_inertia == 0.0
    log, _ = fly_vehicle_file(spec, 0, short_scenario(0.3, 1))
    base, kf = measured_vehicle(log)
    assert base.rotor_inertia == 0.0
    raw = raw_flight(log)
    guess = (spec.guess_mass, spec.guess_inertia)
    fixed = identify_real(build_observations(raw, base, kf), *guess, max_iterations=3,
                          information=False, band=FILE_VEHICLE_BAND)
    assert measured_fit(fixed).rotor_inertia == 0.0
    absent = options_for_vehicle(replace(spec, actuators=replace(spec.actuators,
                                                                 rotor_inertia=None)))
    assert absent.rotor_inertia is None
    fitted = identify_real(build_observations(raw, absent, kf), *guess, max_iterations=3,
                           information=False, band=FILE_VEHICLE_BAND)
    jr = measured_fit(fitted).rotor_inertia
    assert np.isfinite(jr) and jr != 0.0
