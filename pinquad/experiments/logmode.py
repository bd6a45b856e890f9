"""``python -m pinquad.offline --log PATH``: identify mass and inertia from a recorded log.

Dispatch on what the file is:

* a Crazyflie micro-SD binary log (``sdlog.is_sdlog``): a measured flight, turned into
  observations on a 100 Hz grid by :mod:`pinquad.realdata.flights` (motion capture, gyro, rotor
  speeds through the thrust-stand kf) and identified with its M-step (mass from the
  force row, inertia from the 3-8 Hz torque rows with the air-speed moments profiled
  out);
* a CSV / Parquet log (``logs.read_log``) with ``thrust`` and ``torque_*`` columns: a
  simulated-style log, observed through the paper's sources (``sources.observations``;
  sensor A if it carries an onboard estimate and accelerometer samples, else B if it
  has attitude, else C) and identified with the shared regressor M-step;
* a CSV / Parquet log with ``rpm_1..4``: a measured flight in table form, the
  micro-SD path without the PWM repair.

Initial guesses come from the log's sidecar (``mass_guess``, ``inertia_guess``), else
from ``realdata.default_guess`` (crazyflie21: 25 g and half the published inertia;
others: the paper's m0 = 0.001 kg, I0 = diag(1e-4, 2e-4, 1e-4) kg m^2).

The run directory holds report.json (DESIGN.md 4.3), report.md, the log as the E-step
saw it (``logs/flight.parquet``), the smoothed state means (``logs/flight-smoothed.npy``,
(N, 12)) and figures (trajectory, measurement residuals), written whole or not at all.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.io.logs import FlightLog, LogFormatError
from pinquad.io.runs import REPORT_SCHEMA
from pinquad.models.ssm import Observations
from pinquad.realdata.theta import plain_theta

if TYPE_CHECKING:
    from pinquad.identification.full_inertia import FullIdentification

Array = NDArray[np.float64]



@dataclass(frozen=True)
class LogRun:
    """One identification of a log, whatever path produced it.

    sensor: source name (A/B/C) or the measured-log channel list; mstep: ``regressor``,
    ``paper`` or ``full``; mass [kg]; inertia (3,) diagonal [kg m^2]; stderr (4,)
    standard errors of [m, I_xx, I_yy, I_zz] reported as *the* standard error (NaN if
    not computed); iterations; loglik (I,); converged; detail: extra report entries;
    full: the ``full`` M-step's identification (CoM, full inertia tensor and their
    standard errors; None otherwise).
    """

    sensor: str
    mstep: str
    mass: float
    inertia: Array
    stderr: Array
    iterations: int
    loglik: Array
    converged: bool
    detail: dict
    full: FullIdentification | None = None

    def inertia_tensor(self) -> Array:
        """(3, 3) [kg m^2]: the full tensor if identified, else the diagonal."""
        return self.full.inertia if self.full is not None else np.diag(self.inertia)

    def com(self) -> list[float] | None:
        """The identified centre of mass (3,) [m] for report.json, None if not."""
        return None if self.full is None else self.full.com.tolist()


@dataclass(frozen=True)
class LogResult:
    """Everything a log run writes: runs (first = the reported one), the log and the
    observations the E-step saw, the smoothed means (N, 12), guess words, exclusions,
    notes and the kind of log (``sdlog``, ``measured-table``, ``simulated``)."""

    runs: tuple[LogRun, ...]
    log: FlightLog
    obs: Observations
    smoothed: Array
    guess: str
    excluded: tuple[str, ...]
    notes: tuple[str, ...]
    kind: str
    extra: dict
    disc_obs: Observations | None = None
    disc_theta: object | None = None
    disc_posterior: object | None = None


def _msteps(args: argparse.Namespace) -> tuple[str, ...]:
    mstep = getattr(args, "mstep", "both") or "both"
    return ("regressor", "paper") if mstep == "both" else (mstep,)


def _guess(log: FlightLog) -> tuple[float, Array, str]:
    from pinquad.realdata.flights import default_guess

    meta = log.meta
    mass0, inertia0, words = default_guess(meta.vehicle)
    parts = []
    if meta.mass_guess is not None:
        mass0 = float(meta.mass_guess)
        parts.append("mass from the log's sidecar")
    if meta.inertia_guess is not None:
        inertia0 = np.asarray(meta.inertia_guess, dtype=float).reshape(3, 3)
        parts.append("inertia from the log's sidecar")
    if len(parts) < 2:
        parts.append(words)
    if not (mass0 > 0 and np.all(np.diag(inertia0) > 0)):
        raise ValueError(f"{meta.source}: initial guess must be positive; got mass {mass0} kg, "
                         f"inertia diagonal {np.diag(inertia0).tolist()} kg m^2")
    return mass0, inertia0, "; ".join(parts)


def default_sensor(log: FlightLog) -> str:
    """A if the log carries an onboard estimate and accelerometer samples, else B if it
    has attitude samples, else C."""
    if log.onboard is not None and np.isfinite(log.accel).any():
        return "A"
    if np.isfinite(log.euler).any():
        return "B"
    return "C"


# ----------------------------------------------------------------------------- measured

def _measured(raw, args: argparse.Namespace, kind: str) -> LogResult:
    from pinquad.identification.identify import identify
    from pinquad.realdata.flights import (
        build_observations,
        corrected,
        identify_real,
        options_for_sensor,
    )

    log = raw.log
    mass0, inertia0, guess = _guess(log)
    sensors = list(args.sensor) if args.sensor else [None]
    msteps = _msteps(args)
    if "full" in msteps:
        raise ValueError(f"{args.log}: --mstep full needs a CSV or Parquet log with thrust "
                         "and torque columns; measured rotor-speed logs are identified with "
                         "the regressor or paper M-step")
    runs: list[LogRun] = []
    first = None
    disc = (None, None, None)
    for sensor in sensors:
        real = build_observations(raw, options_for_sensor(sensor))
        label = sensor or ",".join(real.obs.channels)
        theta = None
        if "regressor" in msteps:
            ident, post, theta = identify_real(
                real, mass0, inertia0, args.max_iterations, not args.no_information,
                name=Path(str(args.log)).name, estep=args.estep)
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
                "e_steps": ident.e_steps,
                "history": ident.history.tolist(),
                "seconds": ident.seconds,
                "model_free_mass": ident.quasi_static_mass,
                "model_free_mass_note": "kf sum omega^2 along the vertical over g + the mean "
                                        "vertical acceleration, the same transitions, no EM "
                                        "(realdata.quasi_static_mass)",
            }
            split = ident.motor_split
            if split is not None:
                detail["motor_split"] = {
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
            runs.append(LogRun(label, "regressor", ident.mass, ident.inertia, ident.se_total,
                               ident.iterations, ident.loglik, ident.converged, detail))
            if first is None:
                first = (real, post.mean)
                disc = (corrected(real.obs, theta), plain_theta(theta), post)
        if "paper" in msteps:
            # The paper's M-step knows no air-speed moment: give it the torques with the
            # regressor run's moment added when there is one.
            obs = real.obs if theta is None else corrected(real.obs, theta)
            ident_p, post_p = identify(obs, mass0, inertia0, log.meta.gravity, args.estep,
                                       "paper", args.max_iterations, False)
            runs.append(LogRun(label, "paper", ident_p.mass, np.diag(ident_p.inertia),
                               np.full(4, np.nan), int(ident_p.loglik.size), ident_p.loglik,
                               ident_p.converged,
                               {"torques": "with the regressor run's nuisance moment"
                                if theta is not None else "rotor torques only",
                                "seconds": ident_p.seconds}))
            if first is None:
                first = (real, post_p.mean)
                disc = (obs, ident_p.noise, post_p)
    assert first is not None
    real, smoothed = first
    extra = {"kf": {"value": real.kf.kf, "stderr": real.kf.kf_se, "pooled": real.kf.pooled,
                    "runs": {r.source: r.kf for r in real.kf.runs}, "note": real.kf.note},
             "faults": list(real.faults.notes)}
    return LogResult(tuple(runs), real.log, real.obs, smoothed, guess, real.excluded,
                     real.notes, kind, extra, *disc)


# ----------------------------------------------------------------------------- simulated

def _simulated(log: FlightLog, args: argparse.Namespace) -> LogResult:
    from pinquad.identification.identify import identify
    from pinquad.models.sources import observations

    mass0, inertia0, guess = _guess(log)
    sensors = list(args.sensor) if args.sensor else [default_sensor(log)]
    runs: list[LogRun] = []
    first = None
    for sensor in sensors:
        obs = observations(log, sensor)
        for mstep in _msteps(args):
            if mstep == "full":
                run, post, theta = _full(obs, sensor, mass0, inertia0, log.meta.gravity, args)
                runs.append(run)
                if first is None:
                    first = (obs, post.mean, theta, post)
                continue
            ident, post = identify(obs, mass0, inertia0, log.meta.gravity, args.estep, mstep,
                                   args.max_iterations, not args.no_information)
            runs.append(LogRun(sensor, mstep, ident.mass, np.diag(ident.inertia), ident.stderr,
                               int(ident.loglik.size), ident.loglik, ident.converged,
                               {"stderr_note": "observed information of the EKF likelihood",
                                "em_failure": ident.failure,
                                "history": np.column_stack([ident.history_mass,
                                                            ident.history_inertia]).tolist(),
                                "seconds": ident.seconds}))
            if first is None:
                first = (obs, post.mean, ident.noise, post)
    assert first is not None
    obs, smoothed, theta, post = first
    n_ex = int(obs.exclude[: obs.n - 1].sum())
    excluded = (f"{n_ex} transitions: touching the floor (the log's contact flags)",
                f"total: {n_ex} of {obs.n - 1} transitions excluded")
    return LogResult(tuple(runs), log, obs, smoothed, guess, excluded, tuple(log.meta.notes),
                     "simulated", {}, obs, theta, post)


def _full(obs: Observations, sensor: str, mass0: float, inertia0: Array, gravity: float,
          args: argparse.Namespace):
    """EM over all ten inertial parameters (``pinquad.identification.full_inertia``) from the staged
    start (``full_inertia.staged_start``: the diagonal model's EM from the paper's guess,
    refitted with the horizontal CoM), compiled E-step throughout: (LogRun, posterior,
    theta)."""
    from pinquad.discovery.staged import staged_start
    from pinquad.estep.fast_smoother import smooth_quad
    from pinquad.identification.full_inertia import identify_full

    start = staged_start(obs, mass0, inertia0, gravity, smooth_quad)
    res = identify_full(obs, start, smooth_quad, max_iterations=args.max_iterations,
                        information=not args.no_information)
    stderr = np.concatenate([[res.stderr_mass], np.diag(res.stderr_inertia)])
    run = LogRun(sensor, "full", res.mass, np.diag(res.inertia).copy(), stderr,
                 int(res.loglik.size), res.loglik, res.converged,
                 {"stderr_note": "observed information of the EKF likelihood over all ten "
                                 "parameters (delta method to CoM and inertia)",
                  "em_failure": res.failure, "e_steps": res.e_steps,
                  "start": {"note": "diagonal EM from the paper's guess, refitted with the "
                                    "horizontal CoM (full_inertia.staged_start)",
                            "mass": start.mass, "com": start.com.tolist(),
                            "inertia_diag": np.diag(start.inertia).tolist()},
                  "stderr_full": {"com": res.stderr_com.tolist(),
                                  "inertia": res.stderr_inertia.tolist()}},
                 full=res)
    return run, res.posterior, res.theta


# ----------------------------------------------------------------------------- output

def _table(result: LogResult) -> str:
    from pinquad.realdata.flights import PUBLISHED_INERTIA, SCALE_MASS

    crazyflie = result.log.meta.vehicle == "crazyflie21"
    head = "| sensor | M-step | mass [g] | I_xx [1e-6 kg m^2] | I_yy | I_zz | EM iterations |"
    lines = [head, "|---|---|---|---|---|---|---|"]

    def pm(v: float, s: float, scale: float, fmt: str) -> str:
        return f"{v * scale:{fmt}}" + ("" if not np.isfinite(s) else f" ± {s * scale:{fmt}}")

    for r in result.runs:
        lines.append(
            f"| {r.sensor} | {r.mstep} | {pm(r.mass, r.stderr[0], 1e3, '.3f')} | "
            + " | ".join(pm(r.inertia[i], r.stderr[i + 1], 1e6, ".2f") for i in range(3))
            + f" | {r.iterations}{'' if r.converged else ' (not converged)'} |")
    if crazyflie:
        lines.append(f"| scale / published | | {SCALE_MASS * 1e3:.1f} | "
                     + " | ".join(f"{v * 1e6:.2f}" for v in PUBLISHED_INERTIA) + " | |")
        for r in result.runs:
            lines.append(f"\n{r.sensor}, {r.mstep} M-step: mass {r.mass * 1e3:.2f} g vs "
                         f"{SCALE_MASS * 1e3:.1f} g on the scale: "
                         f"{100 * (r.mass / SCALE_MASS - 1):+.2f} %"
                         + ("" if not np.isfinite(r.stderr[0]) else
                            f" ({abs(r.mass - SCALE_MASS) / r.stderr[0]:.1f} standard errors)"))
            free = r.detail.get("model_free_mass")
            if free is not None and np.isfinite(free):
                lines.append(f"{r.sensor}, model-free check (mean vertical thrust, no EM): "
                             f"{free * 1e3:.2f} g ({100 * (free / SCALE_MASS - 1):+.2f} %)")
            split = r.detail.get("motor_split")
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
                        f"({100 * (own / SCALE_MASS - 1):+.2f} %)")
    for r in result.runs:
        if r.full is not None:
            full = r.full
            lines.append(f"\n{r.sensor}, full M-step: centre of mass [mm] "
                         + ", ".join(pm(full.com[i], full.stderr_com[i], 1e3, ".3f")
                                     for i in range(3)))
            lines.append(f"{r.sensor}, full M-step: products of inertia [1e-6 kg m^2] "
                         + ", ".join(f"I_{a}{b} " + pm(full.inertia[i, j],
                                                       full.stderr_inertia[i, j], 1e6, ".2f")
                                     for (i, a), (j, b) in (((0, "x"), (1, "y")),
                                                            ((0, "x"), (2, "z")),
                                                            ((1, "y"), (2, "z")))))
    return "\n".join(lines)


def _plot_residuals(obs: Observations, smoothed: Array, path: Path) -> None:
    """Measurement residuals y - H m over time, one panel per channel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pinquad.core.conventions import wrap_angle

    h = obs.measurement_matrix()
    pred = smoothed @ h.T
    res = obs.ys - pred
    angle = obs.angle_rows()
    if angle.size:
        res[:, angle] = wrap_angle(res[:, angle])
    units = {"pos": "m", "vel": "m/s", "euler": "rad", "gyro": "rad/s"}
    fig, axes = plt.subplots(len(obs.channels), 1, figsize=(10, 2.4 * len(obs.channels)),
                             sharex=True, squeeze=False)
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
    plt.close(fig)


