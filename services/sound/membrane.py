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
  which lowers the low modes most, (0,1) most of all: relative to f01 the
  partials spread (snare (1,1)/(0,1) 1.593 -> 1.657), so this makes the
  head more inharmonic, not less. Relative to (1,1) the (m,1) series moves
  only slightly toward the near-harmonic 1 : 1.5 : 2 : 2.5 of timpani (snare
  (2,1)/(1,1) 1.340 -> 1.364); a kettle's enclosed air, which raises (0,1)
  and the other axisymmetric modes, is not modelled;
* orientation splitting: a real head is not perfectly uniform, so the two
  orientations of an m > 0 mode differ slightly and beat.
"""

from __future__ import annotations

import io
import subprocess
import sys
import threading
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import numpy.typing as npt
from scipy.special import jn_zeros, jv

from services.sound.rebuild_worker import run_child

RHO_AIR = 1.2
"""Density of air, kg/m^3."""


CHILD_PROCESS_ZEROS = 2000
"""Off the main thread, a table with more zeros than this is computed in a child process: SciPy's ``jn_zeros``
holds the GIL for 10-40 ms per order at large sizes, which would stall the node's render loop (the main thread)
as surely as computing it there. The default kit's tables have under 500 zeros."""

SHAPE_TABLE_MODES = 1500
"""Mode sets with more modes than this read their radial shapes J_m(k r) from a :class:`BesselGrid` (interpolated,
error under 1e-8) instead of calling SciPy's ``jv`` per mode at every strike (2-7 us a mode: 95 ms a strike at
20,000 modes, in the render loop). No instrument of the default kit has more (cymbals at most 1500, membranes
160), so their shapes, and renders, are exactly as before."""
GRID_STEP = 0.25
"""Spacing of a :class:`BesselGrid` in x (a power of two, so x / step is exact)."""

_TABLES: list[npt.NDArray[np.float64]] = []  # Bessel-zero tables computed so far, none covering another
_TABLES_LOCK = threading.Lock()  # rebuilds run in the node's worker threads (one per instrument) and in the loop


class _Computing:
    """A table or grid one thread is computing (under :data:`_TABLES_LOCK`'s watch): another thread asking for what
    it covers waits for it instead of computing the same thing side by side (5 drums set to 20,000 modes at once:
    5 child interpreters computing one table, 2.7 times as long as one after the other)."""

    def __init__(self, m_max: int, size: float) -> None:
        self.m_max, self.size = m_max, size  # orders 0..m_max; zeros per order (a table) or x_max (a grid)
        self.future: Future[Any] = Future()
        self.waiting = 0  # threads that came to wait for it (tests watch it)

    def covers(self, m_max: int, size: float) -> bool:
        return self.m_max >= m_max and self.size >= size


_COMPUTING_TABLES: list[_Computing] = []
_COMPUTING_GRIDS: list[_Computing] = []


def _wait_for(job: _Computing) -> Any:
    """What ``job`` computes, or None if it failed (the waiter then tries again, and computes it itself)."""
    with _TABLES_LOCK:
        job.waiting += 1
    try:
        return job.future.result()
    except Exception:  # noqa: BLE001 - its thread's error (Abandoned: its worker closed) is its own
        return None


def _computing(jobs: list[_Computing], m_max: int, size: float) -> tuple[_Computing, bool]:
    """Under :data:`_TABLES_LOCK`: the job computing what covers (m_max, size) and False, or a new one, registered,
    and True (the caller computes it and ends it with :func:`_done`)."""
    for job in jobs:
        if job.covers(m_max, size):
            return job, False
    job = _Computing(m_max, size)
    jobs.append(job)
    return job, True


def _done(jobs: list[_Computing], job: _Computing, result: Any = None, error: BaseException | None = None) -> None:
    with _TABLES_LOCK:
        jobs.remove(job)
    if error is not None:
        job.future.set_exception(error)
    else:
        job.future.set_result(result)


def bessel_table(m_max: int = 40, n_max: int = 20) -> npt.NDArray[np.float64]:
    """Zeros j_mn of J_m, shape (m_max + 1, n_max): row m, column n - 1 (read-only).

    Computed once per process for the largest table asked so far and sliced for smaller ones: the table for
    20,000 modes (the most /batteur/sound/modes allows) takes SciPy seconds. A slice is bit-identical to a table
    computed at its own size (``jn_zeros(m, n)`` is the prefix of ``jn_zeros(m, N)``). A table another thread is
    computing that covers this one is waited for, not computed again.
    """
    while True:
        with _TABLES_LOCK:
            for table in _TABLES:
                if table.shape[0] > m_max and table.shape[1] >= n_max:
                    return table[: m_max + 1, :n_max]
            job, mine = _computing(_COMPUTING_TABLES, m_max, n_max)
        if mine:
            break
        table = _wait_for(job)
        if table is not None:
            return table[: m_max + 1, :n_max]
    try:
        table = _compute_table(m_max, n_max)
    except BaseException as exc:
        _done(_COMPUTING_TABLES, job, error=exc)
        raise
    table.flags.writeable = False
    with _TABLES_LOCK:
        _TABLES[:] = [t for t in _TABLES if t.shape[0] > table.shape[0] or t.shape[1] > table.shape[1]]
        _TABLES.append(table)
    _done(_COMPUTING_TABLES, job, table)
    return table


