"""The one pipeline every entry point runs: read -> check -> identify -> discover ->
judge for one log (``pinquad.pipeline.single``; the steps in ``identify``, ``discover``
and ``judge``). It computes and returns typed results; it writes and prints nothing
(``pinquad.results`` and ``pinquad.report`` do, above it).

The commands that run other steps after the same read and check: the online replay of a
log (``pinquad.pipeline.replay``: read -> check -> observations for the streaming
estimator), the real-vehicle table (``pinquad.pipeline.realdata``: rotor inertia pooled
over the flights) and the measured-flight diagnostics (``pinquad.pipeline.measured``:
read -> check -> observations with the log's vehicle, for ``response``,
``axis_inertia`` and ``realdiscovery``)."""

from pinquad.pipeline.single import (
    LOG_MAX_ITERATIONS,
    PipelineOptions,
    PipelineResult,
    check,
    read,
    run,
    run_path,
)

__all__ = ["LOG_MAX_ITERATIONS", "PipelineOptions", "PipelineResult", "check", "read", "run",
           "run_path"]
