"""The one pipeline every entry point runs: read -> check -> identify -> discover ->
judge -> ``Result`` for one log (``pinquad.pipeline.single``), and ``identify_many`` for a
batch of logs on any executor or Dask cluster (``pinquad.pipeline.batch``)."""

from pinquad.pipeline.batch import Batch, identify_many
from pinquad.pipeline.single import (
    LOG_MAX_ITERATIONS,
    PipelineOptions,
    Result,
    read,
    run,
    run_path,
)

__all__ = ["LOG_MAX_ITERATIONS", "Batch", "PipelineOptions", "Result", "identify_many", "read",
           "run", "run_path"]
