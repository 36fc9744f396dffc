"""Sound parameters files: the instrument parameters the ``/batteur/sound/...`` controls set, kept across restarts.

A sound designer shapes the kit live over OSC (Pure Data, ossia score); ``batteur sound --sound-params-out FILE``
writes what the instruments hold when the node stops, and ``--sound-params FILE`` (also ``batteur render``,
``python -m services.sound.demo``) starts from it. YAML or JSON::

    # batteur sound parameters
    instruments:
      snare:                       # a kit object id
        tension: 3200              # /batteur/sound/tension, N/m
        level: -3                  # /batteur/sound/level, dB
        damping: {sigma0: 14, sigma1: 1.2e-05}   # /batteur/sound/damping's fields
        resonances: [1.0, 0.6]     # /batteur/sound/resonances
      ride:
        model: sample              # /batteur/sound/model

A parameter's key is the last part of its control's address (``air`` for ``/batteur/sound/air``, ``modes`` for
``/batteur/sound/modes``); its value the control's one value, or a mapping of its fields (``damping``, ``stick``,
``second_head``). Ranges are the controls' (docs/osc.md). Each is applied as its control is, on top of the kit's
defaults and ``--model``: a ``radius`` keeps the tension (the drum goes down in pitch), unlike a kit file's radius
(docs/sound.md). A file written by the node holds only what differs from those defaults.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from common.datafile import first_error, parse_file
from common.input_file import NO_SUCH_FILE, file_problem
from common.kit import Kit
from common.messages import OscMessage
from common.output_paths import write_atomically
from services.sound.core import PARAM_MESSAGES, SoundCore, not_taken
from services.sound.instruments import KIND_PARAMS, Instrument, ParamError, Params, default_params

PARAMS_FILE = "a sound parameters file (.yaml or .json)"

KEYS: dict[str, type[OscMessage]] = {cls.ADDRESS.rsplit("/", 1)[1]: cls for cls in PARAM_MESSAGES}
"""A file's parameter key (the last part of the control's address) -> its control message."""
NAME_KEYS: dict[str, str] = {name: key for key, cls in KEYS.items() for name in [PARAM_MESSAGES[cls][0]]}
"""An instrument's parameter name (``air_loading``) -> the file's key (``air``)."""

InstrumentId = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$")]


class SoundParamsFile(BaseModel):
    """The file: ``instruments`` -> kit object id -> parameter key -> value (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")

    instruments: dict[InstrumentId, dict[str, Any]] = Field(
        default_factory=dict, description="kit object id -> {parameter: value}; parameters named as the last part "
        "of their control's address (tension, level, air, modes, damping, ...)")

    def messages(self) -> list[OscMessage]:
        """Each entry as the control message that sets it, in file order; ValueError naming the entry
        (``instruments.snare.tension: ...``) for an unknown key or a value its control refuses."""
        out = []
        for instrument, params in self.instruments.items():
            for key, value in params.items():
                out.append(_message(instrument, key, value))
        return out


def _message(instrument: str, key: str, value: Any) -> OscMessage:
    where = f"instruments.{instrument}.{key}"
    cls = KEYS.get(key)
    if cls is None:
        raise ValueError(f"{where}: no such sound parameter (the file takes: {', '.join(sorted(KEYS))}, "
                         "each the last part of a /batteur/sound/... address)")
    fields = [f for f in cls.model_fields if f != "instrument"]
    if isinstance(value, Mapping):
        data = {"instrument": instrument, **value}
    elif len(fields) == 1:
        data = {"instrument": instrument, fields[0]: value}
    else:
        raise ValueError(f"{where}: give its fields as a mapping ({{{', '.join(f'{f}: ...' for f in fields)}}}, "
                         f"as {cls.ADDRESS} takes them), got {value!r}")
    try:
        return cls.model_validate(data)
    except ValidationError as exc:
        said = first_error(exc)
        field = said.split(":", 1)[0]
        if field in fields and len(fields) == 1:  # one value: its field's name is the key's
            said = said.split(":", 1)[1].strip()
        raise ValueError(f"{where} ({cls.ADDRESS}): {said}") from None


def load_sound_params(path: Path) -> list[OscMessage]:
    """The control messages a sound parameters file holds; FileNotFoundError or ValueError naming the file (and
    the bad entry)."""
    problem = file_problem(path, PARAMS_FILE)
    if problem == NO_SUCH_FILE:
        raise FileNotFoundError(f"--sound-params {path}: no such file")
    if problem is not None:
        raise FileNotFoundError(f"--sound-params {path}: {problem}")
    try:
        data = parse_file(path)
    except (OSError, ValueError) as exc:
        raise ValueError(f"--sound-params {path}: {exc}") from None
    if data is None:
        data = {}
    try:
        return SoundParamsFile.model_validate(data).messages()
    except ValidationError as exc:
        raise ValueError(f"--sound-params {path}: {first_error(exc)}") from None
    except ValueError as exc:
        raise ValueError(f"--sound-params {path}: {exc}") from None


def check_against_kit(messages: list[OscMessage], kit: Kit, source: Path) -> None:
    """ValueError naming ``source`` and the entry for an instrument ``kit`` does not sound, or a parameter its
    kind does not take (checked before a render's long part; values are checked when applied)."""
    kinds = {o.id: o.kind for o in kit.objects if o.kind in KIND_PARAMS}
    for message in messages:
        instrument = str(message.model_dump()["instrument"])
        key = message.ADDRESS.rsplit("/", 1)[1]
        kind = kinds.get(instrument)
        if kind is None:
            raise ValueError(f"--sound-params {source}: instruments.{instrument}: the kit {kit.name!r} has no "
                             f"instrument {instrument!r} (it has: {', '.join(sorted(kinds))})")
        if PARAM_MESSAGES[type(message)][0] not in KIND_PARAMS[kind]:
            raise ValueError(f"--sound-params {source}: instruments.{instrument}.{key}: "
                             f"{not_taken(kind, instrument, message.ADDRESS)}")


def apply_sound_params(core: SoundCore, messages: list[OscMessage], source: Path) -> None:
    """Apply ``messages`` to ``core``'s instruments at once, before it plays (no background rebuild); ValueError
    naming ``source`` and the entry for one an instrument refuses. A value equal to what the instrument holds
    rebuilds nothing (a written file reloads fast)."""
    check_against_kit(messages, core.kit, source)
    for message in messages:
        name, fields = PARAM_MESSAGES[type(message)]
        inst = core.instruments.instruments[str(message.model_dump()["instrument"])]
        values = {f: getattr(message, f) for f in fields}
        if current_values(inst).get(name) == values:
            continue
        try:
            inst.set_param(name, **values)
        except ParamError as exc:
            raise ValueError(f"--sound-params {source}: instruments.{inst.id}.{NAME_KEYS[name]}: {exc}") from None


def current_values(inst: Instrument) -> dict[str, dict[str, Any]]:
    """The fields of every control ``inst`` takes, as it holds them now (parameter name -> {field: value})."""
    return {name: values for name, values in _all_values(inst.p, inst.model).items() if name in inst.accepted}


def _all_values(p: Params, model: str) -> dict[str, dict[str, Any]]:
    return {
        "model": {"model": model}, "level": {"gain_db": p.level_db}, "radius": {"value": p.radius},
        "tension": {"value": p.tension}, "density": {"value": p.density}, "thickness": {"value": p.thickness},
        "damping": {"sigma0": p.damping0, "sigma1": p.damping1}, "n_modes": {"value": p.n_modes},
        "position": {"value": p.position},
        "stick": {"mass": p.stick_mass, "stiffness": p.stick_stiffness, "exponent": p.stick_exponent},
        "snares": {"value": p.snares}, "openness": {"value": p.openness}, "resonances": {"gains": p.resonances},
        "air_loading": {"value": p.air_loading}, "second_head": {"gain": p.second_head, "ratio": p.reso_ratio},
    }


def _plain(values: dict[str, Any]) -> Any:
    """A control's fields as the file writes them: the one value alone, a tuple as a list."""
    shown = {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()}
    return next(iter(shown.values())) if len(shown) == 1 else shown


def changed_params(core: SoundCore) -> dict[str, dict[str, Any]]:
    """What each instrument holds that differs from the kit's defaults and the core's initial model:
    instrument -> {file key: value}, instruments and keys in a stable order."""
    out: dict[str, dict[str, Any]] = {}
    for inst_id in sorted(core.instruments.instruments):
        inst = core.instruments.instruments[inst_id]
        base = _all_values(default_params(inst.obj, inst.role), core.settings.model)
        now = current_values(inst)
        changed = {NAME_KEYS[name]: _plain(values)
                   for name, values in sorted(now.items(), key=lambda kv: NAME_KEYS[kv[0]]) if values != base[name]}
        if changed:
            out[inst_id] = changed
    return out


def settle_rebuilds(core: SoundCore, timeout_s: float) -> bool:
    """Wait (up to ``timeout_s`` seconds) for changes still being computed in the background and take them in,
    so what is written is what was last asked for; False if some were still running."""
    deadline = time.monotonic() + timeout_s
    while core.rebuilding and time.monotonic() < deadline:
        core._finish_rebuilds()  # noqa: SLF001 - the node's own core, stopped: nothing else steps it
        time.sleep(0.01)
    return not core.rebuilding


WRITTEN_FORMATS = {".yaml": "YAML", ".yml": "YAML", ".json": "JSON"}
"""``--sound-params-out``'s extensions -> the format written, the one ``--sound-params`` reads such a file as."""


def check_params_out(path: Path, wav: Path | None = None) -> None:
    """ValueError naming ``--sound-params-out`` for a file it must not write: the take ``wav`` (``--wav``) or its
    .json (replaced by the parameters when the node stops), or a name whose extension says a format it does not
    write (a .toml file written as YAML was refused at the next start)."""
    if wav is not None:
        for taken, what in ((wav, "--wav's take"), (wav.with_name(wav.name + ".json"), "--wav's take's .json")):
            if _same_file(path, taken):
                raise ValueError(f"--sound-params-out {path} is {what} ({taken}): the parameters would replace it; "
                                 "give another file (e.g. sound.yaml)")
    if path.suffix.lower() not in WRITTEN_FORMATS:
        raise ValueError(f"--sound-params-out {path}: give a file ending in .yaml, .yml or .json (the format it is "
                         f"written in, and read back by --sound-params), not {path.suffix or 'no extension'}")


def _same_file(a: Path, b: Path) -> bool:
    """``a`` and ``b`` name the same file (symlinks and relative paths followed), existing or not."""
    try:
        if a.exists() and b.exists():
            return a.samefile(b)
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):  # a symlink loop: compared as written
        return a.absolute() == b.absolute()


def write_sound_params(core: SoundCore, path: Path) -> dict[str, dict[str, Any]]:
    """Write what differs from the defaults (:func:`changed_params`) to ``path`` (YAML for .yaml/.yml, JSON for
    .json: :data:`WRITTEN_FORMATS`; ValueError for another extension), whole or not at all; returns it."""
    kind = WRITTEN_FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(f"{path}: a sound parameters file ends in .yaml, .yml or .json")
    changed = changed_params(core)
    data = {"instruments": changed}
    if kind == "JSON":
        text = json.dumps(data, indent=2) + "\n"
    else:
        text = ("# batteur sound parameters: what differed from the kit's defaults (docs/sound.md)\n"
                + yaml.safe_dump(data, sort_keys=False))
    write_atomically(path, text.encode("utf-8"))
    return changed