def _report(result: LogResult, args: argparse.Namespace, seconds: float) -> dict:
    main = result.runs[0]
    se = main.stderr
    return {
        "schema": REPORT_SCHEMA,
        "source": {"kind": "log", "path": str(args.log), "sensor": main.sensor,
                   "estep": args.estep, "log_type": result.kind,
                   "vehicle": result.log.meta.vehicle, "mstep": main.mstep},
        "estimates": {"mass": main.mass, "inertia": main.inertia_tensor().tolist(),
                      "com": main.com(),
                      "stderr": {"mass": se[0], "inertia_diag": se[1:].tolist()}},
        "em": {"iterations": main.iterations, "loglik": main.loglik.tolist(),
               "converged": bool(main.converged)},
        "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                      "validation": "not run"},
        "excluded": list(result.excluded),
        "cycles": [],
        "run_logs": {"log": {"log": "logs/flight.parquet",
                             "smoothed": "logs/flight-smoothed.npy"}},
        "initial_guess": result.guess,
        "runs": [{"sensor": r.sensor, "mstep": r.mstep,
                  "estimates": {"mass": r.mass, "inertia": r.inertia_tensor().tolist(),
                                "com": r.com(),
                                "stderr": {"mass": r.stderr[0],
                                           "inertia_diag": r.stderr[1:].tolist()}},
                  "em": {"iterations": r.iterations, "loglik": r.loglik.tolist(),
                         "converged": bool(r.converged)},
                  **r.detail} for r in result.runs],
        "notes": list(result.notes),
        "seconds": seconds,
        **result.extra,
    }


