"""The flightgen discovery Monte Carlo's floor-strike condition: its flights and how
they are counted (the runs themselves: ``python -m pinquad.discovery --generator
flightgen --conditions floor_strikes``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from flightgen import generate
from flightgen.rotation import quats_to_rots
from flightgen.vehicle import GRAVITY
from pinquad.experiments import discovery_mc_flightgen as fgmc
from pinquad.report.discovery_mc_flightgen import flightgen_mc_markdown


def _case(condition: str, seed: int, selected=(), contact=(0, 0, 0, 0)) -> fgmc.FlightgenCase:
    return fgmc.FlightgenCase(condition, 100, seed, seed % 1000, 30.0, True, "sines",
                              tuple(selected), {}, math.nan, math.nan, (0.0,) * 4, (0.0,) * 4,
                              1.0, (), {"mass": "trusted"}, *contact)


def test_floor_strike_flights_touch_the_floor_and_carry_no_effect():
    spec = fgmc.flight_spec(fgmc.FLOOR_CONDITION, 7000, 0, 100)
    assert spec.start_on_floor and spec.land and spec.floor_strikes == 2
    assert spec.floor is not None
    assert fgmc.injected(fgmc.FLOOR_CONDITION) == {}
    clean = fgmc.flight_spec("none", 0, 0, 100)
    assert clean.floor is None and not clean.start_on_floor
    # the seeds of the other conditions did not move when the condition was added
    assert fgmc.case_seed(0, "gyro_bias", 3) == 6003
    assert fgmc.case_seed(0, fgmc.FLOOR_CONDITION, 3) == 7003


def test_floor_rows_count_contact_against_the_truth():
    cases = [_case(fgmc.FLOOR_CONDITION, 7000, (), (388, 382, 6, 60)),
             _case(fgmc.FLOOR_CONDITION, 7001, ("ground_effect",), (390, 390, 0, 70)),
             _case("none", 1)]
    rows = {r["condition"]: r for r in fgmc.summarize(cases)}
    floor = rows[fgmc.FLOOR_CONDITION]
    assert floor["contact"] == {"true": 778, "found": 772, "missed": 6, "off": 130}
    assert floor["contact_all_found"] == 1
    assert floor["nothing_selected"] == 1 and floor["extra_selected"] == ["ground_effect"]
    assert "named" not in floor and "contact" not in rows["none"]
    text = flightgen_mc_markdown(list(rows.values()))
    assert "| 100 Hz | 2 | 1/2 | ground_effect | 778 | 772 | 6 | 130 | 1/2 |" in text


def test_true_contact_transitions_mark_every_log_interval_that_touches():
    class Flight:  # the two attributes true_contact_transitions reads
        class spec:
            log_rate, dt = 100, 0.0025  # 4 integrator steps per log row
        in_contact = np.zeros(40, dtype=bool)

    Flight.in_contact[9] = True  # inside transition 2 -> 3
    Flight.in_contact[20] = True  # the end of transition 4 -> 5 (row 5's instant)
    marked = fgmc.true_contact_transitions(Flight, 10)
    assert np.flatnonzero(marked).tolist() == [2, 4, 5]


def test_flightgen_runs_merge_and_a_wrong_kind_of_file_is_an_input_error(tmp_path, capsys):
    from pinquad.cli import discovery

    first, second = tmp_path / "a", tmp_path / "b"
    for d in (first, second):
        d.mkdir()
    fgmc.append_case(first, _case(fgmc.FLOOR_CONDITION, 7000, (), (388, 382, 6, 60)))
    fgmc.append_case(first, _case(fgmc.FLOOR_CONDITION, 7001, ("motor_lag",), (390, 390, 0, 70)))
    # a later run's case of the same condition, rate and seed replaces the earlier one
    fgmc.append_case(second, _case(fgmc.FLOOR_CONDITION, 7001, (), (390, 390, 0, 70)))
    code = discovery.main(["--generator", "flightgen", "--merge", str(first / "cases.jsonl"),
                           str(second / "cases.jsonl"), "--out", str(tmp_path / "merged")])
    assert code == 0
    assert "| 100 Hz | 2 | 2/2 | - | 778 | 772 | 6 | 130 | 1/2 | 0: 0 |" in capsys.readouterr().out
    assert (tmp_path / "merged" / "discovery_mc_flightgen.md").exists()
    assert discovery.main(["--merge", str(first / "cases.jsonl")]) == 2
    assert "--generator flightgen" in capsys.readouterr().err


def test_coefficients_are_scored_against_their_printed_standard_errors():
    drag = list(fgmc.injected("drag").values())  # D_x, D_y, D_z [N s/m]

    def case(seed, coefs, se):
        c = _case("drag", seed, ("drag",))
        return fgmc.FlightgenCase(**{**c.__dict__, "coefficients": {"drag": coefs},
                                     "coef_rel_err": 0.0, "coef_stderr": se})

    off = [drag[0], drag[1], 1.133 * drag[2]]  # D_z 13.3 % high, like flight 1007
    cases = [case(1000, drag, {"drag": [1e-5] * 3}),
             case(1001, off, {"drag": [1e-5, 1e-5, 0.039 * drag[2]]}),  # 3.4 se: not covered
             case(1002, off, {"drag": [1e-5, 1e-5, 0.07 * drag[2]]}),  # 1.9 se: covered
             case(1003, drag, None)]  # a run from before the standard errors were kept
    assert [fgmc.within_stderr(c, 2.0) for c in cases] == [True, False, True, None]
    row = fgmc.summarize(cases)[0]
    assert (row["coef_within_2se"], row["coef_with_stderr"]) == (2, 3)
    # rms of z over the three with errors: D_x, D_y exact; D_z 0, 3.41, 1.90 se
    z_dz = 0.133 * drag[2] / np.array([0.039 * drag[2], 0.07 * drag[2]])
    np.testing.assert_allclose(row["coef_z_rms"], [0.0, 0.0, np.sqrt(np.sum(z_dz**2) / 3)])
    assert "| 4/4 | 2/3 | 0, 0, 2.3 |" in flightgen_mc_markdown([row])
    unnamed = fgmc.FlightgenCase(**{**cases[0].__dict__, "selected": (), "coefficients": {}})
    assert fgmc.within_stderr(unnamed, 2.0) is False


def test_noise_only_drag_error_is_the_least_squares_d_z_of_the_truths_own_forces():
    """The noise-only error is that of D_z fitted to the truth's body-z force: m (R^T (a + g e3))_z minus
    the commanded thrust is n - D_z v_z on a drag flight (no floor, no other effect)."""
    spec = dataclasses.replace(fgmc.flight_spec("drag", 1007, 7, 100), duration=3.0)
    flight = generate(spec)
    rots = quats_to_rots(flight.state[:, 6:10])
    specific = flight.accel_world + np.array([0.0, 0.0, GRAVITY])
    force_z = spec.vehicle.mass * np.einsum("nj,nj->n", rots[:, :, 2], specific)
    residual = force_z - flight.command[:, 0]
    v_z = np.einsum("nj,nj->n", rots[:, :, 2], flight.state[:, 3:6])
    d_z = spec.effects.drag[2]
    fitted = -(residual @ v_z) / (v_z @ v_z)
    noise_only = fgmc.noise_only_drag_error(flight)
    assert abs(noise_only) > 1e-3  # 3 s of thrust noise leaves a visible error
    assert math.isclose(fitted / d_z - 1.0, noise_only, rel_tol=1e-6, abs_tol=1e-9)
    assert math.isnan(fgmc.noise_only_drag_error(
        generate(dataclasses.replace(fgmc.flight_spec("none", 0, 0, 100), duration=0.5))))


def test_drag_rows_count_what_the_thrust_noise_alone_leaves_within_10_percent():
    cases = [fgmc.FlightgenCase(**{**_case("drag", 1000 + i).__dict__,
                                   "noise_only_err": e})
             for i, e in enumerate((0.125, -0.02, -0.115, 0.05))]
    row = fgmc.summarize(cases)[0]
    assert (row["noise_only_within_10pct"], row["noise_only_n"]) == (2, 4)
    assert "the thrust noise alone: 2/4" in flightgen_mc_markdown([row])
