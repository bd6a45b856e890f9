"""pinquad.models: see docs/architecture.md."""