_CHILD = ("import sys, numpy as np; from scipy.special import jn_zeros; m, n = map(int, sys.argv[1:]); "
          "np.save(sys.stdout.buffer, np.array([jn_zeros(k, n) for k in range(m + 1)]))")


def _compute_table(m_max: int, n_max: int) -> npt.NDArray[np.float64]:
    """The table of :func:`bessel_table`, in a child interpreter when large and off the main thread (the same
    SciPy, so the same bits; a plain child, so nothing of this process is imported again or forked)."""
    if threading.current_thread() is not threading.main_thread() and (m_max + 1) * n_max > CHILD_PROCESS_ZEROS:
        try:  # in a rebuild worker, its close() kills the child (Abandoned: no fallback, the result is not wanted)
            table = np.load(io.BytesIO(run_child([sys.executable, "-c", _CHILD, str(m_max), str(n_max)], 600.0)))
            if table.shape == (m_max + 1, n_max):
                return np.asarray(table, dtype=np.float64)
        except (OSError, subprocess.SubprocessError, ValueError):
            pass  # no child possible here: computed in this thread, slower for the loop but as right
    return np.array([jn_zeros(m, n_max) for m in range(m_max + 1)])


@dataclass(frozen=True)
class BesselGrid:
    """J_m(x) and its first two derivatives at x = i GRID_STEP, for m = 0..m_max and i = 0..n - 1: ``points`` has
    shape (m_max + 1, n, 3), the three side by side so that a strike's lookups touch one or two cache lines per
    mode. Quintic Hermite interpolation between two grid points is within 1e-8 of J_m (the sixth derivative of
    J_m is at most 1: error <= step^6 / 46080)."""

    points: npt.NDArray[np.float64]

    @property
    def columns(self) -> int:
        return int(self.points.shape[1])

    @property
    def x_max(self) -> float:
        """Largest x the grid interpolates."""
        return (self.columns - 1) * GRID_STEP

    def covers(self, m_max: int, x_max: float) -> bool:
        return self.points.shape[0] > m_max and self.x_max >= x_max


_GRIDS: list[BesselGrid] = []  # the largest grid computed so far (at most one)


def bessel_grid(m_max: int, x_max: float) -> BesselGrid:
    """A :class:`BesselGrid` covering orders 0..m_max and x in [0, x_max]: computed once per process for the largest
    asked so far (20,000 modes: about 1 s; SciPy's ``jv`` releases the GIL, so a worker thread does not hold the
    render loop) and reused for smaller ones; one another thread is computing that covers it is waited for. The
    grid's points do not depend on its size (x = i step), so the shapes read from it do not depend on what was
    computed before."""
    while True:
        with _TABLES_LOCK:
            if _GRIDS and _GRIDS[0].covers(m_max, x_max):
                return _GRIDS[0]
            if _GRIDS:  # the new grid covers the old one too, so one grid serves every size asked so far
                m_max, x_max = max(m_max, _GRIDS[0].points.shape[0] - 1), max(x_max, _GRIDS[0].x_max)
            job, mine = _computing(_COMPUTING_GRIDS, m_max, x_max)
        if mine:
            break
        waited = _wait_for(job)
        if waited is not None:
            return cast(BesselGrid, waited)
    try:
        grid = _compute_grid(m_max, x_max)
    except BaseException as exc:
        _done(_COMPUTING_GRIDS, job, error=exc)
        raise
    with _TABLES_LOCK:
        if not _GRIDS or grid.covers(_GRIDS[0].points.shape[0] - 1, _GRIDS[0].x_max):
            _GRIDS[:] = [grid]
    _done(_COMPUTING_GRIDS, job, grid)
    return grid


