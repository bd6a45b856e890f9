"""pinquad.cli: see docs/architecture.md."""
