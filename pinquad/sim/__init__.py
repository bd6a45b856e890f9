"""pinquad.sim: see docs/architecture.md."""
