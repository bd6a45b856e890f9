"""What EM takes as an M-step: the update, and what the M-step declares EM may do with it.

An M-step maps the E-step's posterior to new parameters, theta_{i+1} = M(E(theta_i)).
EM's over-relaxation (``pinquad.identification.em.run_em``: the step taken is

    theta_p = theta_t (M(theta_t) / theta_t)^eta   in log-parameter space, eta >= 1,

kept only when log p(y | theta_p) >= log p(y | theta_t)) fits an update that maximises
jointly over every parameter the step moves. Whether an update does is a property of the
update, so each M-step states it (as a state-space model states which parameters its EM
may fit) rather than EM recognising a function by its name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from estimators.protocol import Posterior
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.updates import MStepResult, paper_mstep, regressor_mstep

Update = Callable[[Posterior, Observations, Theta], MStepResult]
"""update(post, obs, theta) -> MStepResult: theta_{i+1} from the E-step at theta_i."""

Extrapolate = Callable[[Theta, Theta, float], Theta]
"""extrapolate(theta_t, M(theta_t), eta) -> theta_p: the over-relaxed step."""


@dataclass(frozen=True)
class MStep:
    """An M-step for ``run_em``: its update and the capabilities it declares.

    update: (post, obs, theta) -> MStepResult. over_relaxation: EM may over-relax the
    update's steps (the update maximises jointly over what the step moves; ``run_em``
    still checks every relaxed step against the likelihood); False: plain EM steps only.
    extrapolate: how an over-relaxed step moves theta, theta_p = extrapolate(theta_t,
    M(theta_t), eta); None: along the log-parameter vector [m, I_xx, I_yy, I_zz, wrench
    noise (6), measurement noise] that ``run_em`` packs (with one eta per entry when it
    runs ``per_parameter``). Calling the M-step calls its update.
    """

    update: Update
    over_relaxation: bool = False
    extrapolate: Extrapolate | None = None

    def __call__(self, post: Posterior, obs: Observations, theta: Theta) -> MStepResult:
        return self.update(post, obs, theta)


REGRESSOR = MStep(regressor_mstep, over_relaxation=True)
"""The regressor M-step (``updates.regressor_mstep``): mass, inertia diagonal and every
noise variance maximised jointly, so its steps may be over-relaxed."""

PAPER = MStep(paper_mstep)
"""The paper's closed form (``updates.paper_mstep``): per-axis updates that are not a
joint maximiser, so EM takes its steps as they are."""
