"""What ``offline --log`` prints by default (``pinquad.report.console``): one line per
parameter and per effect, every line short; ``--explain`` (``Result.explain``) the whole
report as report.md has it."""

from __future__ import annotations

import numpy as np
import pytest

from pinquad.cli.offline import build_parser
from pinquad.report.console import WIDTH, _number, effect_lines, shortened


def test_a_reason_loses_its_asides_first_then_is_cut_at_a_word():
    reason = ("its +-2 standard errors (12.7 e-6 kg m^2 each) cover 46.3 % of the vehicle's "
              "range 7.32-117 e-6 kg m^2 (at most 25 %)")
    assert shortened(reason, 200) == ("its +-2 standard errors cover 46.3 % of the vehicle's "
                                      "range 7.32-117 e-6 kg m^2")
    short = shortened(reason, 40)
    assert len(short) <= 40 and short.endswith("...") and "(" not in short
    assert shortened("a (b (c) d) e", 50) == "a e"


def test_a_number_carries_its_error_to_two_digits_and_the_value_to_the_same_place():
    assert _number(0.034676, 0.001682, 1e3) == "34.7 ± 1.7"
    assert _number(0.17998, 0.000053, 1e3) == "179.980 ± 0.053"
    assert _number(30.55e-6, 12.7e-6, 1e6) == "31 ± 13"
    assert _number(1.2345, float("nan"), 1.0) == "1.234"  # no error: four digits, no ±


def test_one_line_per_effect_or_one_saying_why_there_is_none():
    drag = {"effect": "drag", "coefficients": {"D_x": 0.01582, "D_y": 0.01579},
            "stderr": {"D_x": 0.0017, "D_y": 0.002}, "units": {"D_x": "N s/m", "D_y": "N s/m"},
            "evidence": {"heldout_gain": 0.271}}
    wind = {"effect": "wind", "coefficients": {"w_x": -0.004}, "stderr": {"w_x": 0.00091},
            "units": {"w_x": "N"}, "evidence": {"heldout_gain": 0.36}}
    lines = effect_lines({"selected": [drag, wind]}, None)
    assert lines == ["effect drag: D_x 0.0158 ± 0.0017, D_y 0.0158 ± 0.002 N s/m; held-out "
                     "gain 27 %", "effect wind: w_x -0.004 ± 0.00091 N; held-out gain 36 %"]
    ground = {"effect": "ground_effect", "coefficients": {"k_ge": 5.907}, "units": {"k_ge": "-"},
              "stderr": {"k_ge": 0.2}, "evidence": {"heldout_gain": 0.79}}
    assert effect_lines({"selected": [ground]}, None) == [
        "effect ground_effect: k_ge 5.91 ± 0.2; held-out gain 79 %"]  # dimensionless
    assert effect_lines({"selected": [], "unphysical": [{"effect": "drag"}]}, None) == [
        "effects: none found (best fit outside its physical domain, not kept: drag)"]
    not_run = effect_lines({"selected": [], "not_run": "the base fit did not converge (EM "
                            "stopped at its E-step limit): discovery needs " + "x " * 80}, None)
    assert len(not_run) == 1 and not_run[0].startswith("effects: not looked for: the base fit "
                                                       "did not converge: discovery needs")
    assert len(not_run[0]) <= WIDTH
    assert effect_lines(None, None) == []  # not asked for: nothing said


def test_explain_is_an_option_of_the_log_command():
    assert build_parser().parse_args(["--log", "x.csv", "--explain"]).explain
    assert not build_parser().parse_args(["--log", "x.csv"]).explain


@pytest.fixture(scope="module")
def short_result():
    """A 8 s simulated sensor-B flight through the pipeline (no null calibration)."""
    import pinquad
    from pinquad.pipeline.identify import LogOptions
    from pinquad.pipeline.single import PipelineOptions, run

    log = pinquad.simulate(sensor="B", seed=0).slice(0, 800)
    return pinquad.Result.of(run(log, PipelineOptions(LogOptions(msteps=("regressor",)),
                                                      pinquad.NullSettings(replicates=0))))


def test_the_default_report_is_a_few_short_lines_and_explain_has_the_rest(short_result):
    summary = short_result.summary().splitlines()
    assert len(summary) <= 10 and max(len(line) for line in summary) <= WIDTH
    params = [line.split()[0] for line in summary if line.startswith("  ")]
    assert params[:4] == ["mass", "I_xx", "I_yy", "I_zz"]
    estimate = short_result.estimate
    for name, line in zip(params[:4], summary[2:6], strict=True):
        assert estimate.verdict.get(name).verdict in line
    assert summary[1].endswith(estimate.verdict.overall)
    mass_g = float(summary[2].split()[1])
    assert mass_g == pytest.approx(estimate.mass * 1e3, abs=0.05 * estimate.stderr[0] * 1e3)
    explain = short_result.explain()
    # the long parts live there: the runs' table, every reason, the error budget
    for part in ("| sensor | M-step |", "| B | regressor |", "headline (", "verdict: ",
                 "error budget (standard errors"):
        assert part in explain and part not in short_result.summary()
    assert len(explain.splitlines()) > len(summary)
    assert np.isfinite(estimate.stderr).all()


def test_the_ten_parameter_model_prints_its_centre_of_mass_and_products_in_a_line_each():
    """Values with their errors; an untrusted product with its verdict, not an error bar;
    a CoM the likelihood leaves flat says so."""
    from types import SimpleNamespace

    from pinquad.report.console import full_lines

    inertia = np.array([[250e-6, 1.2e-6, -0.4e-6], [1.2e-6, 310e-6, 0.1e-6],
                        [-0.4e-6, 0.1e-6, 200e-6]])
    full = SimpleNamespace(com=np.array([0.004, -0.003, 0.002]), stderr_mass=1e-4,
                           stderr_com=np.array([1e-4, 1e-4, np.nan]), inertia=inertia,
                           stderr_inertia=np.full((3, 3), 0.2e-6))
    verdicts = {"I_xy": "trusted", "I_xz": "not identifiable", "I_yz": "trusted"}
    verdict = SimpleNamespace(get=lambda n: SimpleNamespace(
        verdict=verdicts[n], trusted=verdicts[n] == "trusted"))
    com, products = full_lines(SimpleNamespace(full=full), verdict)
    assert com == ("  centre of mass: c_x 4.00 ± 0.10, c_y -3.00 ± 0.10, "
                   "c_z 2 (not identifiable) mm")
    assert products == ("  products of inertia: I_xy 1.20 ± 0.20, I_xz -0.4 (not "
                        "identifiable), I_yz 0.10 ± 0.20 e-6 kg m^2")
