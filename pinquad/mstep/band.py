"""The M-step of a measured flight (:class:`BandMStep`): the shared closed form for the
mass (body-z force row), the shared profiled objective for the inertia
(:func:`profiled_inertia`) but on the torque rows band-passed to 3-8 Hz
(:class:`BandStats`), and the model's nuisance block (``Theta.nuisance``,
``pinquad.models.nuisance``: a body moment on thrust, body-frame air speed and body
rates, and the rotor inertia J_r) that the measured flights demand."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import sosfiltfilt

from pinquad.core.filters import band_sos, passband
from pinquad.models.nuisance import NuisanceMoment, torque_features
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.stats import QuadraticSums, transition_mask
from pinquad.mstep.updates import (
    MStepResult,
    body_regressor,
    profiled_mass,
    regressor_stats,
    update_noise,
)

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def profiled_inertia(a: Array, b: Array, c: Array, start: Array) -> tuple[Array, float]:
    """argmin_I J(I) = 1/2 sum_j log q_j(I) - sum_i log I_i, q_j = I^T a_j I - 2 b_j^T I
    + c_j (a (3, 3, 3), b (3, 3), c (3,)): the shared regressor M-step's torque
    objective, over physically consistent diagonal inertias (positive, I_xx <= I_yy +
    I_zz and cyclic).

    Damped Newton from the better of ``start`` and the unweighted least-squares solution:
    gradient g = 1/2 sum_j q_j'/q_j - 1/I, Hessian H = sum_j (a_j/q_j - q_j' q_j'^T /
    (2 q_j^2)) + diag(1/I^2); a step that is not a descent direction falls back to the
    gradient, and each step is halved until J decreases with I physical.
    """

    def parts(inertia: Array) -> tuple[float, Array, Array]:
        q = np.einsum("p,apq,q->a", inertia, a, inertia) - 2.0 * b @ inertia + c
        if np.any(q <= 0) or np.any(inertia <= 0):
            return math.inf, np.zeros(3), np.eye(3)
        dq = 2.0 * np.einsum("apq,q->ap", a, inertia) - 2.0 * b
        val = 0.5 * float(np.sum(np.log(q))) - float(np.sum(np.log(inertia)))
        grad = 0.5 * np.sum(dq / q[:, None], axis=0) - 1.0 / inertia
        hess = (np.einsum("apq,a->pq", a, 1.0 / q)
                - 0.5 * np.einsum("ap,aq,a->pq", dq, dq, 1.0 / q**2) + np.diag(1.0 / inertia**2))
        return val, grad, hess

    def physical(i: Array) -> bool:
        return bool(np.all(i > 0) and np.all(2.0 * i <= i.sum()))

    cands = [np.asarray(start, dtype=float)]
    try:
        cands.append(np.linalg.solve(a.sum(axis=0), b.sum(axis=0)))
    except np.linalg.LinAlgError:
        pass
    cands = [x for x in cands if physical(x)] or [np.full(3, float(np.mean(start)))]
    current = min(cands, key=lambda x: parts(x)[0])
    val, grad, hess = parts(current)
    for _ in range(200):
        try:
            step = -np.linalg.solve(hess, grad)
        except np.linalg.LinAlgError:
            step = -grad
        if not grad @ step < 0:
            step = -grad * float(np.min(current)) ** 2
        t = 1.0
        while t > 1e-10:
            trial = current + t * step
            if physical(trial) and parts(trial)[0] <= val + 1e-4 * t * (grad @ step):
                break
            t *= 0.5
        else:
            break
        done = float(np.max(np.abs(trial - current) / current)) < 1e-10
        current = trial
        val, grad, hess = parts(current)
        if done:
            break
    return current, val


@dataclass(frozen=True)
class BandStats:
    """Band-limited torque-row regression data of one posterior.

    x (K, 3, 3): regressor rows of [I_xx, I_yy, I_zz] for the three torque rows; t (K, 3):
    rotor torques [N m]; z (K, Z): nuisance features; e (K, 1) or (K, 0): the rotor
    acceleration sum_i spin_i omega_i' [rad/s^2], a feature of the yaw row only (its
    coefficient is the rotor inertia J_r); all band-passed; rows: index of each used
    transition (K,).
    """

    x: Array
    t: Array
    z: Array
    rows: NDArray[np.int64]
    e: Array | None = None

    def features(self, j: int, keep: BoolArray | None = None) -> Array:
        """Features projected out of torque row j: z, plus e for the yaw row (j = 2)."""
        z = self.z if keep is None else self.z[keep]
        if j == 2 and self.e is not None and self.e.shape[1]:
            z = np.column_stack([z, self.e if keep is None else self.e[keep]])
        return z

    def rotor_inertia(self, inertia: Array) -> float:
        """J_r [kg m^2]: least-squares coefficient of e in the band-passed yaw residual
        I_zz-row regressor @ inertia - tau_z = z c + J_r e (NaN without e)."""
        if self.e is None or not self.e.shape[1]:
            return float("nan")
        r = self.x[:, 2, :] @ inertia - self.t[:, 2]
        return float(np.linalg.lstsq(self.features(2), r, rcond=None)[0][-1])

    def quadratic(self, keep: BoolArray | None = None) -> tuple[Array, Array, Array]:
        """Quadratic forms (a (3, 3, 3), b (3, 3), c (3,)) of the torque residuals with
        the features projected out (over the rows in ``keep``)."""
        x, t = (self.x, self.t) if keep is None else (self.x[keep], self.t[keep])
        a = np.empty((3, 3, 3))
        b = np.empty((3, 3))
        c = np.empty(3)
        for j in range(3):
            z = self.features(j, keep)
            zz = z.T @ z
            g = z.T @ x[:, j, :]
            h = z.T @ t[:, j]
            sol = np.linalg.lstsq(zz, np.column_stack([g, h]), rcond=None)[0]
            a[j] = x[:, j, :].T @ x[:, j, :] - g.T @ sol[:, :3]
            b[j] = x[:, j, :].T @ t[:, j] - g.T @ sol[:, 3]
            c[j] = t[:, j] @ t[:, j] - h @ sol[:, 3]
        return a, b, c


class BandMStep:
    """M-step for a measured flight (a generalised EM step; equations below).

    Mass: the shared regressor M-step's closed form from the body-z force row,
    m = sum F_k^2 / sum E[a_z,k] F_k, a_z = e3^T R^T ((v_{k+1} - v_k)/dt + g e3).

    Inertia: the shared profiled objective J(I) = 1/2 sum_j log q_j - log det I, but
    with q_j built from the torque rows band-passed to ``band`` [Hz] (zero-phase
    Butterworth, order 2) and the nuisance features projected out. The band is where
    the rigid-body torque model holds on these flights, chosen by the coherence between
    the rotor roll / pitch torques and the gyro's angular acceleration on the seven
    clean flights: 0.9-0.99 from 4 to 8 Hz, 0.5-0.9 at 3 Hz, but 0.0-0.8 at 2 Hz and
    0.1-0.95 at 1 Hz (air-speed dependent moments dominate there) and falling to
    0.2-0.6 on some flights above 10 Hz (the gyro sees motion the rotor speeds do not
    explain). Below the band the features alone cannot rescue the fit: with 2-8 Hz the
    roll / pitch inertia scatter over the flights grows from 10 % to 18 %. Caveat: the
    band-passed update is not the EM M-step of any model, and in closed loop it is
    biased: on simulated flights (``raw_from_simulated``; ``python -m pinquad.response
    --simulate``) it reads the inertia 11-21 % high with the simulator's torque noise
    and 60-170 % high with 3-10 times that, where direct EM stays within 5 %. The
    band-passed regression skips transitions within ``1 / (2 band[0])`` s of an
    excluded one or of the ends (filter transients).

    Rotor inertia (when ``rotor_acc`` (N,) [rad/s^2] is given): the yaw row also projects
    out e = sum_i spin_i omega_i', and with I fixed J_r = the least-squares coefficient of
    e in the band-passed yaw residual (``BandStats.rotor_inertia``).

    Nuisance block (``Theta.nuisance``): with pi (and J_r) fixed, moment_coef = least
    squares of the full-band residual Y pi - tau - [0, 0, J_r e] on the features z; the
    E-step's model (``QuadSSM``, through ``models.ssm.corrected``) then sees
    tau + z moment_coef^T + [0, 0, J_r e].

    Noise: S = dt * residual variance of each wrench row (full band, with the moment),
    measurement variances as the shared ``update_noise``.
    """

    def __init__(self, band: tuple[float, float] = (3.0, 8.0), rotor_acc: Array | None = None):
        self.band = band
        self.rotor_acc = None if rotor_acc is None else np.asarray(rotor_acc, dtype=float)

    def band_stats(self, post, obs: Observations, gravity: float) -> BandStats:
        mean = post.mean
        n_tr = obs.n - 1
        y = body_regressor(mean[:-1], mean[1:], obs.dt, gravity)[:, 3:6, 1:4]
        tau = obs.inputs[:-1, 1:4]
        z = torque_features(mean[:-1], obs.inputs[:-1, 0])
        fs = 1.0 / obs.dt
        lo, hi = passband(self.band, fs)
        sos = band_sos(self.band, fs)

        def bp(v: Array) -> Array:
            return sosfiltfilt(sos, v, axis=0)

        use = transition_mask(obs)
        # the filter's transients last about half a period of its lowest corner
        margin = int(math.ceil(0.5 / (lo if lo > 0 else hi) / obs.dt))
        bad = ~use
        bad[:margin] = bad[-margin:] = True
        near = np.convolve(bad.astype(float), np.ones(2 * margin + 1), mode="same") > 0
        rows = np.flatnonzero(~near)
        if rows.size < 50:
            rows = np.flatnonzero(use)
        e = None
        if self.rotor_acc is not None:
            e = bp(self.rotor_acc[:n_tr, None])[rows]
        return BandStats(x=bp(y.reshape(n_tr, 9)).reshape(n_tr, 3, 3)[rows],
                         t=bp(tau)[rows], z=bp(z)[rows], rows=rows, e=e)

    def __call__(self, post, obs: Observations, theta: Theta, earlier=None):
        """The update; ``earlier`` (``identify.QuadraticSums``): statistics of transitions
        no longer in ``obs`` (the online stream's memory), added to the mass row's."""
        g = theta.gravity
        stats = regressor_stats(post, obs, g)
        mass = profiled_mass(stats if earlier is None
                             else QuadraticSums.of(stats).plus(earlier), theta.mass)
        band = self.band_stats(post, obs, g)
        a, b, c = band.quadratic()
        inertia, objective = profiled_inertia(a, b, c, np.diag(theta.inertia))
        pi = np.concatenate([[mass], inertia])

        idx = np.flatnonzero(transition_mask(obs))
        z_all = torque_features(post.mean, obs.inputs[:, 0])
        resid = stats.y[:, 3:6, :] @ pi - stats.tau[:, 3:6]
        jr = band.rotor_inertia(inertia)
        rotor = np.zeros((obs.n, 3))
        if np.isfinite(jr):
            rotor[:, 2] = jr * self.rotor_acc
            resid = resid - rotor[idx]
        coef = np.linalg.lstsq(z_all[idx], resid, rcond=None)[0].T
        offset = z_all @ coef.T + rotor
        # Wrench residual variances with the moment in place (first order in the state
        # uncertainty, as the shared M-step): q_j = pi^T A_j pi - 2 pi^T b'_j + c'_j.
        # (the force rows keep the shared statistics' b and c, with their covariance
        # terms on a continuous flight)
        tau_eff = stats.tau[:, 3:6] + offset[idx]
        b_eff = stats.b.copy()
        c_eff = stats.c.copy()
        b_eff[3:6] = np.einsum("kap,ka->ap", stats.y[:, 3:6], tau_eff)
        c_eff[3:6] = np.einsum("ka,ka->a", tau_eff, tau_eff)
        q = np.einsum("p,apq,q->a", pi, stats.a, pi) - 2.0 * b_eff @ pi + c_eff
        row_var = np.maximum(q / stats.n, 0.0)
        noise = update_noise(post, obs, theta, row_var)
        nuisance = NuisanceMoment(torque_offset=offset, moment_coef=coef,
                                  rotor_inertia=jr if np.isfinite(jr) else None)
        new = Theta(mass=mass, inertia=np.diag(inertia), noise=noise, gravity=g,
                    nuisance=nuisance)
        return MStepResult(new, objective, row_var)

    def jackknife(self, post, obs: Observations, theta: Theta, blocks: int = 10) -> Array:
        """Delete-one-block jackknife standard errors (4,) of [m, I_xx, I_yy, I_zz] at
        the final posterior: the M-step repeated with each of ``blocks`` contiguous time
        blocks left out. It counts the correlation of neighbouring residuals (slow
        unmodelled effects) that the white-noise information ignores; the posterior is
        held fixed, so it leaves out the E-step's share of the uncertainty."""
        g = theta.gravity
        idx = np.flatnonzero(transition_mask(obs))
        x0, x1 = post.mean[idx], post.mean[idx + 1]
        acc_z = body_regressor(x0, x1, obs.dt, g)[:, 2, 0]
        force = obs.inputs[idx, 0]
        band = self.band_stats(post, obs, g)
        n_tr = obs.n - 1
        label_all = (np.arange(n_tr) * blocks // max(n_tr, 1)).astype(np.int64)
        est = []
        start = np.diag(theta.inertia)
        for blk in range(blocks):
            keep_m = label_all[idx] != blk
            keep_i = label_all[band.rows] != blk
            m = float(force[keep_m] @ force[keep_m] / (acc_z[keep_m] @ force[keep_m]))
            inertia, _ = profiled_inertia(*band.quadratic(keep_i), start)
            est.append([m, *inertia])
        est = np.asarray(est)
        return np.sqrt((blocks - 1) / blocks * ((est - est.mean(axis=0)) ** 2).sum(axis=0))
