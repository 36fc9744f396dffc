"""The pyo end of the signal chain: NumPy blocks in, pyo's graph, blocks out (and the sound card if any).

The vectorised modal bank and the voices render each block in NumPy; the
block is written into a pyo ``DataTable`` shared with NumPy (``getBuffer()``,
no copy) that a ``TableRead`` plays in a loop exactly one block long, so
sample i of the table is output sample i of the block: no added latency.
pyo then applies what it does well (denormal guard, master gain, an optional
``Freeverb`` room, a safety clip) and a ``TableFill`` hands the result back.
The server runs with ``audio='manual'``: one ``process()`` call per block,
no thread, deterministic. A real device is used only by the node, and only
after ``pa_count_devices()`` says one exists (booting portaudio without a
device crashes the interpreter).
"""

from __future__ import annotations

import contextlib
import io
import os
from typing import Any

import numpy as np
import numpy.typing as npt


@contextlib.contextmanager
def _quiet_stderr() -> Any:
    """Silence the C libraries' chatter on fd 2 while pyo loads (ALSA complains when there is no card)."""
    try:
        fd = os.dup(2)
    except OSError:
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        os.dup2(fd, 2)
        os.close(fd)
        os.close(devnull)


def import_pyo() -> Any:
    """Import pyo quietly; returns the module."""
    with _quiet_stderr():
        import pyo

    return pyo


def audio_device_count() -> int:
    """Number of portaudio devices (0 on a machine without a sound card)."""
    pyo = import_pyo()
    with _quiet_stderr():
        try:
            return int(pyo.pa_count_devices())
        except Exception:  # noqa: BLE001 - any failure means no usable device
            return 0


class PyoStage:
    """A pyo graph processing one block per call.

    Parameters
    ----------
    sample_rate : int
        Hz.
    block : int
        Samples per block (the pyo buffer size).
    channels : int
        1 or 2.
    reverb : float
        Wet/dry balance of the room, 0 (dry) to 1.
    master_db : float
        Master gain, dB (SoundCore leaves it at 0 and applies its master before its soft limiter, so that a boost
        is limited rather than clipped here).
    """

    def __init__(
        self, sample_rate: int, block: int, channels: int, reverb: float = 0.0, master_db: float = 0.0
    ) -> None:
        pyo = import_pyo()
        self.block = int(block)
        self.channels = int(channels)
        with _quiet_stderr():
            self.server = pyo.Server(sr=sample_rate, nchnls=channels, buffersize=block, duplex=0, audio="manual")
            self.server.boot()
            self.server.start()
        self.server.setServer()  # new objects belong to this server even if another one exists
        # pyo seeds its random objects (Denorm's anti-denormal noise, about 1e-24) from the system clock's
        # seconds unless given a seed: a render's samples then changed from one second to the next
        self.server.setGlobalSeed(1)
        self._in = [pyo.DataTable(size=block) for _ in range(channels)]
        self._out = [pyo.DataTable(size=block) for _ in range(channels)]
        self.inputs = [np.asarray(t.getBuffer()) for t in self._in]
        self.outputs = [np.asarray(t.getBuffer()) for t in self._out]
        self._read = [pyo.TableRead(t, freq=t.getRate(), loop=1, interp=1).play() for t in self._in]
        self._denorm = pyo.Denorm(self._read)
        gain = 10.0 ** (master_db / 20.0)
        self._gain = pyo.SigTo(gain, time=0.02, init=gain)
        self._dry = self._denorm * self._gain
        self._room = pyo.Freeverb(self._dry, size=0.6, damp=0.6, bal=float(reverb))
        self._clip = pyo.Clip(self._room, min=-1.0, max=1.0)
        self._fill = [pyo.TableFill(self._clip[i], self._out[i]) for i in range(channels)]
        self._keep: list[Any] = [pyo]

    def set_master(self, master_db: float, reverb: float) -> None:
        """Master gain (dB, ramped over 20 ms) and room wet/dry (0..1)."""
        self._gain.value = 10.0 ** (master_db / 20.0)
        self._room.bal = float(reverb)

    def process(self, block: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """One block through the graph; ``block`` shape (n, channels), returns the same shape (a copy)."""
        for c in range(self.channels):
            self.inputs[c][:] = block[:, c]
        self.server.process()
        return np.stack([o.copy() for o in self.outputs], axis=1)

    def close(self) -> None:
        """Stop and free the server."""
        with contextlib.suppress(Exception):
            self.server.stop()
            self.server.shutdown()
