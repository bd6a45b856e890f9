"""pinquad.vehicle: see docs/architecture.md."""
