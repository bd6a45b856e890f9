"""pinquad.identification: see docs/architecture.md."""
