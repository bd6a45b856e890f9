"""Single-column unit errors, dead or stuck rotor channels, a false rotor-speed
declaration and CSV dialects, each on a variant of a real shared IMRC log (jana00):
named with the column, the rows and the fix (``pinquad.io.units_check``,
``pinquad.io.actuation_check``, ``pinquad.io.csv_table``), and the clean log passes."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.cli.offline import build_parser, pipeline_options
from pinquad.core.vehicle_file import shipped_path
from pinquad.io.actuation_check import check_stuck_channel, check_zero_channel
from pinquad.io.declaration_check import check_declared_rotor_speed
from pinquad.io.logs import FlightLog, LogFormatError, read_table, write_log
from pinquad.io.read import read_log
from pinquad.io.sanity import findings, implied_mass
from pinquad.io.units_check import (
    check_gyro_axes,
    check_normalised_thrust,
    check_torque_scale,
    gyro_axis_ratios,
    named_inertia,
)
from pinquad.realdata.vehicle_check import measured_observations

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed"


@pytest.fixture(scope="module")
def rpm_log(tmp_path_factory) -> FlightLog:
    """jana00 exported as pinquad's Parquet log of rotor speeds (vehicle crazyflie21)."""
    assert (DATA / "jana00").exists(), f"shared IMRC data missing: {DATA}"
    sd = read_log(DATA / "jana00")
    log = replace(sd, measured=None, meta=replace(sd.meta, vehicle="crazyflie21",
                                                  vehicle_named=True))
    return read_table(write_log(log, tmp_path_factory.mktemp("rpm") / "jana00.parquet"))


@pytest.fixture(scope="module")
def wrench_csv(rpm_log, tmp_path_factory) -> Path:
    """The same flight as a thrust / torque CSV (100 Hz grid, the wrench its rotor speeds
    give through crazyflie21's rotor model), as a thrust-logging lab would write it."""
    grid = measured_observations(rpm_log).log
    log = replace(grid, rpm=None, meta=replace(grid.meta, wrench_from_rpm=False,
                                               vehicle="crazyflie21", vehicle_named=True,
                                               actuation="sampled"))
    return write_log(log, tmp_path_factory.mktemp("wrench") / "jana00.csv")


@pytest.fixture(scope="module")
def wrench_log(wrench_csv) -> FlightLog:
    return read_table(wrench_csv)


def test_the_clean_variants_pass_every_new_check(rpm_log, wrench_log):
    assert findings(rpm_log) == () and findings(wrench_log) == ()
    ratios = gyro_axis_ratios(wrench_log)
    assert all(r is not None and 0.9 < r < 1.1 for r in ratios), ratios


@pytest.mark.parametrize("axis", [0, 2])
def test_one_gyro_axis_in_deg_per_s_is_named(wrench_log, axis):
    gyro = wrench_log.gyro.copy()
    gyro[:, axis] *= 180.0 / np.pi
    found = check_gyro_axes(replace(wrench_log, gyro=gyro))
    name = ("gyro_x", "gyro_y", "gyro_z")[axis]
    assert found is not None and found[1] == name
    assert f"looks like deg/s in {name}" in found[2] and "pi/180" in found[2]
    ratio = gyro_axis_ratios(replace(wrench_log, gyro=gyro))[axis]
    assert ratio is not None and 50 < ratio < 65


def test_every_gyro_axis_in_deg_per_s_is_left_to_the_whole_sensor_test(wrench_log):
    log = replace(wrench_log, gyro=wrench_log.gyro * 180.0 / np.pi)
    assert check_gyro_axes(log) is None
    assert findings(log)[0].check == "gyro-vs-attitude"


@pytest.mark.parametrize("factor,words,columns", [
    (10.0, "10 times N m", "torque_x, torque_y"),  # yaw correlates 0.46: judged on x50 only
    (1000.0, "N mm", "torque_x, torque_y, torque_z")])
def test_torques_scaled_by_ten_or_in_n_mm_are_named(wrench_log, factor, words, columns):
    found = check_torque_scale(replace(wrench_log, torque=wrench_log.torque * factor))
    assert found is not None and found[1] == columns
    assert words in found[2] and "crazyflie21" in found[2]
    assert check_torque_scale(wrench_log) is None


def test_the_torque_scale_reads_a_vehicle_files_reference_inertia(wrench_log):
    """Named by the shipped crazyflie21.toml as a file, whose [reference] inertia is the
    diagonal (16.57, 16.66, 29.26) e-6 kg m^2: the check reads it as that (3, 3) tensor
    and passes the true torques, and still names torques x10."""
    named = replace(wrench_log, meta=replace(wrench_log.meta, vehicle=str(
        shipped_path("crazyflie21")), vehicle_named=True))
    assert named_inertia(named) == pytest.approx(np.diag([16.57e-6, 16.66e-6, 29.26e-6]))
    assert check_torque_scale(named) is None
    assert check_torque_scale(replace(named, torque=named.torque * 10)) is not None


def test_a_normalised_thrust_command_is_named(wrench_log):
    # PX4 logs the collective thrust as 0..1 of the maximum; 0.6 N is about the
    # Crazyflie's: its hover then reads 0.57 and the hover balance +67 % of mass
    norm = replace(wrench_log, thrust=wrench_log.thrust / 0.6)
    found = check_normalised_thrust(norm, implied_mass(norm))
    assert found is not None and found[1] == "thrust"
    assert "normalised thrust command" in found[2] and "34.7 g" in found[2]
    assert check_normalised_thrust(wrench_log, implied_mass(wrench_log)) is None


