"""What a recorded log's identification prints and writes: the table, the residual
figure, report.json (``pinquad.io.runs.REPORT_SCHEMA``) and report.md, and the run directory holding them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pinquad.core.conventions import wrap_angle
from pinquad.core.vehicle_file import is_vehicle_file, load_vehicle
from pinquad.discovery.calibrated import DiscoveryOutcome
from pinquad.identification.budget import ErrorBudget
from pinquad.identification.identify import Identification
from pinquad.identification.verdict import PRODUCTS, Estimate, EstimateVerdict
from pinquad.io.logs import write_log
from pinquad.io.runs import REPORT_SCHEMA, RunWriter, atomic_write_json
from pinquad.models.ssm import Observations
from pinquad.pipeline.identify import LogResult, torque_words
from pinquad.pipeline.judge import Headline
from pinquad.report.discovery import discovery_markdown
from pinquad.report.offline import plot_trajectory
from pinquad.report.run_tables import write_run_tables

Array = NDArray[np.float64]


def _motor_split_entry(r: Identification) -> dict | None:
    """report.json's ``motor_split`` entry of a measured run (None otherwise)."""
    split = None if r.measured is None else r.measured.motor_split
    if split is None:
        return None
    return {
        "thrust_share": split.share.tolist(),
        "rebuilt_motors": [i + 1 for i in split.rebuilt],
        "measured_motors_mass": split.measured_mass,
        "all_measured_mass": (split.all_measured_mass
                              if np.isfinite(split.all_measured_mass) else None),
        "all_measured_transitions": split.all_measured_rows,
        "note": "each motor's part of the model-free mass's vertical thrust, "
                "relative to the four-motor mean (realdata.MotorSplit); "
                "rebuilt_motors: motors with speeds from the PWM map in some "
                "rows; measured_motors_mass: what the other motors carry of the "
                "model-free mass [kg]; all_measured_mass: the model-free mass "
                "over the transitions with no speed from the PWM map [kg]"}


def run_details(r: Identification, kind: str) -> dict:
    """report.json's per-run entries beyond the estimates: standard-error kinds, the EM
    history, and what the path adds (measured flights: kf-combined errors, the nuisance
    moment, the model-free mass; the ten-parameter model: its start and the CoM and
    tensor errors). kind: the log's kind (``LogResult.kind``)."""
    if r.measured is not None:
        ident = r.measured
        detail = {
            "stderr_observed_information": {"mass": ident.se_info[0],
                                            "inertia_diag": ident.se_info[1:].tolist()},
            "stderr_jackknife": {"mass": ident.se_jack[0],
                                 "inertia_diag": ident.se_jack[1:].tolist()},
            "stderr_statistical": {"mass": ident.se_stat[0],
                                   "inertia_diag": ident.se_stat[1:].tolist()},
            "stderr_note": "stderr = statistical (larger of observed information and "
                           "block jackknife) combined with kf's uncertainty (all "
                           "estimates scale with kf) and, for I_zz, the yaw ratio's",
            "torque_band_hz": list(ident.band),
            "nuisance_moment": {"features": ["thrust", "v_body_x", "v_body_y",
                                             "v_body_z", "omega_x", "omega_y", "omega_z"],
                                "coefficients": ident.moment_coef.tolist()},
            "e_steps": r.e_steps,
            "history": np.column_stack([r.history_mass, r.history_inertia]).tolist(),
            "seconds": r.seconds,
            "model_free_mass": ident.quasi_static_mass,
            "model_free_mass_note": "kf sum omega^2 along the vertical over g + the mean "
                                    "vertical acceleration, the same transitions, no EM "
                                    "(realdata.quasi_static_mass)",
        }
        split = _motor_split_entry(r)
        if split is not None:
            detail["motor_split"] = split
        return detail
    if kind != "simulated":  # the paper's M-step on a measured flight
        return {"torques": torque_words(r), "seconds": r.seconds}
    if r.full is not None:
        start = r.full.start
        return {"stderr_note": "observed information of the EKF likelihood over all ten "
                               "parameters (delta method to CoM and inertia)",
                "em_failure": r.failure, "e_steps": r.e_steps,
                "start": {"note": "diagonal EM from the paper's guess, refitted with the "
                                  "horizontal CoM (full_inertia.staged_start)",
                          "mass": start.mass, "com": np.asarray(start.com).tolist(),
                          "inertia_diag": np.diag(start.inertia).tolist()},
                "stderr_full": {"com": r.full.stderr_com.tolist(),
                                "inertia": r.full.stderr_inertia.tolist()}}
    return {"stderr_note": "observed information of the EKF likelihood",
            "em_failure": r.failure,
            "history": np.column_stack([r.history_mass, r.history_inertia]).tolist(),
            "seconds": r.seconds}


