"""Seeded Monte Carlo of effect discovery on flights pinquad did not simulate
(``python -m pinquad.discovery --generator flightgen``; docs/discovery_flightgen.md).

For each log rate (100, 250, 500 Hz), condition (no effect, or one vocabulary effect at
the realistic Crazyflie-class value of ``pinquad.sim.effects``' defaults) and seed:

1. fly the Crazyflie-class vehicle of ``flightgen`` (its own RK4 on quaternions at
   0.5 ms, its own geometric controller at that rate, the actuation SAMPLED at each log
   row, motion capture at 100 Hz, default noise, no floor, one pass 7 cm above the ground
   plane: ``flight_spec``) with the effect in the truth;
2. write its CSV with ``flightgen.write_csv`` (the log does not mention the effect);
3. put it through the pipeline of ``python -m pinquad.offline --log``
   (``pinquad.pipeline.single``: read, check, identify, discover, judge) with the Monte
   Carlo's options (``FG_OPTIONS``: regressor M-step, at most 100 E-steps, standard
   errors);
4. score: the names selected, each injected effect's coefficients against the truth
   (``|c - c0| / |c0|``, max over its coefficients), the held-out gain of the round that
   selected it, and the base EM's and the final mass / inertia against the truth; on
   drag flights also D_z's error from the flight's own thrust noise alone
   (``noise_only_drag_error``): what an estimator that knew every state would get.

Targets: clean flights nothing selected in >= 19/20 at each rate; each effect
named in >= 19/20, coefficients within 10 %. ``flightgen`` is imported here only (the
experiments layer); it imports nothing of pinquad.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flightgen import CRAZYFLIE, Effects, Flight, FlightSpec, generate, write_csv
from flightgen.rotation import quats_to_rots
from flightgen.trajectory import excursion
from pinquad.experiments.discovery_mc import in_order
from pinquad.io.logs import FlightLog
from pinquad.models.attitude_range import near_euler_singularity
from pinquad.models.contact import touching_transitions
from pinquad.models.sources import floor_contact
from pinquad.pipeline.identify import LogOptions, initial_guess
from pinquad.pipeline.single import PipelineOptions, read, run
from pinquad.sim import effects as sim_effects

FG_CONDITIONS: tuple[str, ...] = ("none", "drag", "ground_effect", "com_offset", "wind",
                                  "motor_lag", "gyro_bias", "floor_strikes")
"""Conditions: no effect, one effect at its ``pinquad.sim.effects`` default, or
``floor_strikes``: no effect, but a floor that the flight takes off from, strikes twice
and lands on, with no contact column in the log (nothing may be selected for
the contact, and the contact transitions must be found from the data)."""

FLOOR_CONDITION = "floor_strikes"

LOG_RATES: tuple[int, ...] = (100, 250, 500)
PARAMS = ("mass", "I_xx", "I_yy", "I_zz")

FG_OPTIONS = PipelineOptions(identification=LogOptions(
    msteps=("regressor",), estep="rts", max_iterations=100, information=True))
"""The pipeline's options for every flight: the regressor M-step with the RTS E-step, at
most 100 E-steps per EM run (``offline --log`` allows ``pipeline.single.
LOG_MAX_ITERATIONS``), standard errors (the coefficients' are scored), discovery with the
default null calibration."""

LOWEST_PASS = 0.07
"""Lowest point of the reference [m] above the ground plane: every flight's hover point
is set so that its vertical excursion comes down to 7 cm once (as the low pass of
``discovery_mc``'s route), where a ground effect of k_ge = 1 adds ~2.7 % of the thrust
and nothing else changes (the flights have no floor to touch: ``floor=None``)."""


def injected(condition: str) -> dict[str, float]:
    """Coefficient name -> injected value of ``condition`` (``pinquad.sim.effects``
    defaults: drag D = (0.0062, 0.0062, 0.0070) N s/m, k_ge = 1, CoM (3, -2) mm, wind
    (10, -6) mN, motor lag 30 ms, gyro bias (0.03, -0.02, 0.015) rad/s); {} for none."""
    if condition in ("none", FLOOR_CONDITION):
        return {}
    return sim_effects.injected_coefficients(condition)


def flightgen_effects(condition: str) -> Effects:
    """The ``flightgen.Effects`` of ``condition`` (same meanings and units as the vocabulary's)."""
    values = list(injected(condition).values())
    if not values:
        return Effects()
    arg: float | tuple[float, ...] = values[0] if len(values) == 1 else tuple(values)
    return Effects(**{condition: arg})


def flight_spec(condition: str, seed: int, index: int, log_rate: int,
                duration: float | None = None) -> FlightSpec:
    """Flight ``index`` of a condition: durations cycle 30, 40, 20 s (``duration`` [s]
    instead, when given: the benchmark's 60 s log); every other flight is aggressive
    (6 m/s^2 peak reference acceleration, else 1.5); trajectories alternate sums of sines
    and minimum-snap splines in pairs; the hover point puts the reference's lowest point
    at ``LOWEST_PASS``; no floor. ``floor_strikes``: the same flight about a 1 m hover
    (flightgen keeps its excursion within 0.6-1.4 m), taking off from the floor, dipping
    5 cm into it twice and landing on it (``flightgen.Floor``'s contact)."""
    dt = 0.0005
    if duration is None:
        duration = (30.0, 40.0, 20.0)[index % 3]
    kind, aggressive = ("sines", "minsnap")[(index // 2) % 2], index % 2 == 0
    # the reference's excursion is the first thing flightgen.generate draws from the
    # seed's generator, so a fresh generator of the same seed reproduces it
    t = np.arange(int(round(duration / dt)) + 1) * dt
    if condition == FLOOR_CONDITION:
        return FlightSpec(duration=duration, trajectory=kind, aggressive=aggressive,
                          log_rate=log_rate, dt=dt, seed=seed, vehicle=CRAZYFLIE,
                          start_on_floor=True, land=True, floor_strikes=2)
    lowest = float(excursion(t, kind, aggressive, np.random.default_rng(seed))[0, :, 2].min())
    return FlightSpec(duration=duration, trajectory=kind, aggressive=aggressive,
                      log_rate=log_rate, dt=dt, seed=seed, vehicle=CRAZYFLIE,
                      effects=flightgen_effects(condition), hover_height=LOWEST_PASS - lowest,
                      floor=None)


def case_seed(base: int, condition: str, i: int) -> int:
    """Flight seed: base * 100000 + condition index * 1000 + i (the same at every rate)."""
    return base * 100000 + FG_CONDITIONS.index(condition) * 1000 + i


@dataclass(frozen=True)
class FlightgenCase:
    """One seeded case: condition, log rate [Hz], seed, flight index, duration [s],
    aggressive, trajectory; selected effect names (in order); coefficients by effect;
    coef_rel_err: the injected effect's max relative coefficient error (NaN: not
    selected or no effect); gain: held-out gain of the round that selected it (NaN);
    base_err / final_err (4,): relative errors of [m, I_xx, I_yy, I_zz] of the base EM
    and of the reported estimate (the refit when an effect is selected); seconds;
    null_rejected: effects the uncalibrated selection chose that the null calibration
    (``pinquad.discovery.null``, 19 shadow flights) rejected; verdicts: parameter ->
    the reported estimate's verdict (``offline --log``'s headline; empty in runs made
    before it was recorded); contact_true / contact_found / contact_missed /
    contact_off: transitions that touch the floor in the truth, found from the data
    among them, missed, and found where the vehicle was off the floor (all 0 on flights
    without a floor); coef_stderr: effect -> the standard errors discovery printed beside
    its coefficients (None in runs made before they were recorded); singular_excluded:
    transitions excluded for an attitude near the Euler angles' singularity
    (``models.attitude_range``; 0 in runs made before); noise_only_err: on drag flights,
    D_z's relative error from the process noise alone (``noise_only_drag_error``; NaN
    on other conditions and in runs made before it was recorded)."""

    condition: str
    log_rate: int
    seed: int
    index: int
    duration: float
    aggressive: bool
    trajectory: str
    selected: tuple[str, ...]
    coefficients: dict[str, list[float]]
    coef_rel_err: float
    gain: float
    base_err: tuple[float, ...]
    final_err: tuple[float, ...]
    seconds: float
    null_rejected: tuple[str, ...] = ()
    verdicts: dict[str, str] | None = None
    contact_true: int = 0
    contact_found: int = 0
    contact_missed: int = 0
    contact_off: int = 0
    coef_stderr: dict[str, list[float]] | None = None
    singular_excluded: int = 0
    noise_only_err: float = math.nan

    def to_json(self) -> dict:
        d = dict(self.__dict__)
        d["selected"] = list(self.selected)
        d["base_err"] = list(self.base_err)
        d["final_err"] = list(self.final_err)
        d["null_rejected"] = list(self.null_rejected)
        return d


def true_contact_transitions(flight: Flight, n_rows: int) -> NDArray[np.bool_]:
    """(n_rows - 1,) bool: log transition k -> k+1 touches the floor at any integrator
    step within it or at its end (``Flight.in_contact``, truth only)."""
    step = int(round(1.0 / (flight.spec.log_rate * flight.spec.dt)))
    touched = flight.in_contact[: (n_rows - 1) * step].reshape(n_rows - 1, step).any(axis=1)
    touched |= flight.in_contact[step: n_rows * step: step][: n_rows - 1]
    return touched


def noise_only_drag_error(flight: Flight) -> float:
    """D_z's relative error [-] that the flight's own thrust noise leaves to an estimator
    that knew every state and every other force: what an unbiased estimate from the log
    can be expected to reach, not a bound on any single flight's.

    The truth's body-z force is F + n_k - D_z v_z,k, with n_k [N] the thrust noise of
    integrator step k (applied minus commanded thrust: drag flights carry no motor lag)
    and v_z,k = (R_k^T v_k)_z [m/s] the true vertical body velocity. Least squares of the
    residual n_k - D_z v_z,k on -v_z,k over the steps gives
    D_z_hat - D_z = -sum(n v_z) / sum(v_z^2); returned relative to D_z. The thrust noise
    lies along body z, so it leaves D_x and D_y alone."""
    drag = flight.spec.effects.drag
    if drag is None or flight.spec.effects.motor_lag:
        return math.nan
    noise = flight.applied[:, 0] - flight.command[:, 0]
    v_body_z = np.einsum("nj,nj->n", quats_to_rots(flight.state[:, 6:10])[:, :, 2],
                         flight.state[:, 3:6])
    return float(-(noise @ v_body_z) / (v_body_z @ v_body_z) / drag[2])


def found_contact_transitions(log: FlightLog) -> NDArray[np.bool_]:
    """(N - 1,) bool: transitions touching the floor contact found from the data, as
    the pipeline's identify step finds it (its other exclusions, such as an attitude near
    the Euler singularity, are not floor contact)."""
    return touching_transitions(floor_contact(log, initial_guess(log)[0]).rows)


def run_case(condition: str, log_rate: int, seed: int, index: int, workdir: Path
             ) -> FlightgenCase:
    """Fly, write CSV, and put it through ``offline --log``'s pipeline (``FG_OPTIONS``)."""
    t0 = time.perf_counter()
    spec = flight_spec(condition, seed, index, log_rate)
    flight = generate(spec)
    path = write_csv(flight, workdir / f"fg-{condition}-{log_rate}-{seed}.csv")
    log = read(path)
    piped = run(log, FG_OPTIONS, source=str(path))
    result, outcome, judged = piped.identified, piped.outcome, piped.verdict
    assert outcome is not None  # a regressor fit, discovery asked for: always run
    truth_contact = true_contact_transitions(flight, result.obs.n)
    found = found_contact_transitions(log)
    singular = near_euler_singularity(log.t, log.euler).transitions()
    section = outcome.to_report()
    truth = np.r_[CRAZYFLIE.mass, np.diag(CRAZYFLIE.inertia_matrix)]
    base = np.r_[piped.run.mass, np.diag(piped.run.inertia)]
    # the headline: discovery's refit when it selected effects, else the base fit
    final = np.r_[piped.mass, piped.inertia_diag]
    coefs = {s["effect"]: [float(v) for v in s["coefficients"].values()]
             for s in section["selected"]}
    stderr = {s["effect"]: [float(v) for v in s["stderr"].values()]
              for s in section["selected"]}
    err, gain = math.nan, math.nan
    if condition in coefs:
        c0 = np.asarray(list(injected(condition).values()))
        err = float(np.max(np.abs(np.asarray(coefs[condition]) - c0) / np.abs(c0)))
        assert outcome.result is not None
        gain = next(s.gain for s in outcome.result.scores if s.effect == condition and s.passed)
    return FlightgenCase(condition, log_rate, seed, index, spec.duration, spec.aggressive,
                         spec.trajectory, tuple(coefs), coefs, err, gain,
                         tuple((base / truth - 1.0).tolist()),
                         tuple((final / truth - 1.0).tolist()), time.perf_counter() - t0,
                         () if outcome.null is None else tuple(outcome.null.rejected),
                         {p.name: p.verdict for p in judged.parameters},
                         int(truth_contact.sum()), int((found & truth_contact).sum()),
                         int((truth_contact & ~found).sum()), int((found & ~truth_contact).sum()),
                         stderr, singular, noise_only_drag_error(flight))


@dataclass(frozen=True)
class FlightgenJob:
    """One case to run (picklable for the process pool)."""

    condition: str
    log_rate: int
    seed: int
    index: int
    workdir: str


def run_job(job: FlightgenJob) -> FlightgenCase:
    """``run_case`` of one job (module level: the process pool pickles it)."""
    return run_case(job.condition, job.log_rate, job.seed, job.index, Path(job.workdir))


def plan(conditions: Sequence[str], rates: Sequence[int], seeds: int, base_seed: int = 0,
         start_index: int = 0, workdir: str = ".") -> list[FlightgenJob]:
    """The jobs of a run: every rate x condition x seed index."""
    return [FlightgenJob(c, r, case_seed(base_seed, c, i), i, workdir) for r in rates
            for c in conditions for i in range(start_index, start_index + seeds)]


def run_cases(work: Sequence[FlightgenJob], executor: Executor) -> Iterator[FlightgenCase]:
    """Each job's case in the order of ``work``, run by ``executor`` (``in_order``)."""
    return in_order(run_job, work, executor)


def _median_max(values: list[float]) -> tuple[float, float]:
    v = [x for x in values if math.isfinite(x)]
    return (float(np.median(v)), float(np.max(v))) if v else (math.nan, math.nan)


def stderr_scores(case: FlightgenCase) -> NDArray[np.float64] | None:
    """(p,) z = (c - c0) / se of the injected effect's coefficients against the standard
    errors printed beside them; None when the effect was not named, no effect was
    injected or the case has no standard errors recorded."""
    truth = injected(case.condition)
    if case.coef_stderr is None or not truth or case.condition not in case.coefficients:
        return None
    c0 = np.asarray(list(truth.values()))
    c = np.asarray(case.coefficients[case.condition])
    return (c - c0) / np.asarray(case.coef_stderr[case.condition])


def within_stderr(case: FlightgenCase, k: float) -> bool | None:
    """Whether every coefficient of the injected effect lies within k of the standard
    errors printed beside it, |c - c0| <= k se (False: the effect was not named); None
    when the case has no standard errors recorded or no effect was injected."""
    if case.coef_stderr is None or not injected(case.condition):
        return None
    z = stderr_scores(case)
    return False if z is None else bool(np.all(np.abs(z) <= k))


def summarize(cases: Sequence[FlightgenCase]) -> list[dict]:
    """One row per (log rate, condition): counts against the targets (module docstring)."""
    rows = []
    for rate in LOG_RATES:
        for cond in FG_CONDITIONS:
            cs = [c for c in cases if c.log_rate == rate and c.condition == cond]
            if not cs:
                continue
            row: dict = {"log_rate": rate, "condition": cond, "n": len(cs),
                         "seeds": [c.seed for c in cs],
                         "nothing_selected": sum(not c.selected for c in cs),
                         "extra_selected": sorted({e for c in cs for e in c.selected
                                                   if e != cond}),
                         "null_rejected": sum(bool(c.null_rejected) for c in cs),
                         "null_rejected_effects": sorted({e for c in cs
                                                          for e in c.null_rejected})}
            judged = [c for c in cs if c.verdicts]
            # a confident wrong answer: a parameter more than 10 % off, called trusted
            row["judged"] = len(judged)
            row["trusted_but_off"] = {
                p: sum(c.verdicts.get(p) == "trusted" and abs(c.final_err[i]) > 0.10
                       for c in judged) for i, p in enumerate(PARAMS)}
            row["off_flagged"] = {
                p: sum(c.verdicts.get(p) != "trusted" and abs(c.final_err[i]) > 0.10
                       for c in judged) for i, p in enumerate(PARAMS)}
            base = np.array([c.base_err for c in cs])
            final = np.array([c.final_err for c in cs])
            row["base_rms_rel_err"] = dict(zip(PARAMS, np.sqrt(np.mean(base**2, axis=0)).tolist(),
                                               strict=True))
            row["final_rms_rel_err"] = dict(zip(PARAMS,
                                                np.sqrt(np.mean(final**2, axis=0)).tolist(),
                                                strict=True))
            if cond == FLOOR_CONDITION:
                row["contact"] = {k: sum(getattr(c, f"contact_{k}") for c in cs)
                                  for k in ("true", "found", "missed", "off")}
                row["singular_flights"] = sum(c.singular_excluded > 0 for c in cs)
                row["singular_excluded"] = sum(c.singular_excluded for c in cs)
                row["contact_all_found"] = sum(c.contact_missed == 0 and c.contact_true > 0
                                               for c in cs)
            elif cond != "none":
                errs = [c.coef_rel_err for c in cs]
                row["named"] = sum(cond in c.selected for c in cs)
                row["exact"] = sum(c.selected == (cond,) for c in cs)
                row["coef_within_10pct"] = sum(math.isfinite(e) and e <= 0.10 for e in errs)
                noise_only = [abs(c.noise_only_err) for c in cs
                              if math.isfinite(c.noise_only_err)]
                if noise_only:
                    # what the thrust noise alone leaves within 10 %: an estimator that
                    # knew every state would reach about this count
                    row["noise_only_n"] = len(noise_only)
                    row["noise_only_within_10pct"] = sum(e <= 0.10 for e in noise_only)
                covered = [within_stderr(c, 2.0) for c in cs]
                row["coef_with_stderr"] = sum(v is not None for v in covered)
                row["coef_within_2se"] = sum(bool(v) for v in covered)
                # per coefficient: about 1 when the printed errors are the real ones,
                # above when they are too small, below when too large
                scores = [z for z in (stderr_scores(c) for c in cs) if z is not None]
                row["coef_z_rms"] = (np.sqrt(np.mean(np.square(scores), axis=0)).tolist()
                                     if scores else [])
                row["coef_err_median"], row["coef_err_max"] = _median_max(errs)
                row["gain_median"] = _median_max([c.gain for c in cs])[0]
            rows.append(row)
    return rows


def read_cases(path: Path) -> list[FlightgenCase]:
    """The cases of a ``cases.jsonl`` written by ``append_case``, or of a run's
    ``discovery_mc_flightgen.json`` (its ``cases``)."""
    text = Path(path).read_text()
    if Path(path).suffix == ".json":
        records = json.loads(text)["cases"]
    else:
        records = [json.loads(line) for line in text.splitlines() if line.strip()]
    out = []
    for d in records:
        d["selected"] = tuple(d["selected"])
        d["base_err"], d["final_err"] = tuple(d["base_err"]), tuple(d["final_err"])
        d["null_rejected"] = tuple(d.get("null_rejected", ()))
        out.append(FlightgenCase(**d))
    return out


def append_case(out: Path, case: FlightgenCase) -> None:
    """Append one case to ``out / cases.jsonl`` (a run interrupted keeps what it did)."""
    with (out / "cases.jsonl").open("a") as f:
        f.write(json.dumps(case.to_json()) + "\n")
