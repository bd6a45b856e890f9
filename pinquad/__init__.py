"""pinquad: EM identification of a quadcopter's mass and inertia."""
