"""What ``python -m pinquad.offline --log`` prints by default: the answer a person reads in
ten seconds. One line per parameter of the headline estimate (value ± total standard
error, unit, verdict, the one main reason when not trusted; the ten-parameter model's
centre of mass and products of inertia in one line each), the vehicle's reference
values when its file has them, one line per effect found (or why none), and a warning when
an assumption moves every number (the thrust coefficient not from a thrust stand, no
vehicle named). Everything else (each run's table, every reason, the error budget, the
null calibration, residual RMS, exclusions and notes) is in report.md / report.json and
printed by ``--explain`` (``pinquad.report.recorded``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from pinquad.core.vehicle_file import is_vehicle_file, load_vehicle
from pinquad.identification.identify import Identification
from pinquad.identification.verdict import PRODUCTS, EstimateVerdict
from pinquad.io.datadir import FETCH_COMMAND
from pinquad.pipeline.identify import LogResult
from pinquad.pipeline.judge import Headline, VehicleEstimate

WIDTH = 120
"""The longest printed line [characters]: a reason is shortened to fit."""

PARAMETERS = (("mass", 1e3, "g"), ("I_xx", 1e6, "e-6 kg m^2"), ("I_yy", 1e6, "e-6 kg m^2"),
              ("I_zz", 1e6, "e-6 kg m^2"))
"""The headline's parameters as printed: name, scale from SI, unit."""

_ASIDE = re.compile(r"\s*\([^()]*\)")


def shortened(text: str, width: int) -> str:
    """``text`` in at most ``width`` characters: its parenthesised asides dropped (innermost
    first), then cut at a word boundary with an ellipsis."""
    short = text
    while _ASIDE.search(short):
        short = _ASIDE.sub("", short)
    short = " ".join(short.split())
    if len(short) <= width:
        return short
    cut = short[: width - 3].rsplit(" ", 1)[0].rstrip(",;:")
    return cut + "..."


def _number(value: float, stderr: float, scale: float) -> str:
    """``value ± stderr`` scaled, the error to two significant digits and the value to the
    same decimal place (four significant digits when there is no error)."""
    if not (np.isfinite(stderr) and stderr > 0):
        return f"{value * scale:.4g}"
    decimals = max(0, 1 - int(np.floor(np.log10(stderr * scale))))
    return f"{value * scale:.{decimals}f} ± {stderr * scale:.{decimals}f}"


def parameter_lines(estimate: VehicleEstimate) -> list[str]:
    """One line per parameter: ``name  value ± total error unit  verdict: main reason``."""
    values = np.r_[estimate.mass, np.diag(estimate.inertia)]
    lines = []
    for (name, scale, unit), value, stderr in zip(PARAMETERS, values, estimate.stderr,
                                                  strict=True):
        verdict = estimate.verdict.get(name)
        head = f"  {name:<6}{_number(value, stderr, scale) + ' ' + unit:<24}{verdict.verdict}"
        if not verdict.trusted and verdict.reasons:
            head += ": " + shortened(verdict.reasons[0], max(WIDTH - len(head) - 2, 20))
        lines.append(head)
    return lines


def full_lines(run: Identification, verdict: EstimateVerdict) -> list[str]:
    """The ten-parameter model's centre of mass [mm] and products of inertia [1e-6 kg
    m^2], one line each: value ± standard error, or the value with its verdict."""
    full = run.full
    assert full is not None
    asked = np.isfinite(full.stderr_mass)
    com = ", ".join(
        f"c_{'xyz'[i]} {_number(full.com[i], full.stderr_com[i], 1e3)}"
        + (" (not identifiable)" if asked and not np.isfinite(full.stderr_com[i]) else "")
        for i in range(3))
    products = []
    for name, i, j in PRODUCTS:
        v = verdict.get(name)
        value, se = full.inertia[i, j], full.stderr_inertia[i, j]
        products.append(f"{name} " + (_number(value, se, 1e6) if v.trusted
                                      else f"{value * 1e6:.3g} ({v.verdict})"))
    return [f"  centre of mass: {com} mm",
            f"  products of inertia: {', '.join(products)} e-6 kg m^2"]


