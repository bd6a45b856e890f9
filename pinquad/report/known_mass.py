"""The known-mass identification's printed table and report.json
(``pinquad.identification.known_mass``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pinquad.core.actuator_curve import CurveVehicle
from pinquad.identification.excitation import Excitation
from pinquad.identification.known_mass import KnownMassResult
from pinquad.identification.known_mass_em import KnownMassEM
from pinquad.identification.verdict import Estimate

INERTIA = ("I_xx", "I_yy", "I_zz")


def _num(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.5g}"


def _estimate_lines(estimates: tuple[Estimate, ...], ref) -> list[str]:
    lines = [f"{'estimate':<17} {'value':>10} {'se':>10} {'reference':>10} {'error':>7}  "
             "verdict", "-" * 75]
    for e in estimates:
        truth = ref[INERTIA.index(e.name)] if ref is not None and e.name in INERTIA else None
        err = "" if truth is None or not math.isfinite(e.value) else \
            f"{(e.value / truth - 1) * 100:+.1f}%"
        lines.append(f"{e.name:<17} {_num(e.value):>10} {_num(e.stderr):>10} "
                     f"{'' if truth is None else _num(truth):>10} {err:>7}  {e.verdict} "
                     f"[{e.unit}]")
        if e.parts:
            lines.append("    se parts: " + ", ".join(f"{k} {_num(v)}" for k, v in e.parts))
        lines += [f"    why: {r}" for r in e.reasons]
    return lines


def _side_by_side(result: KnownMassResult, em: KnownMassEM, ref) -> list[str]:
    """One row per inertia entry: regression, EM, naive and the reference."""

    def cell(e: Estimate, truth: float | None) -> str:
        if not math.isfinite(e.value):
            return f"{'-':>10} {'':>7} {e.verdict:<19}"
        err = "" if truth is None else f"{(e.value / truth - 1) * 100:+.1f}%"
        return f"{_num(e.value):>10} {err:>7} {e.verdict:<19}"

    lines = ["", "side by side (inertia [kg m^2]; error against the reference):",
             f"{'':<5} {'regression':>10} {'':>7} {'':<19} {'EM':>10} {'':>7} {'':<19} "
             f"{'naive':>10} {'':>7} {'reference':>10}"]
    for a, name in enumerate(INERTIA):
        truth = None if ref is None else float(ref[a])
        naive = result.naive_inertia[a]
        naive_err = "" if truth is None or not math.isfinite(naive) else \
            f"{(naive / truth - 1) * 100:+.1f}%"
        lines.append(f"{name:<5} {cell(result.get(name), truth)} {cell(em.get(name), truth)} "
                     f"{_num(naive):>10} {naive_err:>7} {'' if truth is None else _num(truth):>10}")
    return lines


def known_mass_table(result: KnownMassResult, vehicle: CurveVehicle,
                     em: KnownMassEM | None = None) -> str:
    """Estimate, total se, its parts, reference (the vehicle file's [reference] inertia),
    verdict and reasons of the regression, then the naive regression beside it; with
    ``em``, the EM route's estimates the same way and the three side by side."""
    ref = vehicle.spec.reference.inertia
    lines = [f"known mass {result.mass:g} +- {result.mass_se:.2g} kg; torque band {result.band[0]:g}-"
             f"{result.band[1]:g} Hz; the curve explains {result.force_share * 100:.1f} % of "
             "the vertical force", "", "regression:",
             *_estimate_lines(result.estimates, ref)]
    lines += ["", "naive regression (no motor lag, no drag, no filter, raw d omega/dt):"]
    for a, name in enumerate(INERTIA[:2]):
        truth = None if ref is None else ref[a]
        err = "" if truth is None else f" ({(result.naive_inertia[a] / truth - 1) * 100:+.1f} %)"
        lines.append(f"  {name} {_num(result.naive_inertia[a])}{err}, torque explains "
                     f"{result.naive_share[a] * 100:.0f} % of the angular acceleration's "
                     "variance")
    if em is not None:
        lines += ["", f"EM (E-step over {', '.join(em.channels)}; the thrust curve's scale s "
                  f"= m / m_hat, I = s I_hat; {em.iterations} iterations, "
                  f"{'converged' if em.converged else 'not converged'}; {em.seconds:.0f} s with "
                  "its reruns for the assumptions' error parts and the band halves):",
                  *_estimate_lines(em.estimates, ref), *_side_by_side(result, em, ref)]
    lines += ["", *(f"note: {n}" for n in result.notes)]
    if em is not None:
        lines += [f"note: {n}" for n in em.notes]
    return "\n".join(lines)


def headline_trusted(result: KnownMassResult, em: KnownMassEM | None = None) -> bool:
    """Whether every estimate that could be had (a value), by either route, is trusted."""
    routes = (result.estimates, *(() if em is None else (em.estimates,)))
    return all(e.trusted for est in routes for e in est if math.isfinite(e.value))


def _estimates_json(estimates: tuple[Estimate, ...]) -> list[dict]:
    return [{"name": e.name, "value": e.value, "unit": e.unit, "stderr": e.stderr,
             "stderr_parts": dict(e.parts), "verdict": e.verdict, "reasons": list(e.reasons)}
            for e in estimates]


SHARED = ("thrust c_1", "thrust c_2", "time constant", "I_xx", "I_yy", "I_zz")
"""The vehicle's estimates a joint fit of several logs shares (the curve's thrust and
slope at the mean command are left out: each fit's mean command is its own)."""


def joint_comparison(names: list[str], separate: list[KnownMassResult | str],
                     joint: KnownMassResult) -> str:
    """Each shared estimate of every log's own fit beside the joint fit's: value +- total
    se (verdict), and the largest distance of a log's value from the joint one in
    combined total errors (sqrt(se_log^2 + se_joint^2); the joint fit uses the same rows,
    so this understates the distance: a value over 2 is a log that disagrees). A log
without a fit of its own (``separate`` holds why, a string) shows '-'."""
    lines = ["joint fit against each log's own (value +- total se, verdict; max |log - "
             "joint| in combined total errors):"]
    for name in SHARED:
        cells, worst = [], 0.0
        j = next((e for e in joint.estimates if e.name == name), None)
        for log_name, res in zip(names, separate, strict=True):
            e = None if isinstance(res, str) else next(
                (e for e in res.estimates if e.name == name), None)
            if e is None or not math.isfinite(e.value):
                cells.append(f"{Path(log_name).name} -")
                continue
            cells.append(f"{Path(log_name).name} {_num(e.value)} +- {_num(e.stderr)} ({e.verdict})")
            if j is not None and math.isfinite(j.value):
                worst = max(worst, abs(e.value - j.value) / math.hypot(e.stderr, j.stderr))
        if j is None:
            continue
        lines.append(f"  {name}: " + "; ".join(cells) + f"; joint {_num(j.value)} +- "
                     f"{_num(j.stderr)} ({j.verdict}); max {worst:.1f}")
    return "\n".join(lines)


def known_mass_report(result: KnownMassResult, log_path: str, vehicle: CurveVehicle,
                      seconds: float, em: KnownMassEM | None = None,
                      separate: list[KnownMassResult | str] | None = None,
                      segments: list[list[tuple[float, float]]] | None = None,
                      excitation: list[Excitation | None] | None = None) -> dict:
    """report.json (the house's keys, the headline the regression's; the known-mass
    specifics under ``known_mass``, the EM route's under ``known_mass.em``; with several
    logs the headline is the joint fit and each log's own under ``known_mass.separate``;
    ``known_mass.segments``: the fitted rows per log (lo, hi) [s, the log's clock];
    ``known_mass.excitation``: per log its flight segments and useful excitation ranges
    per axis, or None)."""
    inertia = np.array([result.get(n).value for n in INERTIA])
    inertia_se = [result.get(n).stderr for n in INERTIA]
    em_block = ({"iterations": 0, "loglik": [], "converged": None,
                 "note": "known-mass regression only: no EM was run"} if em is None else
                {"iterations": em.iterations, "loglik": em.loglik.tolist(),
                 "converged": em.converged,
                 "note": "the known-mass EM route (known_mass.em); the headline is the "
                         "regression's"})
    known = {
        "estimates": _estimates_json(result.estimates),
        "vertical_force_share": result.force_share,
        "torque_share": list(result.torque_share),
        "band_hz": list(result.band),
        "naive": {"inertia_diag": result.naive_inertia.tolist(),
                  "torque_share": list(result.naive_share)},
        "notes": list(result.notes), "seconds": seconds,
    }
    if separate is not None:
        known["separate"] = [{"not_fitted": r} if isinstance(r, str) else {
            "estimates": _estimates_json(r.estimates), "vertical_force_share": r.force_share}
            for r in separate]
    if segments is not None:
        known["segments"] = [[list(s) for s in log] for log in segments]
    if excitation is not None:
        known["excitation"] = [None if e is None else {
            "flight_segments": [list(t) for t in e.segment_times],
            "ranges": {k: [list(r) for r in v] for k, v in e.ranges.items()},
            "window_s": e.window, "band_hz": list(e.band)} for e in excitation]
    if em is not None:
        known["em"] = {"estimates": _estimates_json(em.estimates), "mass_hat": em.mass_hat,
                       "inertia_hat_diag": em.inertia_hat.tolist(),
                       "nominal_curve": em.nominal.tolist(),
                       "nominal_source": em.nominal_source, "time_constant": em.tau,
                       "channels": list(em.channels), "iterations": em.iterations,
                       "converged": em.converged, "failure": em.failure,
                       "seconds": em.seconds, "notes": list(em.notes)}
    return {
        "schema": "pinquad.report/1",
        "source": {"kind": "log", "path": log_path, "sensor": None,
                   "estep": None if em is None else "rts",
                   "method": "known-mass regression" + ("" if em is None else " and EM"),
                   "vehicle": str(vehicle.spec.source)},
        "estimates": {
            "mass": result.mass, "inertia": np.diag(inertia).tolist(), "com": None,
            # the mass is given: its error is the uncertainty assumed for it
            "stderr": {"mass": result.mass_se, "inertia_diag": inertia_se},
            "stderr_parts": {n: dict(result.get(n).parts) for n in INERTIA},
            "verdict": {e.name: {"verdict": e.verdict, "reasons": list(e.reasons)}
                        for e in result.estimates},
        },
        "em": em_block,
        "discovery": {"selected": [], "not_run": "known-mass mode: no effect discovery"},
        "known_mass": known,
    }
