"""pinquad.core: see docs/architecture.md."""
