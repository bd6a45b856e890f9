"""pinquad.estep: see docs/architecture.md."""
