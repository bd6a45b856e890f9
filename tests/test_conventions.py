"""Other loggers' conventions, declared or detected: a real IMRC flight and a flightgen
flight written as another logger would write them (``pinquad.io.foreign``). Declared in
the sidecar, the conversion at the reader is exact (the same columns, the same
estimates to 1e-6); undeclared, the physical checks refuse the log before any EM and
name the sidecar key that fixes it (``pinquad.io.conventions_check``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flightgen import FlightSpec, generate, write_csv
from pinquad.api import identify
from pinquad.io.declared import Conventions, read_conventions
from pinquad.io.foreign import write_foreign
from pinquad.io.logs import LogFormatError, read_table, write_log
from pinquad.io.read import read_log
from pinquad.io.sanity import ImplausibleLogError, check_log

JANA00 = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana00"
QUAT = ("quat_w", "quat_x", "quat_y", "quat_z")
FEW = settings(max_examples=8, deadline=None, derandomize=True, database=None,
               suppress_health_check=list(HealthCheck))

# (declaration, columns left out, the key an undeclared log's refusal names)
ATTITUDE_CASES = {
    "frame": (Conventions(frame="NED/FRD"), (), '"frame": "NED/FRD"'),
    "quaternion order": (Conventions(quaternion_order="xyzw"), (), '"order": "xyzw"'),
    "inverse quaternion": (Conventions(quaternion_rotation="world_to_body"), (),
                           '"rotation": "world_to_body"'),
    "euler degrees": (Conventions(euler_unit="deg"), QUAT, '"unit": "deg"'),
}
ROTOR_CASES = {
    "rotor speed": (Conventions(rotor_speed="rad/s"), (), '"rotor_speed": "rad/s"'),
    "motor order": (Conventions(motor_order=(2, 3, 4, 1)), (), '"motor_order": [2, 3, 4, 1]'),
}
EXACT_ONLY = {  # declared conversions exact; undeclared not told apart on gentle flights
    "euler order XYZ": (Conventions(euler_order="XYZ"), QUAT, None),
    "everything": (Conventions(frame="NED/FRD", quaternion_order="xyzw",
                               quaternion_rotation="world_to_body"), (), None),
}


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """jana00 (fails without the shared data) as pinquad's own Parquet log, 4 s of it."""
    assert JANA00.exists(), f"shared IMRC data missing: {JANA00}"
    log = replace(read_log(JANA00), measured=None)
    log = log.slice(0, int(np.searchsorted(log.t, 4.0)))
    return read_table(write_log(log, tmp_path_factory.mktemp("real") / "jana00.parquet"))


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    flight = generate(FlightSpec(duration=4.0, dt=0.001, seed=3, log_rate=100))
    return read_table(write_csv(flight, tmp_path_factory.mktemp("fg") / "fg.csv", mass_guess=0.03))


