"""Contact force of a stick (or beater) on an instrument, computed at audio rate.

Hunt-Crossley contact (as used by Avanzini and Rocchesso for sound synthesis):
the striker of mass ``m`` compresses the contact by ``x`` and feels

``F = k x^alpha + lam x^alpha dx/dt``  (F >= 0, only while x > 0)

with ``lam = c(e) k / v0``. The factor ``c`` is solved (:func:`damping_factor`) so that the
contact's coefficient of restitution is exactly the target ``e``: Hunt and Crossley's
``c = 1.5 (1 - e)`` holds only near e = 1 (a target of 0.3 gave 0.58). The contact is integrated with RK4 at an
oversampled rate from ``x = 0, dx/dt = v0`` until the striker leaves. For
``alpha > 1`` a faster strike is shorter and its force peak grows faster than
the velocity, so harder strikes are both louder and brighter.

A physics step (about 1 ms) is often longer than the whole contact, which is
why the force pulse is computed here and not sent by the physics service.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from numba import njit


@dataclass(frozen=True)
class Striker:
    """What hits the instrument.

    Attributes
    ----------
    mass : float
        Effective mass of the striker at the contact point, kg.
    stiffness : float
        Contact stiffness k, N / m^alpha.
    exponent : float
        Contact exponent alpha (1.5 for a Hertzian sphere on a plane).
    """

    mass: float = 0.03
    stiffness: float = 6.5e5
    exponent: float = 1.5


@dataclass(frozen=True)
class ContactPulse:
    """A sampled contact force pulse.

    Attributes
    ----------
    force : np.ndarray
        Force in newtons, shape (n,), one value per output sample (the mean over the sample).
    sample_rate : float
        Hz.
    duration : float
        Contact duration, seconds.
    peak : float
        Peak force, newtons.
    impulse : float
        Integral of the force, newton-seconds.
    """

    force: npt.NDArray[np.float64]
    sample_rate: float
    duration: float
    peak: float
    impulse: float


MIN_RESTITUTION = 0.05
"""Lowest restitution the contact takes (lower targets are raised to it): as e goes to 0 the damping
factor c grows without bound (about 1 / e) and the striker would stay on the head."""
MAX_RESTITUTION = 0.99


def clip_restitution(restitution: float) -> float:
    """The restitution the contact gives for target ``restitution``: clipped to [MIN_RESTITUTION,
    MAX_RESTITUTION]. Whatever derives a quantity from the contact's e (the striker's effective mass from an
    impulse) takes it from here, so the contact gives back the impulse asked."""
    return min(max(float(restitution), MIN_RESTITUTION), MAX_RESTITUTION)


@lru_cache(maxsize=256)
def damping_factor(restitution: float) -> float:
    """The ``c`` in ``lam = c k / v0`` that makes the Hunt-Crossley contact's restitution ``restitution``.

    With ``u = v / v0`` and ``s = x^(alpha+1) k / ((alpha+1) m v0^2)`` the contact's equation becomes
    ``u du/ds = -(1 + c u)``, the same for every mass, stiffness, exponent and velocity; integrating it from
    ``u = 1`` (entry) to ``u = -e`` (exit, back at ``s = 0``) gives ``c (1 + e) = ln((1 + c) / (1 - c e))``,
    solved here by bisection on ``0 < c < 1 / e`` (one root). Near e = 1 it gives Hunt and Crossley's
    ``1.5 (1 - e)``; at e 0.3 it gives 3.09 where theirs gives 1.05 (restitution 0.58). ``restitution`` is
    clipped to [MIN_RESTITUTION, MAX_RESTITUTION].
    """
    e = clip_restitution(restitution)
    lo, hi = 0.0, 1.0 / e
    for _ in range(200):
        c = 0.5 * (lo + hi)
        if c <= lo or c >= hi:
            break
        rest = 1.0 - c * e
        # g(c) = ln(1 + c) - ln(1 - c e) - c (1 + e): negative below the root, growing without bound at 1 / e
        if rest > 0.0 and math.log1p(c) - math.log(rest) - c * (1.0 + e) < 0.0:
            lo = c
        else:
            hi = c
    return 0.5 * (lo + hi)


def hunt_crossley(
    velocity: float,
    striker: Striker,
    restitution: float = 0.6,
    sample_rate: float = 48000.0,
    oversample: int = 16,
    max_duration: float = 0.05,
) -> ContactPulse:
    """Force pulse of one strike.

    Parameters
    ----------
    velocity : float
        Normal approach velocity before contact, m/s (> 0).
    striker : Striker
        Mass, stiffness and exponent of the contact.
    restitution : float
        Coefficient of restitution e the contact gives (exit speed / entry speed), clipped to
        [MIN_RESTITUTION, MAX_RESTITUTION].
    sample_rate : float
        Output sample rate, Hz.
    oversample : int
        Integration steps per output sample.
    max_duration : float
        Upper bound on the contact, seconds (a safety net for soft contacts).

    Returns
    -------
    ContactPulse
        The force per output sample (newtons), starting at first contact.
    """
    v0 = float(velocity)
    if not np.isfinite(v0) or v0 <= 0:
        return ContactPulse(np.zeros(1), sample_rate, 0.0, 0.0, 0.0)
    m, k, alpha = striker.mass, striker.stiffness, striker.exponent
    lam = damping_factor(restitution) * k / v0
    # Hertz estimate of the contact time picks the step so that short contacts stay accurate.
    t_est = 3.2 * (m / k) ** (1.0 / (alpha + 1.0)) * v0 ** ((1.0 - alpha) / (alpha + 1.0))
    dt = 1.0 / (sample_rate * oversample)
    dt = min(dt, t_est / 200.0) if t_est > 0 else dt
    n_max = int(max_duration / dt) + 1

    f, steps = _integrate(v0, m, k, alpha, lam, dt, n_max)
    duration = steps * dt
    # average over output samples (trapezoid on the fine grid)
    t_fine = np.arange(f.shape[0]) * dt
    n_out = max(int(np.ceil(duration * sample_rate)), 1)
    edges = np.arange(n_out + 1) / sample_rate
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * dt)])
    cum_at = np.interp(edges, t_fine, cum)
    per_sample = np.diff(cum_at) * sample_rate  # mean force over each output sample, N
    impulse = float(cum[-1])
    return ContactPulse(per_sample, float(sample_rate), float(duration), float(f.max()), impulse)


@njit(cache=True)
def _accel(x: float, v: float, m: float, k: float, alpha: float, lam: float) -> float:
    if x <= 0:
        return 0.0
    xa = x**alpha
    return -max(k * xa + lam * xa * v, 0.0) / m


@njit(cache=True)
def _integrate(v0: float, m: float, k: float, alpha: float, lam: float, dt: float,
               n_max: int) -> tuple[npt.NDArray[np.float64], int]:
    """RK4 from first contact (x = 0, dx/dt = ``v0``) until the striker leaves or ``n_max`` steps: the force (N)
    at every step, starting with 0, and the number of steps. A numba kernel (a contact is 1,000-4,000 steps;
    in Python it cost about 3.6 ms a strike), the same arithmetic in the same order as the Python loop it
    replaced, so the same numbers."""
    forces = np.empty(n_max + 2)
    forces[0] = 0.0
    count = 1
    x, v = 0.0, v0
    steps = 0
    while steps < n_max:
        k1x, k1v = v, _accel(x, v, m, k, alpha, lam)
        k2x, k2v = v + 0.5 * dt * k1v, _accel(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v, m, k, alpha, lam)
        k3x, k3v = v + 0.5 * dt * k2v, _accel(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v, m, k, alpha, lam)
        k4x, k4v = v + dt * k3v, _accel(x + dt * k3x, v + dt * k3v, m, k, alpha, lam)
        x += dt * (k1x + 2 * k2x + 2 * k3x + k4x) / 6.0
        v += dt * (k1v + 2 * k2v + 2 * k3v + k4v) / 6.0
        steps += 1
        if x <= 0:
            forces[count] = 0.0
            count += 1
            break
        xa = x**alpha
        forces[count] = max(k * xa + lam * xa * v, 0.0)
        count += 1
    return forces[:count].copy(), steps


def warm_up() -> None:
    """Compile (or load from numba's disk cache) the contact kernel now, so that no live strike waits for it."""
    hunt_crossley(1.0, Striker())


def mode_response_chunks(
    pulse: ContactPulse, poles_log: npt.NDArray[np.complex128], chunk: int = 8,
    inverse_powers: npt.NDArray[np.complex128] | None = None,
) -> list[tuple[int, npt.NDArray[np.complex128]]]:
    """The force pulse as a few injections: (sample offset from first contact, complex amplitude per mode).

    The pulse is cut into chunks of ``chunk`` samples; each chunk becomes one
    injection at its start carrying the chunk's transform at every pole. The
    sum of the injections is exactly :func:`mode_response`, and the output
    grows during the contact as it physically does instead of jumping at the
    first contact sample (which would add a broadband click).

    ``inverse_powers``: ``exp(-outer(poles_log, arange(n)))`` for some n >= ``chunk`` (the bank's
    :attr:`~services.sound.modal_bank.BankTables.inverse_powers`, computed with the modes); computed here when
    None, which costs an exponential per mode and sample of a chunk (3-4 ms at 20,000 modes).

    Returns
    -------
    list of (int, np.ndarray)
        Offsets in samples and amplitudes of shape (K,), newton-seconds.
    """
    f = pulse.force
    idx = np.nonzero(f)[0]
    if idx.size == 0:
        return []
    first, last = int(idx[0]), int(idx[-1])
    kernel = inverse_powers
    if kernel is None or kernel.shape[1] < chunk:
        kernel = np.exp(-np.outer(poles_log, np.arange(chunk)))
    out: list[tuple[int, npt.NDArray[np.complex128]]] = []
    for start in range(first, last + 1, chunk):
        m = np.arange(start, min(start + chunk, last + 1))
        w = f[m] / pulse.sample_rate
        # the first columns as a contiguous array: the same values and layout as exp(-outer(poles_log, m - start))
        k = kernel if m.shape[0] == kernel.shape[1] else np.ascontiguousarray(kernel[:, : m.shape[0]])
        out.append((start, np.asarray(k @ w)))
    return out


def mode_response(pulse: ContactPulse, poles_log: npt.NDArray[np.complex128]) -> npt.NDArray[np.complex128]:
    """Complex amplitude each mode receives from a force pulse.

    For a mode with pole ``p = exp(s)`` (``s`` per sample) driven by force
    samples ``f[m]``, the state after the pulse equals that of an impulse of
    complex amplitude ``sum_m f[m] p^(-m) / sr`` at the first contact sample:
    the pulse's Laplace transform at the mode's pole. Its magnitude falls off
    above about 1 / duration, which is what makes short contacts bright.

    Parameters
    ----------
    pulse : ContactPulse
        Force samples, newtons.
    poles_log : np.ndarray
        log of the poles per sample, shape (K,) complex.

    Returns
    -------
    np.ndarray
        shape (K,) complex, newton-seconds.
    """
    f = pulse.force
    idx = np.nonzero(f)[0]
    if idx.size == 0:
        return np.zeros(poles_log.shape[0], dtype=np.complex128)
    m = np.arange(idx[0], idx[-1] + 1)
    w = f[m] / pulse.sample_rate
    return np.asarray(np.exp(-np.outer(poles_log, m)) @ w)
