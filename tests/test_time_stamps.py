"""A real logger's time stamps: clock jitter of a few ms and Unix-time offsets must create
no log gap and leave the estimate where it was; a real 2 s gap is still found
(``pinquad.io.timebase``, docs/bad_input.md)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flightgen import FlightSpec, generate, write_csv
from pinquad.api import identify
from pinquad.io.logs import LogFormatError, read_table, write_log
from pinquad.io.read import read_log
from pinquad.io.timebase import find_gaps, gap_steps, relative_time
from pinquad.realdata.observations import build_observations
from pinquad.realdata.raw import raw_flight

JANA00 = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana00"
OFFSETS = (0.0, 1e6, 1.7e9)
JITTER = st.floats(0.5e-3, 4e-3)
FEW = settings(max_examples=3, deadline=None, derandomize=True, database=None,
               suppress_health_check=list(HealthCheck))


def jittered(t: np.ndarray, amplitude: float, offset: float, seed: int) -> np.ndarray:
    """t + uniform(-amplitude, amplitude), sorted (rows keep their order, t strictly
    increasing), plus offset [s]."""
    rng = np.random.default_rng(seed)
    out = np.sort(t + rng.uniform(-amplitude, amplitude, t.size))
    assert (np.diff(out) > 0).all()
    return out + offset


def with_hole(t: np.ndarray, start: float, seconds: float) -> np.ndarray:
    """Rows kept outside [start, start + seconds)."""
    return (t < start) | (t >= start + seconds)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(rate=st.sampled_from([50.0, 100.0, 250.0, 500.0, 1000.0]), amplitude=JITTER,
       offset=st.sampled_from(OFFSETS), seed=st.integers(0, 2**16))
def test_jitter_and_epoch_offsets_make_no_gap_but_a_2_s_hole_is_one(rate, amplitude, offset,
                                                                     seed):
    t = jittered(np.arange(0.0, 20.0, 1.0 / rate), amplitude, offset, seed)
    rel, t0 = relative_time(t)
    assert t0 == t[0] and rel[0] == 0.0
    assert not gap_steps(rel).any()
    holed = rel[with_hole(rel, 7.0, 2.0)]
    gaps = find_gaps(holed)
    hole = gaps.ends[0] - gaps.starts[0]  # 2 s plus up to one step, give or take the jitter
    assert gaps.count == 1 and 2.0 - 2 * amplitude <= hole <= 2.0 + 2.0 / rate + 2 * amplitude


def test_unix_time_is_read_relative_to_the_first_row_in_float64(tmp_path):
    flight = generate(FlightSpec(duration=1.0, dt=0.001, seed=1, log_rate=100))
    log = read_table(write_csv(flight, tmp_path / "f.csv"))
    for offset in OFFSETS[1:]:
        back = read_table(write_log(replace(log, t=log.t + offset), tmp_path / f"{offset:g}.parquet"))
        np.testing.assert_allclose(back.t, log.t, rtol=0, atol=1e-6)
        assert back.meta.t_origin == offset


def test_float32_unix_time_is_refused_naming_the_column(tmp_path):
    path = tmp_path / "f32.parquet"
    t = (1.7e9 + np.arange(200) * 0.01).astype(np.float32)
    pq.write_table(pa.table({"t": t, "gyro_x": np.zeros(200), "gyro_y": np.zeros(200),
                             "gyro_z": np.zeros(200), "thrust": np.ones(200),
                             "torque_x": np.zeros(200), "torque_y": np.zeros(200),
                             "torque_z": np.zeros(200)}), path)
    with pytest.raises(LogFormatError, match=r"f32\.parquet: column 't' is stored as 32-bit"):
        read_table(path)


def test_sidecar_inertia_guess_may_be_its_diagonal(tmp_path):
    flight = generate(FlightSpec(duration=1.0, dt=0.001, seed=1, log_rate=100))
    path = write_csv(flight, tmp_path / "f.csv")
    side = Path(str(path) + ".json")
    raw = json.loads(side.read_text())
    raw["inertia_guess"] = [1.6e-5, 1.7e-5, 2.9e-5]
    side.write_text(json.dumps(raw))
    np.testing.assert_array_equal(read_table(path).meta.inertia_guess,
                                  np.diag([1.6e-5, 1.7e-5, 2.9e-5]))
    raw["inertia_guess"] = [1.0, 2.0]
    side.write_text(json.dumps(raw))
    with pytest.raises(LogFormatError, match=r"f\.csv\.json: key 'inertia_guess' is \[1\.0, 2\.0\]"):
        read_table(path)


# ----------------------------------------------------------------- a real IMRC flight

@pytest.fixture(scope="session")
def real_export(tmp_path_factory):
    """jana00's ~500 Hz rows as pinquad's own Parquet log (rotor speeds), its estimate
    with standard errors."""
    assert JANA00.exists(), f"shared IMRC data missing: {JANA00}"
    log = replace(read_log(JANA00), measured=None)
    path = write_log(log, tmp_path_factory.mktemp("imrc") / "jana00.parquet")
    return read_table(path), identify(read_table(path)).run


def _changes(log, base) -> np.ndarray:
    run = identify(log, information=False).run
    new = np.r_[run.mass, np.diag(run.inertia)]
    return np.abs(new - np.r_[base.mass, np.diag(base.inertia)]) / np.asarray(base.stderr)


def _gap_transitions(log) -> int:
    real = build_observations(raw_flight(log))
    return sum(e.transitions for e in real.exclusions if e.kind == "log gaps")


@FEW
@given(offset=st.sampled_from(OFFSETS[1:]))
def test_a_real_flights_estimate_ignores_an_epoch_offset(real_export, offset):
    log, base = real_export
    back = replace(log, t=relative_time(log.t + offset)[0])
    assert _gap_transitions(back) == 0
    assert _changes(back, base).max() <= 0.1


@FEW
@given(amplitude=JITTER, offset=st.sampled_from(OFFSETS), seed=st.integers(0, 100))
def test_a_real_flights_jitter_makes_no_gap_and_keeps_mass_and_roll_pitch_inertia(
        real_export, amplitude, offset, seed):
    log, base = real_export
    moved = replace(log, t=relative_time(jittered(log.t, amplitude, offset, seed))[0])
    assert _gap_transitions(moved) == 0
    assert _changes(moved, base)[:3].max() <= 0.1


def test_a_real_flights_yaw_inertia_ignores_2_ms_jitter(real_export):
    log, base = real_export
    moved = replace(log, t=jittered(log.t, 2e-3, 0.0, seed=2000))
    assert _changes(moved, base)[3] <= 0.1


def _with_2_s_hole(log):
    """The rotor-speed log without its rows of 3-5 s (a logger's 2 s pause)."""
    cut = log.slice(0, log.n)
    keep = with_hole(cut.t, 3.0, 2.0)
    return replace(cut, t=cut.t[keep], position=cut.position[keep],
                   velocity=cut.velocity[keep], euler=cut.euler[keep], gyro=cut.gyro[keep],
                   accel=cut.accel[keep], rpm=cut.rpm[keep],
                   vbat=None if cut.vbat is None else cut.vbat[keep])


def test_a_real_2_s_gap_is_found_and_named(real_export):
    log, _ = real_export
    holed = _with_2_s_hole(log)
    real = build_observations(raw_flight(holed))
    gap = [e for e in real.exclusions if e.kind == "log gaps"]
    assert gap and gap[0].transitions >= 200 and "2.00" in gap[0].reason
    assert real.obs.resets[:-1].sum() >= 200


# ----------------------------------------------------------------- a flightgen flight

@pytest.fixture(scope="session")
def flightgen_export(tmp_path_factory):
    flight = generate(FlightSpec(duration=6.0, dt=0.001, seed=3, log_rate=100))
    path = write_csv(flight, tmp_path_factory.mktemp("fg") / "fg.csv", mass_guess=0.03)
    log = read_table(path)
    return log, identify(log).run


@FEW
@given(amplitude=JITTER, offset=st.sampled_from(OFFSETS), seed=st.integers(0, 100))
def test_a_flightgen_flights_estimate_ignores_jitter_and_epoch_offsets(flightgen_export,
                                                                       amplitude, offset,
                                                                       seed):
    log, base = flightgen_export
    moved = replace(log, t=relative_time(jittered(log.t, amplitude, offset, seed))[0])
    assert not gap_steps(moved.t).any()
    assert _changes(moved, base).max() <= 0.1


def test_a_flightgen_flights_estimate_ignores_3_9_ms_jitter(flightgen_export):
    log, base = flightgen_export
    moved = replace(log, t=relative_time(jittered(log.t, 0.00390625, 0.0, seed=0))[0])
    assert _changes(moved, base).max() <= 0.1


def test_a_flightgen_flights_2_s_gap_is_excluded_and_a_reset(flightgen_export):
    from pinquad.models.sources import observations

    log, _ = flightgen_export
    keep = np.flatnonzero(with_hole(log.t, 2.0, 2.0))
    holed = log.slice(0, log.n)
    holed = replace(holed, t=log.t[keep], position=log.position[keep],
                    velocity=log.velocity[keep], euler=log.euler[keep], gyro=log.gyro[keep],
                    accel=log.accel[keep], thrust=log.thrust[keep], torque=log.torque[keep],
                    truth=None if log.truth is None else log.truth[keep])
    obs = observations(holed, "B")
    assert obs.exclude[:-1].sum() == 1 and obs.resets[:-1].sum() == 1
    assert identify(holed, information=False).run.failure is None


@settings(max_examples=50, deadline=None, derandomize=True, database=None)
@given(amplitude=st.floats(0.0, 4e-3), seed=st.integers(0, 2**16))
def test_held_rotor_acceleration_is_each_bins_change_of_speed_whatever_the_jitter(amplitude,
                                                                                 seed):
    """Speeds held from row to row: a bin's acceleration is (omega(end) - omega(start)) /
    dt; jittered stamps change which row holds at an edge, never divide by a step."""
    from pinquad.realdata.rotor_acceleration import RAD_S_PER_RPM, held_grid_rotor_acceleration

    t = np.arange(0.0, 2.0, 0.002)
    rpm = np.column_stack([19000.0 + 600.0 * t, np.full(t.size, 19000.0),
                           np.full(t.size, 19000.0), 19000.0 - 300.0 * t])
    spin, dt = (-1.0, 1.0, -1.0, 1.0), 0.01
    grid = 0.001 + np.arange(0.0, 1.98, dt)  # edges between rows: each bin 5 steps
    exact = (-600.0 - 300.0) * RAD_S_PER_RPM  # the ramps' sum_i spin_i omega_i'
    clean = held_grid_rotor_acceleration(t, rpm, spin, grid, dt)
    np.testing.assert_allclose(clean[1:-1], exact, rtol=1e-6)
    moved = held_grid_rotor_acceleration(jittered(t, amplitude, 0.0, seed), rpm, spin, grid, dt)
    # at most a few rows' change at each edge (jitter up to 2 steps), over dt
    one_row = 900.0 * 0.002 * RAD_S_PER_RPM / dt
    assert np.nanmax(np.abs(moved[1:-1] - exact)) <= 6 * one_row


def test_a_real_rotor_speed_logs_2_s_gap_converges_near_the_clean_estimate(real_export):
    """The smoother restarts over the gap (``models.ssm.restart_mask``) instead of carrying
    the dynamics blind through 200 steps (where the covariance overflowed): EM converges,
    and without 2 s of the ~9 s flight the estimate stays within a standard error of the
    whole log's (measured: at most 0.3 of one, I_yy)."""
    log, base = real_export
    holed = _with_2_s_hole(log)
    run = identify(holed, information=False).run
    assert run.failure is None and run.converged
    change = (np.abs(np.r_[run.mass, np.diag(run.inertia)]
                     - np.r_[base.mass, np.diag(base.inertia)]) / np.asarray(base.stderr))
    assert change.max() <= 1.0, change
