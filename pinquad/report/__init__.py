"""pinquad.report: see docs/architecture.md."""