def run_discovery(result: LogResult, figs: Path) -> dict:
    """Effect discovery (``pinquad.discovery.discover.discover.discover``) on the reported run: the DESIGN 4.3
    ``discovery`` section, figures written to ``figs`` and named relative to the run
    directory. A numerical failure of the refit is reported in the section (key
    ``error``) instead of stopping the run: the identification stands without it."""
    from pinquad.discovery.discover import discover
    from pinquad.discovery.result import DiscoveryConfig
    from pinquad.report.discovery import draw_discovery_figures

    if result.disc_obs is None or result.disc_posterior is None:
        return {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                "validation": "not run", "error": "no EM run to start from"}
    cfg = DiscoveryConfig(**DISCOVERY_SETTINGS.get(result.kind, {}))
    try:
        out = draw_discovery_figures(discover(result.disc_obs, result.disc_theta,
                                              result.disc_posterior, cfg=cfg), figs)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        return {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                "validation": "not run", "error": f"discovery failed numerically: {exc}"}
    section = out.to_report()
    section["figures"] = [f"figures/{Path(f).name}" for f in section["figures"]]
    return section


DISCOVERY_SETTINGS: dict[str, dict] = {"sdlog": {"refit_em": False},
                                        "measured-table": {"refit_em": False}}
"""DiscoveryConfig overrides by log kind (``simulated``, ``sdlog``, ``measured-table``).
Measured flights keep the base inertia of ``realdata``'s band-limited M-step (the
plain regressor M-step of the EM refit does not hold it: on jana10 it moved I_xx from 17
to 24 e-6 kg m^2); their effects and the mass are fitted on the base posterior."""


