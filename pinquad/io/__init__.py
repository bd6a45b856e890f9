"""pinquad.io: see docs/architecture.md."""
