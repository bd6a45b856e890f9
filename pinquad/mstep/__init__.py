"""pinquad.mstep: see docs/architecture.md."""