def pm(v: float, s: float, scale: float, fmt: str) -> str:
    """``value ± stderr`` scaled (the error left out when not computed)."""
    return f"{v * scale:{fmt}}" + ("" if not np.isfinite(s) else f" ± {s * scale:{fmt}}")


def judged(v: float, s: float, scale: float, fmt: str, verdict: Estimate | None) -> str:
    """A number as printed beside its verdict: ``value ± stderr`` when trusted (or not
    judged), else ``value (verdict: first reason)``: an untrusted estimate never stands as
    a bare number with a small error bar."""
    if verdict is None or verdict.trusted:
        return pm(v, s, scale, fmt)
    return f"{v * scale:{fmt}} ({verdict.verdict}: {verdict.reasons[0]})"


def _estimate_cells(mass: float, inertia: Array, stderr: Array,
                    verdict: EstimateVerdict | None) -> str:
    get = (lambda name: None) if verdict is None else verdict.get
    return (f"{judged(mass, stderr[0], 1e3, '.3f', get('mass'))} | "
            + " | ".join(judged(inertia[i, i], stderr[i + 1], 1e6, ".2f", get(n))
                         for i, n in enumerate(("I_xx", "I_yy", "I_zz"))))


def log_table(result: LogResult, headline: Headline | None = None) -> str:
    """The printed table: one row per run (mass [g], inertia diagonal [1e-6 kg m^2] with
    standard errors or, when not trusted, the verdict and its first reason; the overall
    verdict; EM iterations), the final model's row when discovery refitted it, the scale /
    published row and mass checks for the Crazyflie, the ten-parameter model's CoM and
    products of inertia."""
    crazyflie = result.log.meta.vehicle == "crazyflie21" or is_vehicle_file(result.log.meta.vehicle)
    ref = load_vehicle(result.log.meta.vehicle).reference if crazyflie else None
    scale = ref.mass if ref is not None and ref.mass is not None else float("nan")
    published = (ref.inertia if ref is not None and ref.inertia is not None
                 else np.full(3, np.nan))
    crazyflie = crazyflie and np.isfinite(scale)
    head = ("| sensor | M-step | mass [g] | I_xx [1e-6 kg m^2] | I_yy | I_zz | verdict "
            "| EM iterations |")
    lines = [head, "|---|---|---|---|---|---|---|---|"]
    verdicts = (None,) * len(result.runs) if headline is None else headline.run_verdicts
    for r, v in zip(result.runs, verdicts, strict=True):
        lines.append(
            f"| {r.sensor} | {r.mstep} | {_estimate_cells(r.mass, r.inertia, r.stderr, v)} | "
            f"{'-' if v is None else v.overall} | "
            f"{r.iterations}{'' if r.converged else ' (not converged)'} |")
    if headline is not None and headline.refitted:
        f = headline.final
        lines.append(f"| final | {f.model} | "
                     f"{_estimate_cells(f.mass, f.inertia, f.stderr, f.verdict)} | "
                     f"{f.verdict.overall} | |")
    if crazyflie:
        lines.append(f"| scale / published | | {scale * 1e3:.1f} | "
                     + " | ".join(f"{v * 1e6:.2f}" if np.isfinite(v) else "-" for v in published) + " | | |")
        for r in result.runs:
            lines.append(f"\n{r.sensor}, {r.mstep} M-step: mass {r.mass * 1e3:.2f} g vs "
                         f"{scale * 1e3:.1f} g on the scale: "
                         f"{100 * (r.mass / scale - 1):+.2f} %"
                         + ("" if not np.isfinite(r.stderr[0]) else
                            f" ({abs(r.mass - scale) / r.stderr[0]:.1f} standard errors)"))
            free = None if r.measured is None else r.measured.quasi_static_mass
            if free is not None and np.isfinite(free):
                lines.append(f"{r.sensor}, model-free check (mean vertical thrust, no EM): "
                             f"{free * 1e3:.2f} g ({100 * (free / scale - 1):+.2f} %)")
            split = _motor_split_entry(r)
            if split and split["rebuilt_motors"]:
                lines.append(
                    f"{r.sensor}, motors measured "
                    f"({', '.join(f'M{i}' for i in range(1, 5) if i not in split['rebuilt_motors'])}) "
                    f"carry {split['measured_motors_mass'] * 1e3:.2f} g of it; thrust shares "
                    f"of the four-motor mean " + ", ".join(
                        f"M{i + 1} {v:.3f}{' (repaired)' if i + 1 in split['rebuilt_motors'] else ''}"
                        for i, v in enumerate(split["thrust_share"])))
                own = split.get("all_measured_mass")
                if own is not None:
                    lines.append(
                        f"{r.sensor}, model-free mass on the {split['all_measured_transitions']} "
                        f"transitions with every rotor speed measured: {own * 1e3:.2f} g "
                        f"({100 * (own / scale - 1):+.2f} %)")
    for r, v in zip(result.runs, verdicts, strict=True):
        if r.full is not None:
            lines.append("")
            lines += full_model_lines(r, v)
    return "\n".join(lines)