def _same_columns(a, b) -> None:
    for name in ("position", "velocity", "gyro", "accel", "thrust", "torque", "rpm"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None, name
            continue
        np.testing.assert_allclose(y, x, rtol=1e-12, atol=1e-12, err_msg=name)
    turn = np.angle(np.exp(1j * (a.euler - b.euler)))  # yaw +-pi are one angle
    assert np.nanmax(np.abs(turn)) < 1e-12
    assert np.array_equal(np.isnan(a.euler), np.isnan(b.euler))


def _estimate(log) -> np.ndarray:
    run = identify(log, information=False).run
    return np.r_[run.mass, np.diag(run.inertia)]


def _write(log, tmp_path: Path, case: tuple, declare: bool):
    conv, drop, _ = case
    return read_table(write_foreign(log, tmp_path / f"{declare}.parquet", conv, declare, drop))


@FEW
@given(name=st.sampled_from(sorted({**ATTITUDE_CASES, **ROTOR_CASES, **EXACT_ONLY})))
def test_a_declared_convention_reads_as_the_real_flight_exactly(real, tmp_path_factory, name):
    case = {**ATTITUDE_CASES, **ROTOR_CASES, **EXACT_ONLY}[name]
    base = read_table(write_foreign(real, tmp_path_factory.mktemp("b") / "b.parquet",
                                  Conventions(), False, case[1]))
    back = _write(real, tmp_path_factory.mktemp("d"), case, declare=True)
    _same_columns(base, back)
    check_log(back)


@FEW
@given(name=st.sampled_from(sorted({**ATTITUDE_CASES, **EXACT_ONLY})))
def test_a_declared_convention_reads_as_the_simulated_flight_exactly(simulated,
                                                                     tmp_path_factory, name):
    case = {**ATTITUDE_CASES, **EXACT_ONLY}[name]
    base = read_table(write_foreign(simulated, tmp_path_factory.mktemp("b") / "b.parquet",
                                  Conventions(), False, case[1]))
    back = _write(simulated, tmp_path_factory.mktemp("d"), case, declare=True)
    _same_columns(base, back)
    check_log(back)


@settings(max_examples=4, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(name=st.sampled_from(["frame", "inverse quaternion", "rotor speed", "motor order"]))
def test_a_declared_convention_gives_the_same_estimates(real, simulated, tmp_path_factory,
                                                        name):
    case = {**ATTITUDE_CASES, **ROTOR_CASES}[name]
    logs = (real,) if name in ROTOR_CASES else (real, simulated)
    for log in logs:
        back = _write(log, tmp_path_factory.mktemp("e"), case, declare=True)
        np.testing.assert_allclose(_estimate(back), _estimate(log), rtol=1e-6)


@FEW
@given(name=st.sampled_from(sorted({**ATTITUDE_CASES, **ROTOR_CASES})))
def test_an_undeclared_convention_is_refused_naming_the_sidecar_key(real, tmp_path_factory,
                                                                   name):
    case = {**ATTITUDE_CASES, **ROTOR_CASES}[name]
    moved = _write(real, tmp_path_factory.mktemp("u"), case, declare=False)
    with pytest.raises(ImplausibleLogError) as err:
        check_log(moved)
    assert case[2] in str(err.value) and "False.parquet" in str(err.value)


@FEW
@given(name=st.sampled_from(sorted(ATTITUDE_CASES)))
def test_an_undeclared_convention_of_a_simulated_flight_is_refused(simulated,
                                                                   tmp_path_factory, name):
    case = ATTITUDE_CASES[name]
    moved = _write(simulated, tmp_path_factory.mktemp("u"), case, declare=False)
    with pytest.raises(ImplausibleLogError) as err:
        check_log(moved)
    assert case[2] in str(err.value)


def test_a_non_unit_quaternion_is_refused_naming_the_columns(real, tmp_path):
    path = write_log(real, tmp_path / "q.parquet")

    scaled = pq.read_table(path)
    for name in QUAT:
        i = scaled.column_names.index(name)
        scaled = scaled.set_column(i, name, [np.asarray(scaled.column(name)) * 2.0])
    pq.write_table(scaled, path)
    with pytest.raises(LogFormatError, match=r"q\.parquet: columns quat_w, quat_x, quat_y, "
                       r"quat_z have median norm 2"):
        read_table(path)


@pytest.mark.parametrize("raw, words", [
    ({"frame": "NEU"}, "key 'frame' is 'NEU'; expected one of ENU/FLU, NED/FRD"),
    ({"quaternion": "xyzw"}, "key 'quaternion' is 'xyzw'; expected an object"),
    ({"quaternion": {"order": "wzyx"}}, "key 'quaternion.order' is 'wzyx'"),
    ({"euler": {"unit": "grad"}}, "key 'euler.unit' is 'grad'; expected one of rad, deg"),
    ({"rotor_speed": "rpm"}, "key 'rotor_speed' is 'rpm'; expected one of rev/min, rad/s"),
    ({"motor_order": [1, 2, 2, 4]}, "key 'motor_order' is [1, 2, 2, 4]"),
])
def test_a_bad_declaration_names_the_sidecar_and_key(raw, words):
    with pytest.raises(LogFormatError) as err:
        read_conventions(Path("f.csv.json"), raw)
    assert str(err.value).startswith("f.csv.json: ") and words in str(err.value)


def test_a_rotor_speed_log_without_a_sidecar_is_judged_against_no_vehicle(real, tmp_path):
    from pinquad.pipeline.identify import LogOptions, identify_log, plausible_range
    from pinquad.report.console import warning_lines

    path = write_log(real, tmp_path / "bare.parquet")
    Path(str(path) + ".json").unlink()
    log = read_table(path)
    assert not log.meta.vehicle_named and log.meta.vehicle == "paper"
    result = identify_log(log, LogOptions(msteps=("regressor",), information=False,
                                          max_iterations=2))
    assert plausible_range(result.log) is None
    assert any(n.startswith("no vehicle named") for n in result.notes)
    # the printed warning reads the result's flag, not its note's words
    assert result.vehicle_unnamed
    assert any(w.startswith("warning: no vehicle named") for w in warning_lines(result))
    named = identify_log(read_table(write_log(real, tmp_path / "named.parquet")),
                         LogOptions(msteps=("regressor",), information=False, max_iterations=2))
    assert not named.vehicle_unnamed
    assert not any(w.startswith("warning: no vehicle named") for w in warning_lines(named))
