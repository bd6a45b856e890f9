"""One recorded log through pinquad: read -> check -> identify -> discover -> judge ->
``PipelineResult``.

Every step is a function of the previous step's output (the data flows one way):

- read: the log file (CSV, Parquet or Crazyflie micro-SD binary, ``pinquad.io.read``),
  with the vehicle named by the caller, if any, overriding its sidecar's;
- check: its columns against physics (``pinquad.io.sanity.check_log``: units, impossible
  values, declared conventions) before any EM;
- identify: mass [kg] and inertia (3, 3) [kg m^2] by EM, every run asked for
  (``pinquad.pipeline.identify``);
- discover: the unmodelled effects of the reported run, calibrated against shadow
  flights of the base fit, behind the guard every caller gets (``pinquad.pipeline.discover``);
- judge: the headline estimate under the final model with its error budget and verdict
  (``pinquad.pipeline.judge``).

The pipeline computes; it writes nothing and prints nothing. The report it makes (the
terminal summary, the run directory) is ``pinquad.Result``'s (``pinquad.results``), which
the command line (``python -m pinquad.offline --log``), the Python API and the batch
(``pinquad.identify_many``) return or write.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.calibrated import DiscoveryOutcome
from pinquad.discovery.null import NullSettings
from pinquad.discovery.result import DiscoveryResult
from pinquad.identification.identify import Identification
from pinquad.identification.verdict import EstimateVerdict
from pinquad.io.logs import FlightLog
from pinquad.io.read import read_log
from pinquad.io.sanity import check_log
from pinquad.pipeline.discover import run_discovery
from pinquad.pipeline.identify import LogOptions, LogResult, identify_log
from pinquad.pipeline.judge import Headline, VehicleEstimate, headline, run_verdict

LOG_MAX_ITERATIONS = 200
"""E-steps at most per EM run of a recorded log from the command line and the API: a
measured flight's band-limited M-step is not accelerated, and a 40 s yaw sweep of the
shared Crazyflie logs needs about 130."""

FULL_NOT_DISCOVERED = ("effect discovery: not run (it works on the diagonal model: run "
                       "--mstep regressor for it)")
"""Why a ten-parameter fit gets no effect discovery, as printed."""


@dataclass(frozen=True)
class PipelineOptions:
    """How one log goes through the pipeline.

    identification: the EM runs (``LogOptions``: sensors, M-steps, E-step, iterations
    (default ``LOG_MAX_ITERATIONS``), standard errors, torque band); null: the
    calibration of discovery's selection against shadow flights (``NullSettings``;
    replicates 0: off); discover: look for unmodelled effects; vehicle: a shipped vehicle
    name or a ``.toml`` vehicle file (relative paths from the working directory) that
    overrides the log's sidecar, None: the log's own; payload_mass [kg]: a load the
    vehicle carried that its file does not hold, overriding the sidecar's
    ``payload_mass`` (None: the log's own), added to the file's reference mass.
    """

    identification: LogOptions = field(
        default_factory=lambda: LogOptions(max_iterations=LOG_MAX_ITERATIONS))
    null: NullSettings = field(default_factory=NullSettings)
    discover: bool = True
    vehicle: str | None = None
    payload_mass: float | None = None


def read(path: str | Path, vehicle: str | None = None,
         payload_mass: float | None = None) -> FlightLog:
    """The flight recorded in ``path``, its vehicle set to ``vehicle`` and the payload it
    carried to ``payload_mass`` [kg] when given. Raises
    ``pinquad.io.logs.LogFormatError`` naming the file and the column, row or byte offset
    when it is not a readable log, or the vehicle when it is not one."""
    log = read_log(path, vehicle)
    if payload_mass is None:
        return log
    return replace(log, meta=replace(log.meta, payload_mass=float(payload_mass)))


def check(log: FlightLog) -> FlightLog:
    """The log, once its columns passed the physics checks (``pinquad.io.sanity``: units,
    impossible values, conventions). Raises ``ImplausibleLogError`` naming the log, the
    column and what was expected."""
    check_log(log)
    return log


def identify(log: FlightLog, options: LogOptions | None = None,
             executor: Executor | None = None) -> LogResult:
    """Check the log against physics, then identify its vehicle by EM (every run of
    ``options``; ``executor``: where the runs beyond the reported one go, the same
    answer). Raises ``ImplausibleLogError`` / ValueError naming the log on bad input,
    numpy's LinAlgError when EM fails numerically."""
    return identify_log(log, options, executor)  # runs check first


def identify_run(log: FlightLog, options: LogOptions) -> Identification:
    """The reported run of ``identify`` with its own verdict (``Identification.verdict``:
    per parameter, trusted or why not)."""
    identified = identify(log, options)
    run = identified.runs[0]
    return replace(run, verdict=run_verdict(identified, run))


def discover(identified: LogResult, null: NullSettings | None = None,
             executor: Executor | None = None) -> DiscoveryOutcome:
    """Effect discovery on the reported run with the settings for the log's kind; a
    numerical failure, an unconverged base fit or one outside the physical set is said in
    the outcome, not raised (the identification stands without it)."""
    return run_discovery(identified, null, executor)


def discovered(identified: LogResult, null: NullSettings | None = None,
               executor: Executor | None = None) -> tuple[DiscoveryOutcome | None, str | None]:
    """(discovery's outcome, why it was not run): ``discover`` on a diagonal-model fit;
    (None, ``FULL_NOT_DISCOVERED``) for a ten-parameter one. The one discovery step of
    ``run`` and ``with_discovery``."""
    if identified.runs[0].mstep == "full":
        return None, FULL_NOT_DISCOVERED
    return discover(identified, null, executor), None


def judge(identified: LogResult, outcome: DiscoveryOutcome | None) -> Headline:
    """The headline: the estimate under the final model (discovery's refit when it
    selected effects, else the base fit), its error budget and verdict."""
    return headline(identified, outcome)


@dataclass(frozen=True)
class PipelineResult:
    """One log's way through the pipeline (``pinquad.Result`` adds the report it makes).

    source: the log's path as given (report.json's ``source.path``); estep: the E-step
    smoother; identified: the EM runs (``LogResult``; ``runs[0]`` the reported one);
    outcome: effect discovery's outcome (None: not run); discovery_skipped: why
    discovery was asked for and not run (a ten-parameter fit), else None; headline: the
    judged estimate; seconds: wall time [s] from reading the log to the end of EM.
    """

    source: str
    estep: str
    identified: LogResult
    outcome: DiscoveryOutcome | None
    discovery_skipped: str | None
    headline: Headline
    seconds: float

    @property
    def trusted(self) -> bool:
        """Whether the headline estimate's verdict is ``trusted``."""
        return self.headline.final.verdict.trusted

    @property
    def estimate(self) -> VehicleEstimate:
        """The headline estimate: under the final model (discovery's refit when it
        selected effects, else the base fit), with its error budget and verdict."""
        return self.headline.final

    @property
    def mass(self) -> float:
        """The headline mass [kg]."""
        return float(self.headline.final.mass)

    @property
    def inertia(self) -> NDArray[np.float64]:
        """The headline inertia (3, 3) [kg m^2]."""
        return np.asarray(self.headline.final.inertia)

    @property
    def inertia_diag(self) -> NDArray[np.float64]:
        """The headline inertia's diagonal (3,) [kg m^2]."""
        return np.diag(self.inertia).copy()

    @property
    def stderr(self) -> NDArray[np.float64]:
        """Total standard errors (4,) of [m (kg), I_xx, I_yy, I_zz (kg m^2)]: the root sum
        of squares of the error budget's parts (``estimate.budget``; statistical, thrust
        calibration, ...), as report.json's ``estimates.stderr``."""
        return np.asarray(self.headline.final.stderr, dtype=float)

    @property
    def verdict(self) -> EstimateVerdict:
        """The headline's verdict: ``overall``, per parameter ``get(name)``, ``reasons``."""
        return self.headline.final.verdict

    @property
    def run(self) -> Identification:
        """The reported EM run (the base fit): its EM history, the smoothed posterior,
        the observations its E-step saw, its statistical standard errors."""
        return self.identified.runs[0]

    @property
    def effects(self) -> DiscoveryResult | None:
        """Effect discovery's result (selected effects, coefficients with standard errors,
        held-out scores, the refit); None when discovery was not run or found it could
        not run (``discovery_note`` says why)."""
        return None if self.outcome is None else self.outcome.result

    @property
    def selected(self) -> tuple[str, ...]:
        """The unmodelled effects discovery kept (empty: none, or not run)."""
        found = self.effects
        return () if found is None else tuple(found.selected)

    @property
    def discovery_note(self) -> str | None:
        """Why discovery was not run or stopped (an unconverged or unphysical base fit, a
        ten-parameter fit, a numerical failure), else None."""
        if self.discovery_skipped is not None:
            return self.discovery_skipped
        if self.outcome is None:
            return None
        return self.outcome.not_run or self.outcome.error or None

    @property
    def notes(self) -> tuple[str, ...]:
        """What the reading and the fit noted (the thrust coefficient's source, clock
        repairs, the vehicle's range), the log's first."""
        seen = tuple(self.identified.notes)
        return seen + tuple(n for n in self.run.notes if n not in seen)


def run(log: FlightLog, options: PipelineOptions | None = None,
        executor: Executor | None = None, source: str | None = None,
        started: float | None = None) -> PipelineResult:
    """identify -> discover -> judge on a read log (module docstring). executor: worker
    processes for the log's EM runs beyond the reported one and discovery's shadow
    flights (None: all here; the same answer); source: the log's path for the report
    (default: the log's own); started: ``time.perf_counter()`` when reading began (the
    report's seconds count from it; default: now)."""
    options = options or PipelineOptions()
    t0 = time.perf_counter() if started is None else started
    identified = identify(log, options.identification, executor)
    seconds = time.perf_counter() - t0
    outcome, skipped = (discovered(identified, options.null, executor) if options.discover
                        else (None, None))
    return PipelineResult(str(log.meta.source) if source is None else source,
                  options.identification.estep, identified, outcome, skipped,
                  judge(identified, outcome), seconds)


def with_discovery(result: PipelineResult, null: NullSettings | None = None,
                   executor: Executor | None = None) -> PipelineResult:
    """``result`` with effect discovery run on its reported run and the headline judged
    again: the step ``run`` takes when asked to discover (the same guards: an unconverged
    base fit, one outside the physical set, a ten-parameter fit), on an identification
    made without it. A discovery already run is run again with ``null``."""
    outcome, skipped = discovered(result.identified, null, executor)
    return replace(result, outcome=outcome, discovery_skipped=skipped,
                   headline=judge(result.identified, outcome))


def run_path(path: str | Path, options: PipelineOptions | None = None,
             executor: Executor | None = None) -> PipelineResult:
    """read -> check -> identify -> discover -> judge for the log at ``path``."""
    options = options or PipelineOptions()
    started = time.perf_counter()
    log = read(path, options.vehicle, options.payload_mass)
    return run(log, options, executor, str(Path(path)), started)
