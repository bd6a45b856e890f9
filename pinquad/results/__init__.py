"""What the pipeline found, with the report it makes: ``Result`` (one log: ``summary()``,
``explain()``, ``save(run_dir)``) and ``identify_many`` (a batch of logs on any executor or
Dask cluster, each written as its own run directory). The Python API and the command
lines return and write these."""
