"""pinquad.experiments: see docs/architecture.md."""
