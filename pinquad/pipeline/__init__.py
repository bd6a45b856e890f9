"""The one pipeline every entry point runs: read -> check -> identify -> discover ->
judge -> ``Result`` for one log (``pinquad.pipeline.single``), and ``identify_many`` for a
batch of logs on any executor or Dask cluster (``pinquad.pipeline.batch``).

The commands that run other steps after the same read and check: the online replay of a
log (``pinquad.pipeline.replay``: read -> check -> observations for the streaming
estimator), the real-vehicle table (``pinquad.pipeline.realdata``: rotor inertia pooled
over the flights), a vehicle file's simulated cycles (``pinquad.pipeline
.vehicle_file``: fly, log, then read -> check -> identify) and the measured-flight
diagnostics and train/test discovery (``pinquad.pipeline.measured``: read -> check ->
observations with the log's vehicle, for ``response``, ``axis_inertia`` and
``realdiscovery``)."""

from pinquad.pipeline.batch import Batch, identify_many
from pinquad.pipeline.single import (
    LOG_MAX_ITERATIONS,
    PipelineOptions,
    Result,
    check,
    read,
    run,
    run_path,
)

__all__ = ["LOG_MAX_ITERATIONS", "Batch", "PipelineOptions", "Result", "check", "identify_many",
           "read", "run", "run_path"]
