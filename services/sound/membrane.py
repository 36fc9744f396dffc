"""Modes of an ideal circular membrane (drum head) fixed at its rim.

Mode (m, n) has frequency ``f_mn = j_mn / (2 pi a) sqrt(T / sigma)`` where
``j_mn`` is the n-th zero of the Bessel function J_m, ``a`` the radius (m),
``T`` the tension (N/m) and ``sigma`` the surface density (kg/m^2). Its shape is
``J_m(j_mn r / a) cos(m theta)`` and, for m > 0, a second orientation
``J_m(j_mn r / a) sin(m theta)`` at the same frequency: both are kept, so a
strike at any angle excites the right mix. Modal mass (per orientation):
``sigma pi a^2 J_{m+1}(j_mn)^2 / eps_m`` with eps_0 = 1, eps_m = 2.

Optional corrections (both tunable, both 0 gives the ideal membrane):

* air loading: the air moving with the head adds a mass of about
  ``rho_air / k`` per unit area for a mode of wavenumber ``k = j_mn / a``,
  which lowers the low modes most (this is what makes real drums less
  inharmonic than the ideal membrane);
* orientation splitting: a real head is not perfectly uniform, so the two
  orientations of an m > 0 mode differ slightly and beat.
"""

from __future__ import annotations

import io
import subprocess
import sys
import threading
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import jn_zeros, jv

RHO_AIR = 1.2
"""Density of air, kg/m^3."""


CHILD_PROCESS_ZEROS = 2000
"""Off the main thread, a table with more zeros than this is computed in a child process: SciPy's ``jn_zeros``
holds the GIL for 10-40 ms per order at large sizes, which would stall the node's render loop (the main thread)
as surely as computing it there. The default kit's tables have under 500 zeros."""

_TABLES: list[npt.NDArray[np.float64]] = []  # Bessel-zero tables computed so far, none covering another
_TABLES_LOCK = threading.Lock()  # rebuilds run in the node's worker thread as well as in the loop


def bessel_table(m_max: int = 40, n_max: int = 20) -> npt.NDArray[np.float64]:
    """Zeros j_mn of J_m, shape (m_max + 1, n_max): row m, column n - 1 (read-only).

    Computed once per process for the largest table asked so far and sliced for smaller ones: the table for
    20,000 modes (the most /batteur/sound/modes allows) takes SciPy seconds. A slice is bit-identical to a table
    computed at its own size (``jn_zeros(m, n)`` is the prefix of ``jn_zeros(m, N)``).
    """
    with _TABLES_LOCK:
        for table in _TABLES:
            if table.shape[0] > m_max and table.shape[1] >= n_max:
                return table[: m_max + 1, :n_max]
    table = _compute_table(m_max, n_max)
    table.flags.writeable = False
    with _TABLES_LOCK:
        _TABLES[:] = [t for t in _TABLES if t.shape[0] > table.shape[0] or t.shape[1] > table.shape[1]]
        _TABLES.append(table)
    return table


_CHILD = ("import sys, numpy as np; from scipy.special import jn_zeros; m, n = map(int, sys.argv[1:]); "
          "np.save(sys.stdout.buffer, np.array([jn_zeros(k, n) for k in range(m + 1)]))")


def _compute_table(m_max: int, n_max: int) -> npt.NDArray[np.float64]:
    """The table of :func:`bessel_table`, in a child interpreter when large and off the main thread (the same
    SciPy, so the same bits; a plain child, so nothing of this process is imported again or forked)."""
    if threading.current_thread() is not threading.main_thread() and (m_max + 1) * n_max > CHILD_PROCESS_ZEROS:
        try:
            done = subprocess.run([sys.executable, "-c", _CHILD, str(m_max), str(n_max)], capture_output=True,
                                  check=True, timeout=600)
            table = np.load(io.BytesIO(done.stdout))
            if table.shape == (m_max + 1, n_max):
                return np.asarray(table, dtype=np.float64)
        except (OSError, subprocess.SubprocessError, ValueError):
            pass  # no child possible here: computed in this thread, slower for the loop but as right
    return np.array([jn_zeros(m, n_max) for m in range(m_max + 1)])