def _compute_grid(m_max: int, x_max: float) -> BesselGrid:
    n = int(np.ceil(x_max / GRID_STEP)) + 2
    x = np.arange(n) * GRID_STEP
    # J_-2 .. J_(m_max + 2): J_-m = (-1)^m J_m; J' = (J_(m-1) - J_(m+1)) / 2, J'' = (J_(m-2) - 2 J_m + J_(m+2)) / 4
    ext = jv(np.abs(np.arange(-2, m_max + 3))[:, None], x[None, :])
    ext[1] = -ext[1]
    value = ext[2:-2]
    return BesselGrid(np.stack([value, 0.5 * (ext[1:-3] - ext[3:-1]), 0.25 * (ext[:-4] - 2.0 * value + ext[4:])],
                               axis=-1))


@dataclass(frozen=True)
class RadialShapes:
    """J_m(k_a r) of a fixed set of modes, interpolated in a :class:`BesselGrid` (a few vector operations per
    strike, whatever the orders)."""

    grid: BesselGrid
    k_a: npt.NDArray[np.float64]
    row: npt.NDArray[np.int64]  # m * grid columns: each mode's row in the grid, as (order, x) pairs

    @classmethod
    def build(cls, m: npt.NDArray[np.int64], k_a: npt.NDArray[np.float64]) -> RadialShapes:
        grid = bessel_grid(int(m.max()), float(k_a.max()))
        return cls(grid, k_a, m.astype(np.int64) * grid.columns)

    def at(self, r: float) -> npt.NDArray[np.float64]:
        """J_m(k_a r) for every mode, r / a in [0, 1]."""
        u = self.k_a * (r / GRID_STEP)
        i = np.minimum(u.astype(np.int64), self.grid.columns - 2)
        t = u - i
        pairs = self.grid.points.reshape(-1, 3)
        at = self.row + i
        here, there = pairs.take(at, axis=0), pairs.take(at + 1, axis=0)  # (K, 3): J, J', J'' at both ends
        t2 = t * t
        t3 = t2 * t
        # quintic Hermite basis: value, slope (times the step) and curvature (times step^2) at both ends
        h_val1 = t3 * (10.0 + t * (-15.0 + 6.0 * t))
        h_d0 = GRID_STEP * t * (1.0 + t2 * (-6.0 + t * (8.0 - 3.0 * t)))
        h_d1 = GRID_STEP * t3 * (-4.0 + t * (7.0 - 3.0 * t))
        h_c0 = GRID_STEP**2 * 0.5 * t2 * (1.0 + t * (-3.0 + t * (3.0 - t)))
        h_c1 = GRID_STEP**2 * 0.5 * t3 * (1.0 + t * (-2.0 + t))
        j0 = here[:, 0]
        return np.asarray(j0 + h_val1 * (there[:, 0] - j0) + h_d0 * here[:, 1] + h_d1 * there[:, 1]
                          + h_c0 * here[:, 2] + h_c1 * there[:, 2])


def radial_shapes(m: npt.NDArray[np.int64], k_a: npt.NDArray[np.float64]) -> RadialShapes | None:
    """The interpolated shapes of a mode set larger than SHAPE_TABLE_MODES (computed now, where the modes are
    built: the node's worker thread), else None (shapes computed exactly at each strike)."""
    return RadialShapes.build(m, k_a) if m.shape[0] > SHAPE_TABLE_MODES else None


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
    radial : RadialShapes or None
        Interpolated radial shapes (more than SHAPE_TABLE_MODES modes), else None.
    """

    m: npt.NDArray[np.int64]
    n: npt.NDArray[np.int64]
    orientation: npt.NDArray[np.int64]
    zeros: npt.NDArray[np.float64]
    freq: npt.NDArray[np.float64]
    mass: npt.NDArray[np.float64]
    radial: RadialShapes | None = None

    def shape_at(self, r: float, theta: float) -> npt.NDArray[np.float64]:
        """Mode shapes at the point (r / a, theta radians), shape (K,)."""
        return circular_mode_shapes(self.m, self.orientation, self.zeros, r, theta, self.radial)


def circular_mode_shapes(
    m: npt.NDArray[np.int64],
    orientation: npt.NDArray[np.int64],
    k_a: npt.NDArray[np.float64],
    r: float,
    theta: float,
    table: RadialShapes | None = None,
) -> npt.NDArray[np.float64]:
    """J_m(k_a r/a) times cos(m theta) (orientation 0) or sin(m theta) (orientation 1), shape (K,).

    The mode shapes of a circular membrane or plate at (r / a clipped to [0, 1], theta radians); the radial part
    is read from ``table`` (the same modes' :class:`RadialShapes`) when given.
    """
    rc = min(max(r, 0.0), 1.0)
    radial = jv(m, k_a * rc) if table is None else table.at(rc)
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
    return MembraneModes(ms_e, ns_e, orient, zeros, freq, mass, radial_shapes(ms_e, zeros))
