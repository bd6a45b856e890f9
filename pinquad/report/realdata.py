"""The real-vehicle table of ``python -m pinquad.realdata``: the identified flights as a
Markdown table, with the summaries printed below it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import VehicleSpec
from pinquad.realdata.consistency import FlightRow, FlightScatter
from pinquad.realdata.dataset import FLIGHTS, YAW_FLIGHTS
from pinquad.realdata.rotor_inertia import PooledRotorInertia
from pinquad.vehicle.actuators import CRAZYFLIE_SPEC


def _short_reasons(r: FlightRow) -> str:
    words = []
    for e in r.fit.exclusions:
        if not e.transitions:
            continue
        words.append(f"{e.transitions} {e.kind}")
    return ", ".join(words) if words else "-"


def _pm(value: float, total: float, stat: float, scale: float, fmt: str = ".2f") -> str:
    return (f"{value * scale:{fmt}} ± {total * scale:{fmt}} "
            f"({stat * scale:{fmt}})")


def _judged(r: FlightRow, i: int, scale: float, fmt: str = ".2f") -> str:
    """Parameter i of [m, I_xx, I_yy, I_zz] as ``value ± total (statistical)``, or, when its
    verdict is not trusted, ``value (verdict)`` without an error bar."""
    name = ("mass", "I_xx", "I_yy", "I_zz")[i]
    v = None if r.run.verdict is None else r.run.verdict.get(name)
    if v is None or v.trusted:
        text = _pm(r.params[i], r.run.stderr[i], r.fit.se_stat[i], scale, fmt)
        s = 1.0 if r.scatter_scale is None else float(r.scatter_scale[i])
        return text if s == 1.0 else f"{text} [x{s:.1f}]"
    return f"{r.params[i] * scale:{fmt}} ({v.verdict})"


def _verdict_words(r: FlightRow) -> str:
    """The overall verdict and, when not trusted, its reasons."""
    verdict = r.run.verdict
    if verdict is None:
        return "-"
    if verdict.trusted:
        return verdict.overall
    return f"{verdict.overall}: " + "; ".join(verdict.reasons)


def _rotor_words(r: FlightRow) -> str:
    jr = r.fit.rotor_inertia
    if not np.isfinite(jr):
        return f"{r.name} none"
    return f"{r.name} {1e9 * jr:.1f} ({r.rotor_source or 'fitted on this log'})"


def effect_words(r: FlightRow) -> str:
    """The effects found on a flight with their held-out gain against the null's largest
    (``FlightRow.effects``), and those the null explained."""
    if r.effects is None:
        return "not run"
    if r.effects.get("error"):
        return f"failed: {r.effects['error']}"
    parts = []
    for e in r.effects["selected"]:
        gain = 100 * e["heldout_gain"]
        if e["p_value"] is None:
            parts.append(f"{e['effect']} (gain {gain:.0f} %, not calibrated)")
        else:
            parts.append(f"{e['effect']} (gain {gain:.0f} % vs null max "
                         f"{100 * e['null_gain_max']:.0f} %, p {e['p_value']:.2f})")
    parts += [f"not {e} (the null explains it)" for e in r.effects["rejected"]]
    return "; ".join(parts) or "none"


def reference_values(spec: VehicleSpec) -> tuple[float, NDArray[np.float64], str, str]:
    """(mass [kg], inertia (3,) [kg m^2], how the mass is known, how the inertia is known)
    a vehicle file's flights are compared with: its ``[reference]``, else its body."""
    ref = spec.reference
    mass = ref.mass if ref.mass is not None else spec.mass
    inertia = (np.asarray(ref.inertia, dtype=float) if ref.inertia is not None
               else np.diag(spec.inertia).copy())
    return (mass, inertia, ref.mass_note or "the file's body mass",
            ref.inertia_note or "the file's body inertia")


