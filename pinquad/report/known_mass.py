"""The known-mass identification's printed table and report.json
(``pinquad.identification.known_mass``)."""

from __future__ import annotations

import math

import numpy as np

from pinquad.core.actuator_curve import CurveVehicle
from pinquad.identification.known_mass import KnownMassResult
from pinquad.identification.verdict import TRUSTED

INERTIA = ("I_xx", "I_yy", "I_zz")


def _num(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.5g}"


def known_mass_table(result: KnownMassResult, vehicle: CurveVehicle) -> str:
    """Estimate, total se, its parts, reference (the vehicle file's [reference] inertia),
    verdict and reasons, then the naive regression beside it."""
    ref = vehicle.spec.reference.inertia
    lines = [f"known mass {result.mass:g} +- {result.mass_se:.2g} kg; torque band {result.band[0]:g}-"
             f"{result.band[1]:g} Hz; the curve explains {result.force_share * 100:.1f} % of "
             "the vertical force",
             "", f"{'estimate':<17} {'value':>10} {'se':>10} {'reference':>10} {'error':>7}  "
             f"verdict", "-" * 75]
    for e in result.estimates:
        truth = ref[INERTIA.index(e.name)] if ref is not None and e.name in INERTIA else None
        err = "" if truth is None or not math.isfinite(e.value) else \
            f"{(e.value / truth - 1) * 100:+.1f}%"
        lines.append(f"{e.name:<17} {_num(e.value):>10} {_num(e.stderr):>10} "
                     f"{'' if truth is None else _num(truth):>10} {err:>7}  {e.verdict} "
                     f"[{e.unit}]")
        if e.parts:
            lines.append("    se parts: " + ", ".join(f"{k} {_num(v)}" for k, v in e.parts))
        lines += [f"    why: {r}" for r in e.reasons]
    lines += ["", "naive regression (no motor lag, no drag, no filter, raw d omega/dt):"]
    for a, name in enumerate(INERTIA[:2]):
        truth = None if ref is None else ref[a]
        err = "" if truth is None else f" ({(result.naive_inertia[a] / truth - 1) * 100:+.1f} %)"
        lines.append(f"  {name} {_num(result.naive_inertia[a])}{err}, torque explains "
                     f"{result.naive_share[a] * 100:.0f} % of the angular acceleration's "
                     "variance")
    lines += ["", *(f"note: {n}" for n in result.notes)]
    return "\n".join(lines)


def headline_trusted(result: KnownMassResult) -> bool:
    """Whether every estimate that could be had (a value) is trusted."""
    return all(e.verdict == TRUSTED for e in result.estimates if math.isfinite(e.value))


def known_mass_report(result: KnownMassResult, log_path: str, vehicle: CurveVehicle,
                      seconds: float) -> dict:
    """report.json (the house's keys; the known-mass specifics under ``known_mass``)."""
    inertia = np.array([result.get(n).value for n in INERTIA])
    inertia_se = [result.get(n).stderr for n in INERTIA]
    return {
        "schema": "pinquad.report/1",
        "source": {"kind": "log", "path": log_path, "sensor": None, "estep": None,
                   "method": "known-mass regression", "vehicle": str(vehicle.spec.source)},
        "estimates": {
            "mass": result.mass, "inertia": np.diag(inertia).tolist(), "com": None,
            # the mass is given: its error is the uncertainty assumed for it
            "stderr": {"mass": result.mass_se, "inertia_diag": inertia_se},
            "stderr_parts": {n: dict(result.get(n).parts) for n in INERTIA},
            "verdict": {e.name: {"verdict": e.verdict, "reasons": list(e.reasons)}
                        for e in result.estimates},
        },
        "em": {"iterations": 0, "loglik": [], "converged": None,
               "note": "known-mass regression: no EM was run"},
        "discovery": {"selected": [], "not_run": "known-mass mode: no effect discovery"},
        "known_mass": {
            "estimates": [{"name": e.name, "value": e.value, "unit": e.unit,
                           "stderr": e.stderr, "stderr_parts": dict(e.parts),
                           "verdict": e.verdict, "reasons": list(e.reasons)}
                          for e in result.estimates],
            "vertical_force_share": result.force_share,
            "torque_share": list(result.torque_share),
            "band_hz": list(result.band),
            "naive": {"inertia_diag": result.naive_inertia.tolist(),
                      "torque_share": list(result.naive_share)},
            "notes": list(result.notes), "seconds": seconds,
        },
    }