def discovery_summary(section: dict) -> str:
    """A few printed lines: what was selected, its coefficients and the held-out RMS."""
    if "error" in section:
        return f"effect discovery: {section['error']}"
    sel = section["selected"]
    if not sel:
        return "effect discovery: no significant unmodelled effect (held-out test)"
    lines = [f"effect discovery: selected {', '.join(s['effect'] for s in sel)}"]
    for s in sel:
        co = ", ".join(f"{n} = {v:.4g} ± {s['stderr'][n]:.2g} {s['units'][n]}"
                       for n, v in s["coefficients"].items())
        lines.append(f"  {s['effect']}: {co}; held-out gain "
                     f"{100 * s['evidence']['heldout_gain']:.0f} %")
    refit = section.get("refit")
    if refit:
        inertia = np.diag(np.asarray(refit["inertia"])) * 1e6
        lines.append(f"  refit with the effects: mass {refit['mass'] * 1e3:.3f} g, inertia diagonal "
                     f"({', '.join(f'{v:.2f}' for v in inertia)}) 1e-6 kg m^2")
    b, a = section["residual_rms_before"], section["residual_rms_after"]
    lines.append("  held-out residual RMS before -> after: " + ", ".join(
        f"{k} {b[k]:.3g} -> {a[k]:.3g}" for k in b))
    return "\n".join(lines)