def test_a_rotor_channel_at_zero_names_its_rows(rpm_log):
    rpm = rpm_log.rpm.copy()
    third = 2 * rpm_log.n // 3
    rpm[third:, 2] = 0.0
    found = check_zero_channel(replace(rpm_log, rpm=rpm))
    assert found is not None and found[1] == "rpm_3"
    assert f"rows {third + 1}-{rpm_log.n}" in found[2]
    assert f"({third} of {rpm_log.n} rows)" in found[2] and "--faults" in found[2]
    assert check_zero_channel(rpm_log) is None


def test_a_zero_channel_with_pwm_commands_is_left_to_the_repair():
    # jana20's motor 1 reads 0 in a third of its rows; its PWM commands rebuild it
    log = read_log(DATA / "jana20")
    assert log.measured is not None and log.measured.pwm is not None
    assert check_zero_channel(log) is None
    assert check_zero_channel(replace(log, measured=None)) is not None


def test_a_rotor_channel_stuck_at_its_hover_value_is_named(rpm_log):
    rpm = rpm_log.rpm.copy()
    third = 2 * rpm_log.n // 3
    rpm[third:, 2] = np.median(rpm[:, 2])
    found = check_stuck_channel(replace(rpm_log, rpm=rpm))
    assert found is not None and found[1] == "rpm_3"
    assert f"rows {third + 1}-{rpm_log.n}" in found[2]
    assert check_stuck_channel(rpm_log) is None


def test_a_false_rad_per_s_declaration_is_named(rpm_log, tmp_path):
    path = write_log(rpm_log, tmp_path / "f.parquet")
    side = Path(f"{path}.json")
    side.write_text(json.dumps({**json.loads(side.read_text()), "rotor_speed": "rad/s"}))
    found = check_declared_rotor_speed(read_table(path))
    assert found is not None and found[1] == "rpm_*"
    assert '"rotor_speed": "rad/s"' in found[2] and "remove the key" in found[2]
    assert check_declared_rotor_speed(rpm_log) is None


def test_a_duplicated_header_is_refused_naming_both_positions(wrench_csv, tmp_path):
    lines = wrench_csv.read_text().splitlines()
    header = lines[0].split(",")
    k = header.index("gyro_x")
    dup = tmp_path / "dup.csv"
    dup.write_text("\n".join([lines[0] + ",gyro_x"]
                             + [ln + "," + ln.split(",")[k] for ln in lines[1:]]) + "\n")
    with pytest.raises(LogFormatError, match=(f"column 'gyro_x' appears twice in the header, "
                                              f"as column {k + 1} and column "
                                              f"{len(header) + 1}")):
        read_table(dup)


def test_a_european_csv_is_read_like_the_plain_one(wrench_csv, wrench_log, tmp_path):
    lines = wrench_csv.read_text().splitlines()
    eu = tmp_path / "eu.csv"
    eu.write_text("\n".join([lines[0].replace(",", ";")]
                            + [ln.replace(",", ";").replace(".", ",") for ln in lines[1:]]))
    Path(f"{eu}.json").write_text(Path(f"{wrench_csv}.json").read_text())
    log = read_table(eu)
    np.testing.assert_array_equal(log.thrust, wrench_log.thrust)
    np.testing.assert_array_equal(log.gyro, wrench_log.gyro)
    assert any("separated by ';' with ',' as the decimal mark" in n for n in log.meta.notes)
    bad = tmp_path / "thousands.csv"
    bad.write_text("t;pos_x;pos_y;pos_z;thrust;torque_x;torque_y;torque_z\n"
                   "0,0;1.234,5;0;0;0,3;0;0;0\n")
    with pytest.raises(LogFormatError, match="line 2, column 'pos_x': '1.234,5'"):
        read_table(bad)


def test_offline_names_the_dead_channel_with_exit_2_and_writes_nothing(rpm_log, tmp_path):
    rpm = rpm_log.rpm.copy()
    rpm[2 * rpm_log.n // 3:, 2] = 0.0
    path = write_log(replace(rpm_log, rpm=rpm), tmp_path / "zero.parquet")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "pinquad.offline", "--log", str(path),
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "error:" in proc.stderr and "column 'rpm_3' reads 0 rev/min" in proc.stderr
    assert "Traceback" not in proc.stderr and "RealDataOptions" not in proc.stderr
    assert not out.exists()


def test_offline_faults_flag_reaches_the_identification():
    args = build_parser().parse_args(["--log", "x.parquet", "--faults", "exclude"])
    assert pipeline_options(args).identification.faults == "exclude"
    assert pipeline_options(build_parser().parse_args(["--log", "x"])).identification.faults \
        is None


def test_no_usable_actuation_names_the_channel_and_the_flag():
    log = read_log(DATA / "jana20")
    with pytest.raises(ValueError) as err:
        measured_observations(log, faults="exclude")
    text = str(err.value)
    assert "rpm_1:" in text and "whole channel is distrusted" in text
    assert "--faults repair" in text and "RealDataOptions" not in text
