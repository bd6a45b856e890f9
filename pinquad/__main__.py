"""``python -m pinquad`` points to the entry points."""

print("pinquad entry points: python -m pinquad.offline | python -m pinquad.online | "
      "python -m pinquad.flight | python -m pinquad.actuators | python -m viz RUN_DIR")