def reference_line(result: LogResult) -> str | None:
    """The vehicle file's reference values (a scale's mass, a published inertia), when the
    log's vehicle has them."""
    vehicle = result.log.meta.vehicle
    if not (vehicle == "crazyflie21" or is_vehicle_file(vehicle)):
        return None
    ref = load_vehicle(vehicle).reference
    if ref is None:
        return None
    parts = []
    if ref.mass is not None:
        parts.append(f"mass {ref.mass * 1e3:.4g} g")
    if ref.inertia is not None:
        parts.append("inertia " + ", ".join(f"{v * 1e6:.4g}" for v in ref.inertia)
                     + " e-6 kg m^2")
    name = Path(vehicle).name if is_vehicle_file(vehicle) else vehicle
    return f"  reference ({name}): {'; '.join(parts)}" if parts else None


def _coefficients(selected: dict) -> str:
    # "-": a dimensionless coefficient, printed without a unit
    units = {n: "" if u == "-" else f" {u}" for n, u in selected["units"].items()}
    one = set(units.values()).pop() if len(set(units.values())) == 1 else None
    text = ", ".join(f"{n} {v:.3g} ± {selected['stderr'][n]:.2g}"
                     + ("" if one is not None else units[n])
                     for n, v in selected["coefficients"].items())
    return text + (one or "")


def effect_lines(section: dict | None, skipped: str | None) -> list[str]:
    """One line per effect discovery kept, or one saying why there is none; nothing when
    discovery was not asked for."""
    width = WIDTH - len("effects: not looked for: ")
    if skipped is not None:
        return [f"effects: not looked for: {shortened(skipped, width)}"]
    if section is None:
        return []
    if section.get("not_run"):
        return [f"effects: not looked for: {shortened(section['not_run'], width)}"]
    if "error" in section:
        return [f"effects: discovery failed: {shortened(section['error'], width)}"]
    lines = [shortened(f"effect {s['effect']}: {_coefficients(s)}; held-out gain "
                       f"{100 * s['evidence']['heldout_gain']:.0f} %", WIDTH)
             for s in section["selected"]]
    if not lines:
        odd = [e["effect"] for e in section.get("unphysical", ())]
        lines = ["effects: none found" + (f" (best fit outside its physical domain, not "
                                          f"kept: {', '.join(odd)})" if odd else "")]
    if section.get("note"):
        lines.append(f"  note: {shortened(section['note'], WIDTH - 8)}")
    return lines


def warning_lines(result: LogResult) -> list[str]:
    """Assumptions that move every number, said where a person reads: a thrust coefficient
    not from a thrust stand (its assumed error is in the budget), no vehicle named."""
    lines = []
    kf = result.kf
    if kf is not None and kf.missing_stand is not None:
        lines.append(f"warning: no thrust-stand data found: kf = {kf.kf:.4g} N/(rad/s)^2 "
                     f"± {100 * kf.rel_se:.0f} % assumed, and mass and inertia scale with it; "
                     f"`{FETCH_COMMAND}` gets the stand's runs")
    if result.vehicle_unnamed:
        lines.append("warning: no vehicle named: judged against no vehicle's range (name it "
                     "in the sidecar's \"vehicle\" or with --vehicle)")
    return lines


def console_summary(result: LogResult, headline: Headline, source: str, seconds: float,
                    section: dict | None, skipped: str | None) -> str:
    """The default printed report of one log (module docstring)."""
    final = headline.final
    lines = [f"{Path(source).name}: {result.contents}; {result.obs.n} steps of "
             f"{result.obs.dt * 1e3:.0f} ms; EM {seconds:.1f} s",
             f"estimate ({final.model}): {final.verdict.overall}",
             *parameter_lines(final)]
    run = result.runs[0]
    if run.full is not None:  # the ten-parameter model: its CoM and products too
        lines += full_lines(run, headline.run_verdicts[0])
    ref = reference_line(result)
    if ref is not None:
        lines.append(ref)
    lines += effect_lines(section, skipped)
    lines += warning_lines(result)
    return "\n".join(lines)
