"""pinquad.data: the packaged vehicle descriptions (``*.urdf``, read by
pinquad.vehicle.model) and ``python -m pinquad.data``, the public data set's download
command (pinquad.cli.data)."""
