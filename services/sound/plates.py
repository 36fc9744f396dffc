"""Modes of cymbals, bells and rims: dense inharmonic plates and a few bell-like partials.

A cymbal is modelled as a thin free-edge circular plate of bronze, stiffened
by its curvature. Kirchhoff plate theory gives
``f_mn = lambda_mn^2 / (2 pi a^2) sqrt(D / (rho h))`` with bending stiffness
``D = E h^3 / (12 (1 - nu^2))``; for a free edge ``lambda_mn`` is close to
``(pi / 2) (m + 2 n) + c`` above the first few modes (Leissa). The dome and
the lathing make a cymbal stiffer in its low modes; this is the
``curvature_hz`` term added in quadrature. Mode density then comes out
constant in frequency, as plate theory predicts (about one mode every
20 Hz for a 16" crash): a dense, inharmonic, noisy spectrum. Hammering makes
every cymbal irregular: each mode is detuned by a reproducible random amount
(``irregularity``), which also splits the two orientations of m > 0 modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from services.sound.membrane import RadialShapes, circular_mode_shapes, radial_shapes

BRONZE_E = 1.1e11
"""Young's modulus of B20 bronze, Pa."""
BRONZE_RHO = 8600.0
"""Density of B20 bronze, kg/m^3."""
BRONZE_NU = 0.34

# exact free-edge eigenvalues lambda^2 of the first modes (nu ~ 0.33, Leissa), keyed by (m, n)
_FREE_LOW = {(2, 0): 5.253, (0, 1): 9.084, (3, 0): 12.23, (1, 1): 20.52, (4, 0): 21.6, (5, 0): 33.1, (2, 1): 35.2}


@dataclass(frozen=True)
class PlateModes:
    """Mode orientations of a plate, sorted by frequency.

    Attributes
    ----------
    m : np.ndarray
        Nodal diameters, shape (K,).
    orientation : np.ndarray
        0: cos(m theta), 1: sin(m theta), shape (K,).
    k_a : np.ndarray
        Dimensionless radial wavenumber (lambda) used for the mode shape J_m(lambda r / a).
    freq : np.ndarray
        Hz, shape (K,).
    mass : np.ndarray
        Modal masses, kg, shape (K,).
    radial : RadialShapes or None
        Interpolated radial shapes (more than SHAPE_TABLE_MODES modes), else None.
    """

    m: npt.NDArray[np.int64]
    orientation: npt.NDArray[np.int64]
    k_a: npt.NDArray[np.float64]
    freq: npt.NDArray[np.float64]
    mass: npt.NDArray[np.float64]
    radial: RadialShapes | None = None

    def shape_at(self, r: float, theta: float) -> npt.NDArray[np.float64]:
        """Approximate mode shapes at (r / a, theta radians), shape (K,), |value| <= 1."""
        return circular_mode_shapes(self.m, self.orientation, self.k_a, r, theta, self.radial)


def plate_modes(
    radius: float,
    thickness: float,
    n_modes: int,
    curvature_hz: float = 150.0,
    irregularity: float = 0.03,
    seed: int = 0,
    f_max: float = 20000.0,
) -> PlateModes:
    """The lowest ``n_modes`` mode orientations (up to ``f_max`` Hz) of a cymbal-like plate.

    Parameters
    ----------
    radius, thickness : float
        metres.
    n_modes : int
        Upper bound on the number of mode orientations kept.
    curvature_hz : float
        Stiffening of the low modes by the dome, Hz (added in quadrature).
    irregularity : float
        Relative standard deviation of the per-mode detuning (hammering).
    seed : int
        Seed of the detuning, so a cymbal always sounds the same.
    f_max : float
        Highest frequency kept, Hz.
    """
    if radius <= 0 or thickness <= 0 or n_modes < 1:
        raise ValueError("radius, thickness and n_modes must be positive")
    d = BRONZE_E * thickness**3 / (12.0 * (1.0 - BRONZE_NU**2))
    speed = np.sqrt(d / (BRONZE_RHO * thickness))  # m^2/s
    scale = speed / (2.0 * np.pi * radius**2)  # f = scale * lambda^2
    lam_max = np.sqrt(f_max / scale) + 2.0
    m_max = int(2 * lam_max / np.pi) + 2
    n_max = int(lam_max / np.pi) + 2
    grid_m, grid_n = np.meshgrid(np.arange(m_max + 1), np.arange(n_max + 1), indexing="ij")
    mm, nn = grid_m.reshape(-1), grid_n.reshape(-1)
    lam = (np.pi / 2.0) * (mm + 2 * nn) + 0.4
    lam2 = lam**2
    for (m, n), value in _FREE_LOW.items():
        lam2[(mm == m) & (nn == n)] = value
    keep = (mm + nn >= 2) | ((mm == 0) & (nn >= 1))  # no rigid-body modes
    keep &= ~((mm == 1) & (nn == 0))
    mm, nn, lam2 = mm[keep], nn[keep], lam2[keep]
    reps = np.where(mm > 0, 2, 1)
    mm_e = np.repeat(mm, reps)
    lam2_e = np.repeat(lam2, reps)
    orient = np.zeros_like(mm_e)
    first = np.concatenate([[True], np.diff(np.repeat(np.arange(mm.shape[0]), reps)) != 0])
    orient[~first] = 1
    rng = np.random.default_rng(seed)
    f_plate = scale * lam2_e
    freq = np.sqrt(f_plate**2 + curvature_hz**2) * np.exp(irregularity * rng.standard_normal(mm_e.shape[0]))
    order = np.argsort(freq, kind="stable")
    freq, mm_e, orient, lam2_e = freq[order], mm_e[order], orient[order], lam2_e[order]
    sel = freq < f_max
    freq, mm_e, orient, lam2_e = freq[sel][:n_modes], mm_e[sel][:n_modes], orient[sel][:n_modes], lam2_e[sel][:n_modes]
    plate_mass = BRONZE_RHO * thickness * np.pi * radius**2
    mass = np.full(freq.shape[0], plate_mass / 4.0)
    k_a = np.sqrt(lam2_e)
    return PlateModes(mm_e, orient, k_a, freq, mass, radial_shapes(mm_e, k_a))


# Partials of a cowbell and of a ride bell relative to their lowest, from published spectra
COWBELL_RATIOS = np.array([1.0, 1.48, 2.07, 2.51, 2.94, 3.58, 4.27, 5.11])
COWBELL_GAINS = np.array([1.0, 0.8, 0.35, 0.5, 0.3, 0.2, 0.15, 0.1])
BELL_RATIOS = np.array([1.0, 1.51, 2.02, 2.44, 2.99, 3.63, 4.31, 5.07, 5.94, 6.83])
BELL_GAINS = np.array([1.0, 0.7, 0.6, 0.45, 0.4, 0.3, 0.25, 0.2, 0.15, 0.12])


def ring_modes(f2: float, n_max: int = 14) -> npt.NDArray[np.float64]:
    """Flexural modes of a thin ring (a drum's hoop): f_n proportional to n (n^2 - 1) / sqrt(n^2 + 1), n >= 2."""
    n = np.arange(2, n_max + 1, dtype=np.float64)
    shape = n * (n**2 - 1) / np.sqrt(n**2 + 1)
    return np.asarray(f2 * shape / shape[0])
