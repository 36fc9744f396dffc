"""A block-wise vectorised bank of damped modal resonators.

Each mode k is a complex one-pole resonator with pole
``p_k = exp((-sigma_k + 2j pi f_k) / sr)``; its output is the imaginary part of
its complex state, so a struck mode sounds ``a_k exp(-sigma_k t) sin(2 pi f_k t + phi_k)``.

Instead of a recursion per sample (one pyo object per mode), the bank computes a
whole block at once. Writing the sample index in the block as ``n = Bn a + b``
(``a < A``, ``b < Bn``, ``A Bn = block``, 16 x 16 for 256) gives

``y[Bn a + b] = Im(sum_k z_k p_k^(Bn a) p_k^b)``

which is a real matrix product ``(A x 2K) @ (2K x Bn)`` of the state scaled by
``p^(Bn a)`` (A cheap vector products, row after row while it is in cache)
with a table of ``p^b`` computed when the modes change: BLAS does the work,
about one multiply-add pair per mode-sample, and the only large array read
per block is the table (2K x Bn float32).
Strikes are injected sample-accurately inside a block. A bank whose energy has
decayed below a floor is zeroed and skipped, so decayed modes cost nothing and
never reach denormal floats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]


MAX_DECAY_PER_BLOCK = 12.0
"""Fastest decay a mode renders with, nepers per block (e^-12, -104 dB). A strike inside a block is folded into
the state at the block's start, scaled by up to e^(decay x block), and that must stay finite and precise in
float32: a faster mode (the heaviest damping the panel allows, or a tiny drum's modes far above Nyquist) would
overflow to NaN and take the whole mix with it. Such modes die within a few milliseconds (T60 0.58 block, 3 ms at
256 samples) at this rate too."""


MAX_T60_S = 30.0
"""Longest ring a mode renders with, seconds (time to decay by 60 dB): slower decay rates, down to the zero that
``/batteur/sound/damping 0 0`` allows, are raised to ``6.91 / MAX_T60_S`` (0.23 1/s). Undamped modes would ring at
full level for ever (the instrument never stops costing its bank) and every strike would add to them without
bound. The slowest mode of the default kit (the ride, 0.35 1/s, T60 20 s) is above it, so it changes nothing there;
with the bank's floor, an undamped drum falls silent about a minute after its last strike."""
MIN_DECAY_PER_S = 6.91 / MAX_T60_S
"""Slowest decay rate a mode renders with, 1/s (see ``MAX_T60_S``)."""


INVERSE_POWERS = 8
"""Columns of :attr:`BankTables.inverse_powers`: p^-j for j < 8, what a contact force injected in chunks of 8
samples needs (:func:`services.sound.excitation.mode_response_chunks`), computed with the modes and not per
strike."""


def _split(block: int) -> tuple[int, int]:
    """Factor a block length into (A, Bn), A as large as 16 with Bn >= 8 (256 -> 16 x 16)."""
    for a in (16, 8, 4, 2):
        if block % a == 0 and block // a >= 8:
            return a, block // a
    return 1, block


def _fit(values: ComplexArray, k: int) -> ComplexArray:
    """Truncate or zero-pad to length k."""
    if values.shape[0] >= k:
        return values[:k]
    return np.pad(values, (0, k - values.shape[0]))


@dataclass(frozen=True)
class BankTables:
    """Everything a bank computes from its modes, read-only: :meth:`ModeSet.adopt` takes it whole, so a table
    added here is adopted with the rest.

    ``table`` is (2K, Bn) float32, rows interleaved per mode (2k: Im p^b, 2k+1: Re p^b, zero for modes that would
    alias) to match a complex64 array viewed as float32 pairs (Re, Im): no copy, and the first n modes are a
    prefix. ``p_b_rows`` (Bn, K) and ``p_a_rows`` (A, K) give p^q = p^(Bn a) p^b for a strike inside a block.
    """

    freq: FloatArray  # Hz, (K,)
    decay: FloatArray  # 1/s, (K,), limited to [MIN_DECAY_PER_S, MAX_DECAY_PER_BLOCK per block]
    slowed: int  # modes whose decay rate was raised to MIN_DECAY_PER_S
    poles_log: ComplexArray  # log p per sample, (K,)
    table: npt.NDArray[np.float32]  # (2K, Bn): Im p^b, Re p^b
    p_bn: npt.NDArray[np.complex64]  # (K,): p^Bn
    p_b_rows: ComplexArray  # (Bn, K): p^b
    p_a_rows: ComplexArray  # (A, K): p^(Bn a)
    p_block: ComplexArray  # (K,): p^block
    inverse_powers: ComplexArray  # (K, INVERSE_POWERS): p^-j


def _tables(freq: FloatArray, decay: FloatArray, slowed: int, sr: float, block: int, a_rows: int,
            bn: int) -> BankTables:
    """The tables of modes ``freq`` (Hz) decaying at ``decay`` (1/s, already limited)."""
    k = freq.shape[0]
    s = (-decay + 2j * np.pi * freq) / sr
    audible = (freq < 0.48 * sr).astype(np.float64)
    b = np.exp(np.outer(s, np.arange(bn)))  # (K, Bn): p^b
    # Im(x y) = Re(x) Im(y) + Im(x) Re(y)
    table = np.empty((k, 2, bn))
    table[:, 0, :] = b.imag * audible[:, None]
    table[:, 1, :] = b.real * audible[:, None]
    return BankTables(
        freq=freq, decay=decay, slowed=slowed, poles_log=np.asarray(s, dtype=np.complex128),
        table=np.ascontiguousarray(table.reshape(2 * k, bn), dtype=np.float32),
        p_bn=np.exp(s * bn).astype(np.complex64),
        p_b_rows=np.ascontiguousarray(b.T),
        p_a_rows=np.exp(np.outer(np.arange(a_rows) * bn, s)),
        p_block=np.exp(s * block),
        inverse_powers=np.exp(-np.outer(s, np.arange(INVERSE_POWERS))))


def _damped(base: BankTables, decay: FloatArray, slowed: int, sr: float, block: int, bn: int) -> BankTables:
    """``base``'s tables with the same frequencies decaying at ``decay`` (1/s, limited) instead, from ``base`` by
    real factors: p' = p rho with rho = exp(-(decay - base.decay) / sr), so p'^n = p^n rho^n (real powers and
    products instead of ``_tables``' complex exponentials: a press costs the render loop 2.5-3x less)."""
    rho = np.exp(-(decay - base.decay) / sr)  # (K,)
    k = rho.shape[0]
    a_rows = base.p_a_rows.shape[0]
    rho_b = rho[None, :] ** np.arange(bn)[:, None]  # (Bn, K)
    rho_a = rho[None, :] ** (np.arange(a_rows) * bn)[:, None]  # (A, K)
    table = base.table.reshape(k, 2, bn) * rho_b.T.astype(np.float32)[:, None, :]  # zero rows (aliasing) stay zero
    return BankTables(
        freq=base.freq, decay=decay, slowed=slowed, poles_log=base.poles_log - (decay - base.decay) / sr,
        table=table.reshape(2 * k, bn),
        p_bn=(base.p_bn * (rho**bn)).astype(np.complex64),
        p_b_rows=base.p_b_rows * rho_b,
        p_a_rows=base.p_a_rows * rho_a,
        p_block=base.p_block * rho**block,
        inverse_powers=base.inverse_powers * rho[:, None] ** -np.arange(INVERSE_POWERS)[None, :])


class ModeSet:
    """A set of K modes rendered block by block.

    Parameters
    ----------
    sample_rate : float
        Sample rate, Hz.
    block : int
        Block length, samples.
    floor : float
        Amplitude below which a silent bank is zeroed and skipped (output units).
    """

    def __init__(self, sample_rate: float, block: int, floor: float = 1e-7) -> None:
        self.sr = float(sample_rate)
        self.block = int(block)
        self.floor = float(floor)
        self.A, self.Bn = _split(self.block)
        self.z: ComplexArray = np.zeros(0, dtype=np.complex128)
        self._pending: list[tuple[int, ComplexArray]] = []
        self._retunes: list[tuple[int, BankTables]] = []  # (offset in the next block, tables from then on)
        self._blocks = 0
        self._live = False
        self.n_live = 0
        self._use(_tables(np.zeros(0), np.zeros(0), 0, self.sr, self.block, self.A, self.Bn))

    # ------------------------------------------------- tables (read-only, shared by adopt)
    @property
    def freq(self) -> FloatArray:
        """Mode frequencies, Hz, shape (K,)."""
        return self.tables.freq

    @property
    def decay(self) -> FloatArray:
        """Decay rates as rendered (limited), 1/s, shape (K,)."""
        return self.tables.decay

    @property
    def slowed(self) -> int:
        """Modes whose decay rate the last ``set_modes`` raised to ``MIN_DECAY_PER_S``."""
        return self.tables.slowed

    @property
    def poles_log(self) -> ComplexArray:
        """log of each mode's pole per sample, shape (K,)."""
        return self.tables.poles_log

    @property
    def _table(self) -> npt.NDArray[np.float32]:
        return self.tables.table

    # ------------------------------------------------------------------ modes
    @property
    def size(self) -> int:
        """Number of modes K."""
        return int(self.freq.shape[0])

    @property
    def active(self) -> bool:
        """True while the bank holds energy or a pending strike."""
        return bool(self._pending) or self._live

    def set_modes(self, freq_hz: npt.ArrayLike, decay_per_s: npt.ArrayLike) -> None:
        """Set mode frequencies (Hz, shape (K,)) and decay rates (1/s, shape (K,)).

        Modes above 0.48 sr get zero output (they would alias); decay rates are capped at
        ``MAX_DECAY_PER_BLOCK`` nepers per block and raised to at least ``MIN_DECAY_PER_S`` (stored so; the
        raised ones counted in ``slowed``). The state of
        modes that keep their index is kept, so a live change bends the pitch
        of a ringing drum instead of cutting it; new modes start silent.
        """
        f = np.asarray(freq_hz, dtype=np.float64).reshape(-1)
        d = np.asarray(decay_per_s, dtype=np.float64).reshape(-1)
        if f.shape != d.shape:
            raise ValueError(f"freq and decay shapes differ: {f.shape} vs {d.shape}")
        if np.any(~np.isfinite(f)) or np.any(~np.isfinite(d)) or np.any(f < 0) or np.any(d < 0):
            raise ValueError("mode frequencies and decay rates must be finite and >= 0")
        self._use(_tables(f, self._limit(d), int(np.count_nonzero(d < MIN_DECAY_PER_S)), self.sr, self.block, self.A,
                          self.Bn))

    def _limit(self, d: FloatArray) -> FloatArray:
        """Decay rates ``d`` (1/s) limited to the rendered range."""
        return np.minimum(np.maximum(d, MIN_DECAY_PER_S), MAX_DECAY_PER_BLOCK * self.sr / self.block)

    def retune(self, decay_per_s: npt.ArrayLike, offset: int = 0) -> None:
        """Decay at ``decay_per_s`` (1/s, shape (K,), limited as in :meth:`set_modes`) from sample ``offset`` of
        the next block on, same frequencies: the ringing state carries over, so a press damps what rings from
        its own sample (a stick laid on a ringing head) and a lift lets it ring on at the law's rate."""
        if not 0 <= offset < self.block:
            raise ValueError(f"offset {offset} outside the block [0, {self.block})")
        self._retunes.append((int(offset), self._damped_tables(decay_per_s)))

    def set_decay(self, decay_per_s: npt.ArrayLike) -> None:
        """Decay at ``decay_per_s`` from the next block on (between blocks: a rebuild of a pressed instrument);
        :meth:`retune` inside a block."""
        self.tables = self._damped_tables(decay_per_s)

    def _damped_tables(self, decay_per_s: npt.ArrayLike) -> BankTables:
        """The tables of the current modes decaying at ``decay_per_s`` (1/s, shape (K,)), derived from the
        law's (those of the last :meth:`set_modes`); exactly the law's when it is theirs (a press lifted)."""
        d = np.asarray(decay_per_s, dtype=np.float64).reshape(-1)
        if d.shape != self.freq.shape:
            raise ValueError(f"decay has {d.shape[0]} modes, bank has {self.size}")
        if np.any(~np.isfinite(d)) or np.any(d < 0):
            raise ValueError("decay rates must be finite and >= 0")
        base = self.law_tables
        limited = self._limit(d)
        if np.array_equal(limited, base.decay):
            return base
        return _damped(base, limited, int(np.count_nonzero(d < MIN_DECAY_PER_S)), self.sr, self.block, self.Bn)

    def adopt(self, other: ModeSet) -> None:
        """Take ``other``'s modes and tables (built elsewhere, e.g. in a worker thread), keeping this bank's
        ringing state and pending strikes: the same result as ``set_modes`` with ``other``'s modes, without its
        cost. Both banks must have the same sample rate and block."""
        if (other.sr, other.block) != (self.sr, self.block):
            raise ValueError("banks differ in sample rate or block")
        self._use(other.tables)

    def _use(self, tables: BankTables) -> None:
        """Render with ``tables`` from now on: modes that keep their index keep their state, new ones start
        silent, pending strikes are fitted to the new count."""
        self.tables = tables
        self.law_tables = tables  # what :meth:`retune` derives damped tables from
        k = tables.freq.shape[0]
        z = np.zeros(k, dtype=np.complex128)
        n = min(self.z.shape[0], k)
        z[:n] = self.z[:n]
        self.z = z
        self._pending = [(off, _fit(amp, k)) for off, amp in self._pending]
        self._retunes = [(off, t) for off, t in self._retunes if t.freq.shape[0] == k]  # stale ones dropped
        self._scaled = np.empty((self.A, k), dtype=np.complex64)  # z p^(Bn a), built by repeated products
        self._live = bool(np.any(self.z != 0))
        self.n_live = k if self._live else 0

    def powers(self, n: int) -> ComplexArray:
        """p_k^n for every mode, shape (K,)."""
        return np.asarray(np.exp(self.tables.poles_log * n))

    def _advance(self, q: int) -> ComplexArray:
        """p_k^q for 0 <= q <= block from the tables (no exp): (p^Bn)^a p^b with q = Bn a + b."""
        t = self.tables
        if q == self.block:
            return t.p_block
        a, b = divmod(q, self.Bn)
        return np.asarray(t.p_a_rows[a] * t.p_b_rows[b])

    # ---------------------------------------------------------------- strikes
    def strike(self, amplitude: npt.ArrayLike, offset: int = 0) -> None:
        """Start every mode with complex amplitude ``amplitude[k]`` at sample ``offset`` of the next block.

        The mode then sounds ``Im(amplitude[k] p_k^(n - offset))`` for
        ``n >= offset``; strikes add (the bank is linear), so rolls and flams sum.
        """
        amp = np.asarray(amplitude, dtype=np.complex128).reshape(-1)
        if amp.shape[0] != self.size:
            raise ValueError(f"amplitude has {amp.shape[0]} modes, bank has {self.size}")
        if not 0 <= offset < self.block:
            raise ValueError(f"offset {offset} outside the block [0, {self.block})")
        self._pending.append((int(offset), amp))

    def scale(self, factor: float) -> None:
        """Multiply the ringing state (e.g. a level change)."""
        self.z *= factor

    def clear(self) -> None:
        """Silence every mode at once."""
        self.z[:] = 0
        self._pending.clear()
        self._live = False
        self.n_live = 0

    def reset(self) -> None:
        """Silent, with a fresh state fitted to the tables (a render that raised may have left it half-updated):
        pending strikes dropped, the last pending decay change taken at once."""
        if self._retunes:
            self.tables = self._retunes[-1][1]
        self._retunes.clear()
        self._pending.clear()
        self.z = np.zeros(self.size, dtype=np.complex128)
        self._scaled = np.empty((self.A, self.size), dtype=np.complex64)
        self._live = False
        self.n_live = 0

    # ---------------------------------------------------------------- render
    def _block_of(self, z: ComplexArray, n: int | None = None, rows: int | None = None) -> npt.NDArray[np.float32]:
        """Im(sum_k z_k p_k^i) for i in [0, rows * Bn) (default: the block) over the first ``n`` modes, float32."""
        n = self.size if n is None else n
        rows = self.A if rows is None else rows
        if n == 0:
            return np.zeros(rows * self.Bn, dtype=np.float32)
        scaled = self._scaled[:rows, :n]  # (rows, n) complex64: z p^(Bn a), each row from the previous one
        scaled[0] = z[:n]
        p_bn = self.tables.p_bn[:n]
        for a in range(1, rows):
            np.multiply(scaled[a - 1], p_bn, out=scaled[a])
        return (scaled.view(np.float32) @ self.tables.table[: 2 * n]).reshape(-1)

    def process(self, out: npt.NDArray[np.float32]) -> None:
        """Add the next block of the bank's output into ``out`` (shape (block,)).

        Skips all work when the bank is silent.
        """
        if self.size == 0:
            self._pending.clear()
            self._retunes.clear()
            return
        if self._retunes:
            self._fold_with_retunes(out)
        elif self._pending:
            for offset, amp in self._pending:
                self._fold(offset, amp, out)
            self._pending.clear()
            self._live = True
            self.n_live = self.size
        if self._live:
            n = self.n_live
            out += self._block_of(self.z, n)
            self.z[:n] *= self.tables.p_block[:n]
        self._blocks += 1
        if self._live and self._blocks % 8 == 0:
            # modes are sorted by frequency and high modes decay first: keep rendering only the
            # prefix that still holds energy, zero the rest (so nothing ever reaches denormal floats)
            live = self.z[: self.n_live]
            mag = np.abs(live)
            live[mag < self.floor] = 0
            above = np.nonzero(mag >= self.floor)[0]
            n_live = int(above[-1]) + 1 if above.size else 0
            if n_live < self.n_live:
                self.z[n_live: self.n_live] = 0
                self.n_live = n_live
            if n_live == 0:
                self._live = False

    def _fold(self, offset: int, amp: ComplexArray, out: npt.NDArray[np.float32]) -> None:
        """Fold a strike at sample ``offset`` into the state at the block start."""
        # a strike at sample `offset` is the same as amplitude amp p^-offset at the block start,
        # minus what that would have sounded before `offset` (a partial product, offset / block of a block)
        if offset == 0:
            self.z += amp
            return
        shifted = amp / self._advance(offset)
        self.z += shifted
        rows = -(-offset // self.Bn)
        out[:offset] -= self._block_of(shifted, self.size, rows)[:offset]

    def _fold_with_retunes(self, out: npt.NDArray[np.float32]) -> None:
        """Fold this block's strikes and decay changes, in sample order, into the state at the block start
        under the last tables: each change keeps what was heard before its sample and continues the state
        from it with the new poles."""
        events = sorted([(off, 0, i) for i, (off, _) in enumerate(self._retunes)]
                        + [(off, 1, i) for i, (off, _) in enumerate(self._pending)])  # a change first on a tie
        struck = False
        for offset, kind, i in events:
            if kind == 1:
                self._fold(offset, self._pending[i][1], out)
                struck = True
                continue
            tables = self._retunes[i][1]
            if offset == 0 or not (struck or self._live):
                self.tables = tables
                continue
            # heard before `offset`: the state under the old poles; from it on, that state at `offset`
            # continued with the new poles (written as a state at the block start, minus its part before)
            rows = -(-offset // self.Bn)
            before = self._block_of(self.z, self.size, rows)[:offset].copy()
            at = self.z * self._advance(offset)
            self.tables = tables
            self.z = at / self._advance(offset)
            out[:offset] += before - self._block_of(self.z, self.size, rows)[:offset]
        self._retunes.clear()
        self._pending.clear()
        if struck:
            self._live = True
            self.n_live = self.size

    def energy(self) -> float:
        """Sum of squared mode amplitudes (output units squared)."""
        return float(np.sum(np.abs(self.z) ** 2))
