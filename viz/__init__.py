"""viser browser view of a finished pinquad run."""