def full_model_lines(r: Identification, verdict: EstimateVerdict | None) -> list[str]:
    """A ten-parameter run's centre of mass [mm] and products of inertia [1e-6 kg m^2],
    each with its standard error or why it has none / its verdict."""
    full = r.full
    assert full is not None
    # standard errors computed (the mass's is finite) but not the CoM's: the data
    # leave it undetermined (identification.fisher.determined_covariance)
    asked = np.isfinite(full.stderr_mass)
    return [f"{r.sensor}, full M-step: centre of mass [mm] "
            + ", ".join(f"c_{'xyz'[i]} " + (
                pm(full.com[i], full.stderr_com[i], 1e3, ".3f")
                if np.isfinite(full.stderr_com[i]) or not asked
                else f"{full.com[i] * 1e3:.3f} (not identifiable: the likelihood "
                     "is flat along it)") for i in range(3)),
            f"{r.sensor}, full M-step: products of inertia [1e-6 kg m^2] "
            + ", ".join(f"{name} " + judged(
                full.inertia[i, j], full.stderr_inertia[i, j], 1e6, ".2f",
                None if verdict is None else verdict.get(name))
                for name, i, j in PRODUCTS)]


def plot_residuals(obs: Observations, smoothed: Array, path: Path) -> None:
    """Measurement residuals y - H m over time, one panel per channel."""
    h = obs.measurement_matrix()
    pred = smoothed @ h.T
    res = obs.ys - pred
    angle = obs.angle_rows()
    if angle.size:
        res[:, angle] = wrap_angle(res[:, angle])
    units = {"pos": "m", "vel": "m/s", "euler": "rad", "gyro": "rad/s"}
    fig = Figure(figsize=(10, 2.4 * len(obs.channels)))
    axes = fig.subplots(len(obs.channels), 1, sharex=True, squeeze=False)
    for i, ch in enumerate(obs.channels):
        ax = axes[i, 0]
        for j, lab in enumerate("xyz"):
            col = res[:, 3 * i + j]
            ok = np.isfinite(col)
            ax.plot(obs.t[ok], col[ok], ".", ms=1.5, label=f"{ch} {lab}")
        ax.set_ylabel(f"{ch} residual [{units[ch]}]")
        ax.legend(loc="upper right", fontsize=7, markerscale=4)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle("measurement residuals y - H E[x | all y] of the smoothed state")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def null_lines(null: dict) -> list[str]:
    """Printed lines of the ``null_calibration`` entry: each tested effect's gain against
    its shadow flights' (``pinquad.discovery.null``)."""
    if not null.get("replicates"):
        return [f"  null calibration: {null.get('note', 'not run')}"] if null else []
    lines = [f"  null calibration: {null['replicates']} shadow flights of the base fit "
             f"(seed {null['seed']}, {null['seconds']:.0f} s); an effect is kept when its "
             f"held-out gain beats them (p <= {null['alpha']:g})"]
    if null.get("shadow_tracking_rms_m", 0.0) > 0.1:
        lines.append(f"    note: {null['shadow_tracking_note']}")
    if null.get("shadow_inertia_note"):
        lines.append(f"    note: {null['shadow_inertia_note']}")
    for name, e in null["effects"].items():
        lines.append(f"    {name}: gain {100 * e['heldout_gain']:.1f} % vs null max "
                     f"{100 * e['null_gain_max']:.1f} % (passed the uncalibrated selection on "
                     f"{e['null_passes']}/{null['replicates']}), p = {e['p_value']:.2f}: "
                     + ("kept" if e["kept"] else "rejected, not reported"))
    return lines


