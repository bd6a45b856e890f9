"""The log's own clock and the grid bins that move continuously with the rows' times
(``pinquad.io.timebase.clock_times``, ``pinquad.realdata.resample``)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.io.read import read_log
from pinquad.io.timebase import clock_times, frame_clock, frame_numbers, grid_times
from pinquad.realdata.resample import at_grid_time, held_average, sample_average

FAST = settings(max_examples=40, deadline=None, derandomize=True, database=None)


@FAST
@given(rate=st.sampled_from([100.0, 250.0, 500.0]), offset=st.sampled_from([0.0, 1e6, 1.7e9]))
def test_evenly_stamped_rows_keep_their_times(rate, offset):
    t = offset + np.arange(0.0, 20.0, 1.0 / rate)
    np.testing.assert_allclose(clock_times(t) - offset, t - offset, rtol=0, atol=1e-6)


@FAST
@given(rate=st.sampled_from([100.0, 500.0]), amplitude=st.floats(0.0, 4e-3),
       seed=st.integers(0, 2**16), dropped=st.lists(st.integers(200, 1700), max_size=3,
                                                    unique=True))
def test_the_clock_takes_out_jitter_and_keeps_dropped_rows(rate, amplitude, seed, dropped):
    """Stamps jittered by uniform(-a, a) (sorted), rows dropped: the clock is back within
    a fraction of the jitter on all but the few rows next to a drop, where the jitter
    itself cannot tell which side a row belongs to."""
    true = np.delete(np.arange(0.0, 20.0, 1.0 / rate), dropped)
    rng = np.random.default_rng(seed)
    stamps = np.sort(true + rng.uniform(-amplitude, amplitude, true.size))
    error = np.abs(clock_times(stamps) - true)
    assert np.sqrt(np.mean(error**2)) <= 0.1 * amplitude + 1e-9
    assert np.mean(error > 0.5 * amplitude + 1e-9) <= 0.01


def test_a_dropped_row_is_not_spread_over_its_neighbours():
    t = np.delete(np.arange(0.0, 10.0, 0.002), [4, 2000])  # one near the start, as IMRC has
    np.testing.assert_allclose(clock_times(t), t, rtol=0, atol=1e-9)


def test_rows_dropped_next_to_an_end_are_found_under_jitter():
    """500 Hz rows with four dropped after the fifth (as the IMRC micro-SD logs have) or
    before the last five, stamps jittered by uniform(-a, a) and sorted: the five rows
    beyond the drop are placed within the jitter (over 20 draws, the median of their
    largest error at most a quarter of a), not a whole drop (8 ms) away. Now and then a
    row next to the drop still falls on its wrong side: the jitter cannot tell."""
    full = np.arange(0.0, 20.0, 0.002)
    for amplitude in (2e-3, 4e-3):
        for gone, outer in ((np.arange(5, 9), slice(0, 5)),
                            (full.size - np.arange(6, 10), slice(-5, None))):
            true = np.delete(full, gone)
            worst = []
            for seed in range(20):
                rng = np.random.default_rng(seed)
                stamps = np.sort(true + rng.uniform(-amplitude, amplitude, true.size))
                worst.append(np.abs(clock_times(stamps) - true)[outer].max())
            assert np.median(worst) <= 0.25 * amplitude


def test_the_grid_passes_through_evenly_stamped_rows_and_covers_them():
    t = 3.0 + np.arange(0.0, 5.0, 0.01)
    np.testing.assert_allclose(grid_times(t, 0.01), t, rtol=0, atol=1e-9)
    odd = 3.0 + np.arange(0.0, 5.0, 0.002) + 0.0013
    grid = grid_times(odd, 0.01)
    assert grid[0] <= odd[0] < grid[0] + 0.01 and grid[-1] <= odd[-1] < grid[-1] + 0.01


def test_one_row_per_bin_is_read_as_it_is():
    t = np.arange(0.0, 2.0, 0.01)
    x = np.column_stack([np.sin(3 * t), np.cos(5 * t)])
    np.testing.assert_array_equal(sample_average(t, x, t - 0.005, 0.01, t.size, 0.01, 0.5), x)
    np.testing.assert_array_equal(sample_average(t, x, t, 0.01, t.size, 0.01, 0.0), x)
    np.testing.assert_allclose(held_average(t, x, t, 0.01, t.size), x, rtol=0, atol=1e-12)


@FAST
@given(shift=st.floats(0.0, 2e-3))
def test_a_bin_moves_continuously_with_its_rows(shift):
    """Rows moved by up to a row step change each bin by at most the samples' largest
    difference times the fraction of a row moved, never by a whole row's reading."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 1.0, 0.002)
    x = rng.normal(size=(t.size, 1))
    start = np.arange(0.0, 0.99, 0.01)
    base = sample_average(t, x, start, 0.01, start.size, 0.002, 0.0)
    moved = sample_average(t + shift, x, start, 0.01, start.size, 0.002, 0.0)
    jump = np.nanmax(np.abs(np.diff(x[:, 0])))
    assert np.nanmax(np.abs(moved - base)) <= jump * shift / 0.002 + 1e-12


def test_a_held_bin_is_the_exact_time_average():
    t = np.array([0.0, 0.004, 0.013, 0.02, 0.03])
    x = np.array([[1.0], [2.0], [3.0], [4.0], [5.0]])
    got = held_average(t, x, np.array([0.0, 0.01]), 0.01, 2)
    np.testing.assert_allclose(got[:, 0], [(1 * 4 + 2 * 6) / 10, (2 * 3 + 3 * 7) / 10])


