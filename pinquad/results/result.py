"""``pinquad.Result``: one log's way through the pipeline (``pinquad.pipeline.single``)
with the report it makes: ``summary()`` (what ``python -m pinquad.offline --log``
prints), ``explain()`` (all of it), ``discovery()`` (report.json's section) and
``save(run_dir)`` (the run directory, written whole or not at all: a staging directory
renamed into place, with the permissions any new folder of the user gets)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path

from pinquad.io.runs import RunWriter
from pinquad.pipeline.single import PipelineResult
from pinquad.report.console import console_summary
from pinquad.report.discovery import discovery_figure_name, draw_discovery_figures
from pinquad.report.recorded import (
    discovery_summary,
    headline_summary,
    log_table,
    report_json,
    report_markdown,
    write_log_run,
)


@dataclass(frozen=True)
class Result(PipelineResult):
    """One log's way through the pipeline (``PipelineResult``: the log's identification,
    discovery's outcome, the judged headline, and properties ``mass``, ``inertia``,
    ``stderr``, ``verdict``, ``effects``, ...) with the report it makes."""

    @classmethod
    def of(cls, found: PipelineResult) -> Result:
        """The pipeline's result ``found`` with its report."""
        if isinstance(found, cls):
            return found
        return cls(**{f.name: getattr(found, f.name) for f in fields(PipelineResult)})

    def summary(self) -> str:
        """What ``python -m pinquad.offline --log`` prints about the run: one line per
        parameter (value ± total standard error, unit, verdict, the main reason), the
        vehicle's reference values, one line per effect found, warnings
        (``pinquad.report.console``)."""
        return console_summary(self.identified, self.headline, self.source, self.seconds,
                               self.discovery(), self.discovery_skipped)

    def discovery(self) -> dict | None:
        """report.json's ``discovery`` section (None: not run), its figures named as
        ``save`` draws them (``figures/discovery_<effect>.png``)."""
        if self.outcome is None:
            return None
        found = self.outcome.result
        if found is None:
            return self.outcome.to_report()
        named = replace(found, figures=tuple(discovery_figure_name(ev.effect)
                                             for ev in found.evidence))
        return replace(self.outcome, result=named).to_report()

    def explain(self) -> str:
        """The whole printed report (``offline --log --explain``): the log, exclusions and
        notes, the EM time, discovery's selection with its coefficients, held-out residual
        RMS and null calibration, the table of runs, the headline with every reason and
        its error budget."""
        ident = self.identified
        lines = [f"log: {ident.contents}; {ident.obs.n} steps of {ident.obs.dt * 1e3:.0f} ms",
                 f"initial guess: {ident.guess}",
                 *(f"excluded: {line}" for line in ident.excluded),
                 *(f"note: {note}" for note in ident.notes),
                 *(f"note: {r.sensor}, {r.mstep} M-step: {r.failure}"
                   for r in ident.runs if r.failure),
                 f"\nEM: {self.seconds:.1f} s"]
        if self.discovery_skipped is not None:
            lines.append(f"\n{self.discovery_skipped}")
        section = self.discovery()
        if section is not None:
            lines += ["", discovery_summary(section)]
        lines += ["", log_table(ident, self.headline), "", headline_summary(self.headline)]
        return "\n".join(lines)

    def write(self, writer: RunWriter) -> None:
        """The run directory's files into ``writer``'s staging directory (the caller
        publishes): report.json, report.md, the log as the E-step saw it, the smoothed
        means, figures and the viewer's tables."""
        outcome = self.outcome
        if outcome is not None and outcome.result is not None:
            outcome = replace(outcome, result=draw_discovery_figures(
                outcome.result, writer.path("figures")))
        section = self.discovery()
        report = report_json(self.identified, self.source, self.estep, self.seconds,
                             section, self.headline)
        markdown = report_markdown(self.identified, self.source, section, self.headline)
        write_log_run(writer, self.identified, report, markdown, outcome)

    def save(self, run_dir: str | Path, *, replace: bool = False) -> Path:
        """Write the run directory ``run_dir`` whole or not at all and return it.

        replace=False: ``run_dir`` must be absent or empty (``OutputError`` otherwise);
        True: it is this run's own earlier output (a task run again) and is replaced,
        whatever an interrupted attempt left half written.
        """
        writer = RunWriter(run_dir, replace=replace)
        with writer:
            self.write(writer)
            return writer.publish()