def _load(args: argparse.Namespace) -> LogResult:
    from pinquad.io.logs import read_log
    from pinquad.io.sdlog import is_sdlog, read_sdflight
    from pinquad.realdata.flights import RawFlight, raw_from_sdflight

    path = Path(args.log)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file; expected a CSV, Parquet or Crazyflie "
                             "micro-SD log")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a log file")
    if is_sdlog(path):
        return _measured(raw_from_sdflight(read_sdflight(path)), args, "sdlog")
    log = read_log(path)
    if log.thrust is not None:
        return _simulated(log, args)
    return _measured(RawFlight(log=log), args, "measured-table")


def identify_log(args: argparse.Namespace) -> int:
    """Identify the vehicle of ``args.log`` and write a run directory (module docstring).

    Raises LogFormatError / ValueError (with the file named) on bad input; returns 0.
    """
    from pinquad.io.logs import write_log
    from pinquad.io.runs import RunWriter, atomic_write_json, new_run_dir
    from pinquad.report.offline import plot_trajectory

    t0 = time.perf_counter()
    print(f"pinquad offline --log {args.log}: E-step {args.estep}, "
          f"M-step(s) {', '.join(_msteps(args))}")
    try:
        result = _load(args)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"{args.log}: EM failed numerically ({exc}); the log's actuation and "
                         "measurements do not fit a rigid-body model from the initial "
                         "guess (give mass_guess / inertia_guess in the sidecar)") from None
    seconds = time.perf_counter() - t0
    print(f"log type: {result.kind}; {result.obs.n} steps of {result.obs.dt * 1e3:.0f} ms")
    print(f"initial guess: {result.guess}")
    for line in result.excluded:
        print(f"excluded: {line}")
    for note in result.notes:
        print(f"note: {note}")
    print()
    print(_table(result))
    print(f"\n{seconds:.1f} s")

    out_dir = args.out or new_run_dir("log")
    writer = RunWriter(out_dir)
    try:
        figs = writer.path("figures")
        figs.mkdir(exist_ok=True)
        discovery = None
        if result.runs[0].mstep == "full" and not args.no_discover:
            print("\neffect discovery: not run (it works on the diagonal model: run "
                  "--mstep regressor for it)")
        elif not args.no_discover:
            discovery = run_discovery(result, figs)
            print()
            print(discovery_summary(discovery))
        logs_dir = writer.path("logs")
        logs_dir.mkdir(exist_ok=True)
        write_log(result.log, logs_dir / "flight.parquet")
        np.save(logs_dir / "flight-smoothed.npy", result.smoothed)
        plot_trajectory(result.log, None, figs / "trajectory.png", result.smoothed)
        _plot_residuals(result.obs, result.smoothed, figs / "residuals.png")
        report = _report(result, args, seconds)
        if discovery is not None:
            report["discovery"] = discovery
        atomic_write_json(writer.path("report.json"), report)
        md = (f"# pinquad: identification from {args.log}\n\n" + _table(result) + "\n\n"
              + "\n".join(f"- excluded: {e}" for e in result.excluded) + "\n"
              + "".join(f"- note: {n}\n" for n in result.notes))
        if discovery is not None:
            from pinquad.report.discovery import discovery_markdown

            md += "\n" + discovery_markdown(discovery)
        writer.path("report.md").write_text(md)
        final = writer.publish()
    except BaseException:
        writer.abort()
        raise
    print(f"run written to {final}")
    if getattr(args, "view", False):
        from viz.__main__ import main as viz_main

        return viz_main([str(final)])
    return 0
