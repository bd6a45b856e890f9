"""pinquad.realdata: see docs/architecture.md."""