def format_table(results: Sequence[FlightRow],
                 rotor: PooledRotorInertia | None = None,
                 spec: VehicleSpec = CRAZYFLIE_SPEC,
                 scatters: Sequence[FlightScatter] = ()) -> str:
    """The markdown table of the identified flights and the summaries below it
    (``rotor``: the pooled rotor inertia the flights were identified with, described;
    ``spec``: the vehicle file, whose ``[reference]`` the flights are compared with;
    ``scatters``: the flights compared with each other, ``realdata.consistency``)."""
    if not results:
        return "(no flights)"
    kf = results[0].fit.kf
    ref_mass, ref_inertia, _, inertia_note = reference_values(spec)
    act = spec.actuators
    yaw_rel = 0.0 if act is None else act.yaw_ratio_se / act.yaw_ratio
    repair = spec.faults.repair_rel_se
    repair_words = (
        f"and for logs whose rotor speeds were rebuilt from PWM the repair's (mass "
        f"{100 * repair[0]:.1f} %, I_xx {100 * repair[1]:.0f} %, I_yy {100 * repair[2]:.0f} %, "
        f"I_zz {100 * repair[3]:.0f} %, measured by rebuilding M1 on the clean logs). "
        if repair else "(no PWM repair for this vehicle: implausible rows are excluded). ")
    lines = [
        f"| log | what was flown | used / excluded transitions (why) | mass [g] | vs "
        f"{1e3 * ref_mass:g} g | "
        "I_xx [1e-6 kg m^2] | I_yy | I_zz | verdict | EM iterations | effects found "
        "(held-out gain vs the null's) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        run = r.run
        within = abs(run.mass - ref_mass) <= 2.0 * run.stderr[0]
        lines.append(
            f"| {r.name} | {FLIGHTS.get(r.name, '')} | {r.fit.n_used} / {r.fit.n_excluded} "
            f"({_short_reasons(r)}) | {_judged(r, 0, 1e3)} | "
            f"{100 * (run.mass / ref_mass - 1.0):+.2f} %{'' if within else ' (!)'} | "
            + " | ".join(_judged(r, i, 1e6, ".1f") for i in (1, 2, 3))
            + f" | {_verdict_words(r)} | {run.iterations}"
            + f"{'' if run.converged else ' (not converged)'}"
            + f" | {effect_words(r)} |")
    calibrated = [r.effects for r in results if r.effects and r.effects.get("replicates")]
    if any(r.effects is not None for r in results):
        lines += ["", "effects found: effect discovery on each flight's base fit (effects fitted "
                  "on the base posterior); an effect is listed when its held-out gain beats "
                  + (f"all {calibrated[0]['replicates']} shadow flights of that fit (seed "
                     f"{calibrated[0]['seed']}; pinquad.discovery.null)" if calibrated
                     else "the selection's tests (no null calibration was needed or asked)")]
    lines += [
        "",
        "value ± total standard error (statistical standard error): statistical = larger of "
        "the observed-information and the block-jackknife standard errors; total adds kf's "
        f"{100 * kf.rel_se:.1f} % (all estimates are proportional to kf), for I_zz the "
        f"yaw ratio's {100 * yaw_rel:.1f} %, " + repair_words
        + "(!) marks a mass more than two total standard errors from the scale.",
        "",
        kf.note,
    ]
    if scatters:
        lines += ["", "flights against each other (the trusted estimates of each parameter "
                  "over the flights that share their rotor-speed source; where they scatter "
                  "beyond their statistical errors, every such flight's statistical error is "
                  "scaled by S = sqrt(chi2 / dof) inside its total and its verdict judged "
                  "again; pinquad.realdata.consistency):"]
        lines += [f"- {sc.describe()}" for sc in scatters]
    if rotor is not None:
        lines += ["", rotor.describe()]
    masses = np.array([r.run.mass for r in results])
    rel = masses / ref_mass - 1.0
    # one log has no spread: its sd is not computed (ddof=1 over one value)
    spread = (f"spread (sd) {1e3 * masses.std(ddof=1):.2f} g" if masses.size > 1
              else "no spread (one log)")
    lines += ["", f"mass: mean {1e3 * masses.mean():.2f} g, {spread} "
              f"over {masses.size} logs; |error| <= 1.5 % in {int(np.sum(np.abs(rel) <= 0.015))} "
              f"of {masses.size}; worst {100 * rel[np.argmax(np.abs(rel))]:+.2f} % "
              f"({results[int(np.argmax(np.abs(rel)))].name})"]
    qs = np.array([r.fit.quasi_static_mass for r in results])
    if np.isfinite(qs).any():
        lines.append(
            "model-free check, mass that balances the mean vertical thrust (kf sum omega^2 "
            "along the vertical over g + the mean vertical acceleration, the same "
            "transitions, no EM): " + ", ".join(
                f"{r.name} {1e3 * q:.2f} g ({100 * (q / ref_mass - 1.0):+.1f} %)"
                for r, q in zip(results, qs, strict=True) if np.isfinite(q)))
    lines += _rebuilt_motor_lines(results, ref_mass)
    yaw = [r for r in results if r.name in YAW_FLIGHTS]
    if len(yaw) >= 2:
        izz = np.array([r.run.inertia[2, 2] for r in yaw])
        lines.append(
            f"I_zz on the yaw flights ({', '.join(r.name for r in yaw)}): "
            + ", ".join(f"{1e6 * v:.1f}" for v in izz)
            + f" e-6 kg m^2; spread (max - min) / mean = "
              f"{100 * float(np.ptp(izz) / izz.mean()):.0f} %, sd / mean = "
              f"{100 * float(izz.std(ddof=1) / izz.mean()):.0f} % (kf and the yaw ratio are "
              "common to all logs and cancel in this comparison); rotor inertia J_r used "
              "[e-9 kg m^2]: " + ", ".join(_rotor_words(r) for r in yaw))
    inert = np.array([np.diag(r.run.inertia) for r in results])
    mean, sd = inert.mean(axis=0), inert.std(ddof=1, axis=0) if len(results) > 1 else np.zeros(3)
    lines += [
        "",
        "| inertia [1e-6 kg m^2] | I_xx | I_yy | I_zz |",
        "|---|---|---|---|",
        "| mean over logs ± sd | " + " | ".join(f"{1e6 * m:.1f} ± {1e6 * s:.1f}"
                                            for m, s in zip(mean, sd, strict=True)) + " |",
        "| spread sd / mean | " + " | ".join(f"{100 * s / m:.0f} %"
                                          for m, s in zip(mean, sd, strict=True)) + " |",
        f"| reference: {inertia_note} | "
        + " | ".join(f"{1e6 * v:.2f}" for v in ref_inertia) + " |",
    ]
    return "\n".join(lines)


def _rebuilt_motor_lines(results: Sequence[FlightRow], ref_mass: float
                         ) -> list[str]:
    """What the logs with rebuilt rotor speeds say about the mass without the rebuild: the
    measured motors' part of the model-free mass, and the mass if each rebuilt motor
    carried a share of the thrust anywhere in the range it carries on the clean logs
    (ref_mass [kg]: the scale's)."""
    split = {r.name: r.fit.motor_split for r in results if r.fit.motor_split is not None}
    clean = {n: m for n, m in split.items() if not m.rebuilt}
    faulty = {n: m for n, m in split.items() if m.rebuilt}
    motors = sorted({i for m in faulty.values() for i in m.rebuilt})
    if not faulty or not clean or len(motors) != 1:
        return []
    i = motors[0]
    shares = np.array([m.share[i] for m in clean.values()])
    lo, hi = float(shares.min()), float(shares.max())
    names = list(clean)
    words = [
        f"M{i + 1} repaired ({', '.join(faulty)}): the three measured motors alone carry "
        + ", ".join(f"{n} {1e3 * m.measured_mass:.2f} g" for n, m in faulty.items())
        + f" of the model-free mass; on the clean logs M{i + 1} carries {lo:.3f} "
        f"({names[int(np.argmin(shares))]}) to {hi:.3f} ({names[int(np.argmax(shares))]}) of "
        "the four-motor mean thrust, and with a share anywhere in that range the faulty "
        "logs' mass would be "
        + ", ".join(f"{n} {1e3 * m.mass_if(lo):.2f}-{1e3 * m.mass_if(hi):.2f} g "
                    f"({100 * (m.mass_if(lo) / ref_mass - 1):+.1f} to "
                    f"{100 * (m.mass_if(hi) / ref_mass - 1):+.1f} %)"
                    for n, m in faulty.items())
        + "; within 1.5 % of the scale needs a share of at most "
        + ", ".join(f"{n} {m.share_for(1.015 * ref_mass):.3f}" for n, m in faulty.items())
        + " (the repaired M1 gives "
        + ", ".join(f"{n} {m.share[i]:.3f}" for n, m in faulty.items()) + ")"]
    own = {n: m for n, m in faulty.items() if m.all_measured_rows}
    if own:
        words.append(
            f"model-free mass on the transitions where no rotor speed comes from the PWM map "
            f"(M{i + 1} measured, its pulse-divided readings multiplied back): "
            + ", ".join(f"{n} {1e3 * m.all_measured_mass:.2f} g "
                        f"({100 * (m.all_measured_mass / ref_mass - 1):+.1f} %, "
                        f"{m.all_measured_rows} transitions)" for n, m in own.items()))
    return words
