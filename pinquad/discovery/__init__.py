"""pinquad.discovery: see docs/architecture.md."""