def discovery_summary(section: dict) -> str:
    """A few printed lines: what was selected, its coefficients and the held-out RMS."""
    if section.get("not_run"):
        return f"effect discovery: not run: {section['not_run']}"
    if "error" in section:
        return f"effect discovery: {section['error']}"
    sel = section["selected"]
    null = section.get("null_calibration", {})
    odd = unphysical_lines(section.get("unphysical", ()))
    if section.get("note"):
        odd.insert(0, f"  note: {section['note']}")
    if not sel:
        calibrated = bool(null.get("replicates"))
        head = ("effect discovery: no significant unmodelled effect (held-out test"
                + (", null calibration)" if calibrated else ")"))
        if odd:
            head = "effect discovery: no physical effect explains the residual"
        return "\n".join([head, *odd, *(null_lines(null) if calibrated else [])])
    lines = [f"effect discovery: selected {', '.join(s['effect'] for s in sel)}"]
    for s in sel:
        co = ", ".join(coefficient_text(s, n) for n in s["coefficients"])
        lines.append(f"  {s['effect']}: {co}; held-out gain "
                     f"{100 * s['evidence']['heldout_gain']:.0f} %")
    named = {s["effect"] for s in sel} | {e["effect"] for e in section.get("unphysical", ())}
    floor = section.get("ground_effect_floor")
    if floor and "ground_effect" in named:
        lines.append(f"  ground-effect law: height above the {floor['note']}")
    refit = section.get("refit")
    if refit:
        inertia = np.diag(np.asarray(refit["inertia"])) * 1e6
        lines.append(f"  refit with the effects: mass {refit['mass'] * 1e3:.3f} g, inertia diagonal "
                     f"({', '.join(f'{v:.2f}' for v in inertia)}) 1e-6 kg m^2")
    b, a = section["residual_rms_before"], section["residual_rms_after"]
    lines.append("  held-out residual RMS before -> after: " + ", ".join(
        f"{k} {b[k]:.3g} -> {a[k]:.3g}" for k in b))
    lines.extend(odd)
    lines.extend(null_lines(null))
    return "\n".join(lines)