@dataclass(frozen=True)
class MembraneModes:
    """The lowest modes of a membrane, one entry per mode orientation.

    Attributes
    ----------
    m, n : np.ndarray
        Nodal diameters and circles, int, shape (K,).
    orientation : np.ndarray
        0: cos(m theta), 1: sin(m theta); shape (K,).
    zeros : np.ndarray
        j_mn, shape (K,).
    freq : np.ndarray
        Frequencies, Hz, shape (K,).
    mass : np.ndarray
        Modal masses, kg, shape (K,).
    """

    m: npt.NDArray[np.int64]
    n: npt.NDArray[np.int64]
    orientation: npt.NDArray[np.int64]
    zeros: npt.NDArray[np.float64]
    freq: npt.NDArray[np.float64]
    mass: npt.NDArray[np.float64]

    def shape_at(self, r: float, theta: float) -> npt.NDArray[np.float64]:
        """Mode shapes at the point (r / a, theta radians), shape (K,)."""
        return circular_mode_shapes(self.m, self.orientation, self.zeros, r, theta)


def circular_mode_shapes(
    m: npt.NDArray[np.int64],
    orientation: npt.NDArray[np.int64],
    k_a: npt.NDArray[np.float64],
    r: float,
    theta: float,
) -> npt.NDArray[np.float64]:
    """J_m(k_a r/a) times cos(m theta) (orientation 0) or sin(m theta) (orientation 1), shape (K,).

    The mode shapes of a circular membrane or plate at (r / a clipped to [0, 1], theta radians).
    """
    radial = jv(m, k_a * min(max(r, 0.0), 1.0))
    angular = np.where(orientation == 0, np.cos(m * theta), np.sin(m * theta))
    return np.asarray(radial * angular)


def membrane_modes(
    radius: float,
    tension: float,
    density: float,
    n_modes: int,
    air_loading: float = 0.0,
    splitting: float = 0.0,
) -> MembraneModes:
    """The ``n_modes`` lowest mode orientations of a membrane.

    Parameters
    ----------
    radius : float
        a, metres.
    tension : float
        T, N/m.
    density : float
        sigma, kg/m^2.
    n_modes : int
        Number of mode orientations to keep (an m > 0 mode counts twice).
    air_loading : float
        0: none; 1: the air-mass estimate above; scales the added mass.
    splitting : float
        Relative frequency difference between the two orientations of m > 0 modes.

    Returns
    -------
    MembraneModes
        Sorted by frequency.
    """
    if radius <= 0 or tension <= 0 or density <= 0 or n_modes < 1:
        raise ValueError("radius, tension, density and n_modes must be positive")
    # enough zeros that the n_modes lowest are all there: about X^2 / 2 orientations have j_mn < X
    x = 2.0 * np.sqrt(n_modes) + 10.0
    table = bessel_table(int(x) + 2, int(x / np.pi) + 2)
    m_idx, n_idx = np.meshgrid(np.arange(table.shape[0]), np.arange(table.shape[1]), indexing="ij")
    zeros = table.reshape(-1)
    ms = m_idx.reshape(-1)
    ns = n_idx.reshape(-1) + 1
    order = np.argsort(zeros, kind="stable")
    zeros, ms, ns = zeros[order], ms[order], ns[order]
    # expand orientations
    reps = np.where(ms > 0, 2, 1)
    zeros = np.repeat(zeros, reps)[:n_modes]
    ms_e = np.repeat(ms, reps)[:n_modes]
    ns_e = np.repeat(ns, reps)[:n_modes]
    orient = np.zeros_like(ms_e)
    # second copy of each m > 0 pair is the sin orientation
    first = np.concatenate([[True], (ms_e[1:] != ms_e[:-1]) | (ns_e[1:] != ns_e[:-1])])
    orient[~first] = 1
    c = np.sqrt(tension / density)
    freq = zeros / (2.0 * np.pi * radius) * c
    if air_loading > 0:
        added = RHO_AIR * radius / (density * zeros)  # air mass / head mass per unit area
        freq = freq / np.sqrt(1.0 + air_loading * added)
    if splitting > 0:
        freq = freq * (1.0 + splitting * orient)
    eps = np.where(ms_e == 0, 1.0, 2.0)
    mass = density * np.pi * radius**2 * jv(ms_e + 1, zeros) ** 2 / eps
    return MembraneModes(ms_e, ns_e, orient, zeros, freq, mass)
