"""One EM update on a sliding window, shared by the closed-loop online estimator
(``pinquad.experiments.online``) and the replay of a recorded log (``pinquad.experiments.online_replay``).

A window covers steps start .. stop-1. Its prior is the previous window's smoothed
marginal at ``start`` when the two overlap (mean and diagonal variances, floored at
1e-10), else the caller's; the update runs ``iterations`` EM iterations, with the
force-free warm-up E-step (``KinematicSSM``) first when the parameters are the initial
guess.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior, StateSpaceModel
from pinquad.models.ssm import KinematicSSM, Observations, QuadSSM, Theta
from pinquad.mstep.stats import QuadraticSums

Array = NDArray[np.float64]

PreviousWindow = tuple[int, Posterior, Observations]
"""(start step, posterior, observations) of the last update."""


def window_prior(previous: PreviousWindow | None, start: int, x0: Array, p0: Array
                 ) -> tuple[Array, Array]:
    """Prior mean (12,) and variances (12,) of the window starting at ``start``: the
    previous posterior's marginal there (copied: its arrays may be reused), else
    (x0, p0)."""
    if previous is not None:
        prev_start, post, _ = previous
        j = start - prev_start
        if 0 <= j < post.mean.shape[0]:
            return post.mean[j].copy(), np.maximum(np.diag(post.cov[j]), 1e-10)
    return x0, p0


def window_em(win: Observations, theta: Theta, warm_up: bool, iterations: int,
              smooth: Callable[[StateSpaceModel, Array], Posterior], mstep,
              earlier: QuadraticSums | None,
              model_of: Callable[[Observations, Theta], StateSpaceModel] = QuadSSM
              ) -> tuple[Theta, Posterior]:
    """``iterations`` EM iterations on the window (one more, the force-free warm-up
    E-step, first when ``warm_up``): E-step ``smooth(model_of(win, theta), win.ys)``,
    M-step ``mstep(post, win, theta, earlier)`` (``earlier``: the memory of transitions
    that left the window). Returns the new parameters and the last posterior."""
    post = None
    for it in range(iterations + (1 if warm_up else 0)):
        model = KinematicSSM(win, theta) if warm_up and it == 0 else model_of(win, theta)
        post = smooth(model, win.ys)
        theta = mstep(post, win, theta, earlier).theta
    assert post is not None
    return theta, post