def test_a_row_flagged_nan_is_a_hole_not_bridged():
    t = np.arange(0.0, 0.1, 0.01)
    x = np.arange(10.0)[:, None]
    x[4] = np.nan
    got = sample_average(t, x, t, 0.01, t.size, 0.01, 0.0)
    assert np.isnan(got[4, 0]) and np.isfinite(np.delete(got[:, 0], 4)).all()


def test_a_pose_is_read_at_its_grid_steps_time_and_angles_wrap():
    times = np.array([0.0, 0.012, 0.021])
    values = np.array([[3.1], [-3.1], [-3.0]])
    grid = np.array([0.01])
    got = at_grid_time(grid, times, values, np.array([0]), np.array([1]), 0.1, angle=True)
    # from -3.1 at 12 ms back towards 3.1 at 0 ms, the short way round through pi
    expected = -3.1 - (2 * np.pi - 6.2) * (0.002 / 0.012)
    np.testing.assert_allclose(got[0, 0], expected, atol=1e-12)


def _lossy_stream(rate: float, keep: float, seconds: float, rng: np.random.Generator
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(frame numbers kept, their true times [s]): a stream taken at ``rate`` Hz whose
    frames each arrive with probability ``keep`` (the first always)."""
    frames = np.arange(int(seconds * rate))
    kept = frames[(rng.random(frames.size) < keep) | (frames == 0)]
    return kept, kept / rate


@FAST
@given(rate=st.sampled_from([50.0, 101.1, 120.0, 240.0]), keep=st.floats(0.4, 1.0),
       jitter=st.floats(0.0, 0.3), offset=st.sampled_from([0.0, 1.7e9]),
       seed=st.integers(0, 2**16))
def test_a_lossy_stream_is_numbered_by_its_frames_and_its_jitter_taken_out(
        rate, keep, jitter, offset, seed):
    """Stamps of a fixed-rate stream with frames lost (a motion-capture stream over
    radio), jittered by uniform(-a, a) with a up to 0.3 frame periods and put in Unix
    time: every frame number is found (up to a constant) and the clock is back within a
    fraction of the jitter."""
    rng = np.random.default_rng(seed)
    frames, true = _lossy_stream(rate, keep, 12.0, rng)
    amplitude = jitter / rate
    stamps = np.sort(true + rng.uniform(-amplitude, amplitude, true.size)) + offset
    numbers = frame_numbers(stamps)
    assert numbers is not None
    np.testing.assert_array_equal(numbers - numbers[0], frames - frames[0])
    clock = frame_clock(stamps)
    assert clock is not None
    error = clock - offset - true
    assert np.sqrt(np.mean(error**2)) <= 0.15 * amplitude + 1e-7


@FAST
@given(seed=st.integers(0, 2**16))
def test_stamps_on_no_frame_lattice_have_no_frame_clock(seed):
    """Stamps at random times (a Poisson stream) are no lossy fixed-rate stream: no frame
    clock, so their own stamps are kept."""
    rng = np.random.default_rng(seed)
    stamps = np.cumsum(rng.exponential(0.01, 1000))
    assert frame_numbers(stamps) is None
    assert frame_clock(stamps) is None


REAL_FLIGHTS = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed"


@cache
def _pose_stamps(name: str) -> np.ndarray:
    """The motion-capture stamps [s] of a shared IMRC micro-SD log (fails without the
    data)."""
    path = REAL_FLIGHTS / name
    assert path.is_file(), f"the Crazyflie data are missing: {path}"
    measured = read_log(path).measured
    assert measured is not None and measured.pose_t is not None
    return measured.pose_t


@settings(max_examples=8, deadline=None, derandomize=True, database=None)
@given(name=st.sampled_from(["jana04", "jana27"]), amplitude=st.floats(0.5e-3, 3e-3),
       seed=st.integers(0, 2**16), offset=st.sampled_from([0.0, 1.7e9]))
def test_a_real_pose_streams_frame_clock_does_not_see_stamp_jitter(name, amplitude, seed,
                                                                   offset):
    """The real motion-capture streams of a long yaw flight (jana04, 2816 poses) and a
    random flight (jana27): their stamps jittered by uniform(-a, a) (a up to 3 ms, 0.3 of
    a frame; sorted) and put in Unix time give the same frame numbers to 0.2 % of the
    poses and, on the others, a clock within 0.15 ms rms of the unjittered stamps'
    clock."""
    stamps = _pose_stamps(name)
    clean = frame_clock(stamps)
    assert clean is not None
    rng = np.random.default_rng(seed)
    moved = np.sort(stamps + rng.uniform(-amplitude, amplitude, stamps.size)) + offset
    numbers, clean_numbers = frame_numbers(moved), frame_numbers(stamps)
    assert numbers is not None and clean_numbers is not None
    wrong = (numbers - numbers[0]) != (clean_numbers - clean_numbers[0])
    assert wrong.mean() <= 0.002
    clock = frame_clock(moved)
    assert clock is not None
    # a pose numbered one frame off is placed a frame (9.9 ms) off: counted above
    error = (clock - offset - clean)[~wrong]
    assert np.sqrt(np.mean(error**2)) <= 0.15e-3