def coefficient_text(entry: dict, name: str) -> str:
    """One coefficient of a selected effect as printed: value ± standard error and unit;
    on its domain's edge, said so with the fit without the domain beside it."""
    value, se, unit = entry["coefficients"][name], entry["stderr"][name], entry["units"][name]
    if name not in entry.get("on_domain_edge", ()):
        return f"{name} = {value:.4g} ± {se:.2g} {unit}"
    free = (entry.get("coefficients_without_domain") or {}).get(name)
    without = "" if free is None else f"; without it {free:.4g}"
    return (f"{name} = {value:.4g} ± {se:.2g} {unit} (on the edge of its domain "
            f"{name} {entry['domain'][name]}{without})")


def unphysical_lines(entries) -> list[str]:
    """What an effect whose best fit is outside its physical domain leaves unexplained."""
    lines = []
    for e in entries:
        fit = ", ".join(f"{k} = {v:.4g}" for k, v in e["closest_unphysical_fit"].items())
        rows = ", ".join(f"{k} rms {r['rms_before']:.3g} ({100 * r['share']:.0f} % of it)"
                         for k, r in e["unexplained_rows"].items())
        lines.append(f"  not kept: {e['effect']} ({fit}): {e['reason']}")
        lines.append(f"    unexplained residual it would have taken: {rows or 'none held out'}")
    return lines




def _estimates(r: Identification, verdict: EstimateVerdict | None = None) -> dict:
    out = {"mass": r.mass, "inertia": np.asarray(r.inertia).tolist(),
           "com": None if r.com is None else r.com.tolist(),
           "stderr": {"mass": r.stderr[0], "inertia_diag": r.stderr[1:].tolist()}}
    if verdict is not None:
        out["verdict"] = verdict.to_report()
    return out


def _em(r: Identification) -> dict:
    return {"iterations": r.iterations, "loglik": r.loglik.tolist(),
            "converged": bool(r.converged), "failure": r.failure}


def report_json(result: LogResult, path: str, estep: str, seconds: float,
                discovery: dict | None, headline: Headline) -> dict:
    """report.json of a recorded log (``pinquad.io.runs.REPORT_SCHEMA``): ``estimates`` under the final model
    (discovery's refit when effects were selected, else the base fit) with its verdict,
    the base fit under ``base`` (same layout), the headline's ``verdict``, every run with
    its details and verdict, exclusions, notes, the kf and fault notes of measured
    flights, the discovery section (``not run`` when None) and ``search_range``: where EM
    searched mass and inertia (None: unbounded)."""
    main = result.runs[0]
    report = {
        "schema": REPORT_SCHEMA,
        "source": {"kind": "log", "path": path, "sensor": main.sensor,
                   "estep": estep, "log_type": result.contents, "log_kind": result.kind,
                   "vehicle": result.log.meta.vehicle, "mstep": main.mstep},
        "estimates": headline.final.to_report(),
        "base": headline.base.to_report(),
        "verdict": headline.final.verdict.to_report(),
        "em": _em(main),
        "discovery": discovery if discovery is not None else {
            "selected": [], "residual_rms_before": {}, "residual_rms_after": {},
            "validation": "not run", "not_run": "not asked for", "note": None,
            "unphysical": [], "ground_effect_floor": None},
        "excluded": list(result.excluded),
        "cycles": [],
        "run_logs": {"log": {"log": "logs/flight.parquet",
                             "smoothed": "logs/flight-smoothed.npy"}},
        "initial_guess": result.guess,
        "runs": [{"sensor": r.sensor, "mstep": r.mstep, "estimates": _estimates(r, v),
                  "em": _em(r), **run_details(r, result.kind)}
                 for r, v in zip(result.runs, headline.run_verdicts, strict=True)],
        "notes": list(result.notes),
        "seconds": seconds,
        "search_range": None if result.search is None else {
            "mass": list(result.search.mass), "inertia_lo": result.search.inertia_lo.tolist(),
            "inertia_hi": result.search.inertia_hi.tolist(), "source": result.search.source},
    }
    if result.kf is not None:
        kf = result.kf
        report["kf"] = {"value": kf.kf, "stderr": kf.kf_se, "pooled": kf.pooled,
                        "runs": {r.source: r.kf for r in kf.runs}, "note": kf.note}
        report["faults"] = list(result.faults)
    return report


