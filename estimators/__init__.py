"""Generic state estimation over a :class:`StateSpaceModel`: EKF, RTS smoother, GTSAM
batch smoother. Knows nothing of quadcopters."""

from estimators.protocol import FilterResult, Posterior, StateSpaceModel

__all__ = ["FilterResult", "Posterior", "StateSpaceModel"]