def headline_summary(headline: Headline) -> str:
    """The printed headline: the final model's estimate, its verdict and the reasons."""
    f = headline.final
    mass = judged(f.mass, f.stderr[0], 1e3, ".3f", f.verdict.get("mass"))
    lines = [f"headline ({f.model}): mass {mass} g, "
             "inertia diagonal " + ", ".join(
                 judged(f.inertia[i, i], f.stderr[i + 1], 1e6, ".2f", f.verdict.get(n))
                 for i, n in enumerate(("I_xx", "I_yy", "I_zz"))) + " e-6 kg m^2",
             f"verdict: {f.verdict.overall}"]
    lines += [f"  {r}" for r in f.verdict.reasons]
    if f.budget is not None:
        lines += budget_lines(f.budget)
    return "\n".join(lines)


def budget_lines(budget: ErrorBudget) -> list[str]:
    """The error budget printed: each parameter's total and its non-zero parts."""
    total = budget.total
    lines = ["error budget (standard errors; the total is their root sum of squares):"]
    for i, (name, scale, unit) in enumerate((("mass", 1e3, "g"), ("I_xx", 1e6, "e-6 kg m^2"),
                                             ("I_yy", 1e6, "e-6 kg m^2"),
                                             ("I_zz", 1e6, "e-6 kg m^2"))):
        parts = ", ".join(f"{k} {v[i] * scale:.3g}" for k, v in budget.parts.items()
                          if np.isfinite(v[i]) and v[i] > 0)
        lines.append(f"  {name}: {total[i] * scale:.3g} {unit} ({parts or 'none'})")
    return lines


def report_markdown(result: LogResult, path: str, discovery: dict | None,
                    headline: Headline) -> str:
    """report.md: the log's contents, the table with verdicts, the headline, exclusions,
    notes and the discovery section."""
    md = (f"# pinquad: identification from {path}\n\nlog: {result.contents}\n\n"
          + log_table(result, headline) + "\n\n" + headline_summary(headline).replace(
              "\n  ", "\n- ") + "\n\n"
          + "\n".join(f"- excluded: {e}" for e in result.excluded) + "\n"
          + "".join(f"- note: {n}\n" for n in result.notes))
    if discovery is not None:
        md += "\n" + discovery_markdown(discovery)
    return md


def write_log_run(writer: RunWriter, result: LogResult, report: dict, markdown: str,
                  outcome: DiscoveryOutcome | None = None) -> None:
    """The run directory's files (report.json, report.md, the log as the E-step saw it,
    the smoothed means, trajectory and residual figures, the viewer's tables of
    ``pinquad.report.run_tables``: EM history, residual per step before and after
    ``outcome``'s refit, raw motion capture) into ``writer``'s staging directory; the
    caller publishes or aborts."""
    figs = writer.path("figures")
    figs.mkdir(exist_ok=True)
    logs_dir = writer.path("logs")
    logs_dir.mkdir(exist_ok=True)
    write_log(result.log, logs_dir / "flight.parquet")
    np.save(logs_dir / "flight-smoothed.npy", result.smoothed)
    plot_trajectory(result.log, None, figs / "trajectory.png", result.smoothed)
    plot_residuals(result.obs, result.smoothed, figs / "residuals.png")
    added = write_run_tables(writer, result, outcome, report)
    atomic_write_json(writer.path("report.json"), report)
    writer.path("report.md").write_text(markdown + "".join(f"{line}\n" for line in added))
