"""Fuzz every service core's handler with every message model, and audit the files they touch.

hypothesis builds valid messages of every registered model (values anywhere in their declared
ranges, strings from their choices or arbitrary text, including paths such as ``../../etc/passwd``)
and hands each to the physics, interaction, sound and graphics cores, as the node would. A core
may reject a message (a reply, a counter, a log line) but must not raise, and no message may
make it open a file outside the directories it was configured with: a Python audit hook records
every ``open`` during the handler calls.
"""

from __future__ import annotations

import atexit
import shutil
import string
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from common.messages import REGISTRY, OscMessage, WireField, WireKind

pytestmark = pytest.mark.timeout(300)

ALLOWED_DIR = Path(tempfile.mkdtemp(prefix="batteur-fuzz-"))
"""The only directory the cores under test are configured with (for saving); removed when the run ends."""
atexit.register(shutil.rmtree, ALLOWED_DIR, ignore_errors=True)
_opens: list[tuple[str, str]] = []
"""(path, "role address") of every file opened by a handler."""
_auditing = [""]


def _audit(event: str, args: tuple[Any, ...]) -> None:
    try:
        who = _auditing[0]
    except TypeError:  # interpreter shutdown
        return
    if who and event == "open" and args and isinstance(args[0], (str, bytes, Path)):
        _opens.append((str(args[0]), who))


sys.addaudithook(_audit)

PATHS = st.sampled_from(["/etc/passwd", "../../../../etc/shadow", "/tmp/batteur-evil.yaml", "~/.ssh/id_rsa",
                         "default", "snare", "x" * 300, "", "/dev/zero", "C:\\\\windows", "kit.yaml", "../kits/x"])
TEXT = st.one_of(PATHS, st.text(alphabet=string.printable, max_size=40))


def field_strategy(f: WireField) -> st.SearchStrategy[Any]:
    if f.choices:
        values = [int(c) for c in f.choices] if f.kind is WireKind.INT else list(f.choices)
        base: st.SearchStrategy[Any] = st.sampled_from(values)
    elif f.kind is WireKind.STR:
        base = TEXT
    elif f.kind is WireKind.INT:
        lo = int(f.minimum) if f.minimum is not None else -(2**31)
        hi = int(f.maximum) if f.maximum is not None else 2**31 - 1
        base = st.integers(max(lo, -(2**31)), min(hi, 2**31 - 1))
    else:
        lo_f = f.minimum if f.minimum is not None else -1e6
        hi_f = f.maximum if f.maximum is not None else 1e6
        if f.kind is WireKind.TIME:
            lo_f, hi_f = max(lo_f, -1.0), min(hi_f, 1e5)
        base = st.floats(lo_f, hi_f, allow_nan=False, allow_infinity=False)
    if f.variadic:
        return st.lists(base, max_size=130).map(tuple)
    return base


def message_strategy() -> st.SearchStrategy[OscMessage]:
    strategies: list[st.SearchStrategy[Any]] = []
    for model in REGISTRY:
        fields = {f.name: field_strategy(f) for f in model.wire_fields()}
        strategies.append(st.fixed_dictionaries(fields).map(_builder(model)).filter(lambda m: m is not None))
    return st.one_of(strategies)


def _builder(model: type[OscMessage]) -> Callable[[dict[str, Any]], OscMessage | None]:
    def build(values: dict[str, Any]) -> OscMessage | None:
        try:
            return model.model_validate(values)
        except ValueError:
            return None  # e.g. an id pattern the text does not meet: the decoder would drop it

    return build


def make_cores() -> dict[str, Any]:
    from common.kit import load_kit
    from services.graphics.core import GraphicsCore
    from services.interaction.config import FileConfigStore, InteractionConfig
    from services.interaction.core import InteractionCore
    from services.physics.core import PhysicsCore, PhysicsSettings
    from services.sound.core import SoundCore, SoundSettings

    kit = load_kit("default")
    return {
        "physics": PhysicsCore(PhysicsSettings(scene="strike", mode="live")),
        "interaction": InteractionCore(kit=kit, config=InteractionConfig(),
                                       store=FileConfigStore(ALLOWED_DIR / "interaction.yaml")),
        "sound": SoundCore(SoundSettings(use_pyo=False), kit),
        "graphics": GraphicsCore(),
    }


CORES: dict[str, Any] = {}
FAILURES: list[str] = []


@settings(max_examples=3_000, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(message=message_strategy(), now=st.floats(0, 1e4, allow_nan=False))
def _fuzz_one(message: OscMessage, now: float) -> None:
    for role, core in CORES.items():
        _auditing[0] = f"{role} {message.ADDRESS}"
        try:
            core.handle(message, now, "127.0.0.1:9")
        except Exception as exc:
            FAILURES.append(f"{role}: {message!r}: {type(exc).__name__}: {exc}")
        finally:
            _auditing[0] = ""


def _outside(path: str) -> bool:
    resolved = Path(path).expanduser().resolve()
    allowed = [ALLOWED_DIR.resolve(), Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve(),
               Path(__file__).resolve().parents[1]]  # the code's own data (kits, samples, models)
    return not any(resolved == a or a in resolved.parents for a in allowed)


def _run_fuzz() -> None:
    if not CORES:
        CORES.update(make_cores())
        _opens.clear()
        FAILURES.clear()
        _fuzz_one()


def test_every_handler_takes_every_message_without_raising() -> None:
    _run_fuzz()
    assert FAILURES == [], "\n".join(FAILURES[:20])


KNOWN_OPENERS = {"interaction /batteur/interaction/config/load"}
"""Handlers that take a file name in the message (checked on their own below)."""


def test_no_handler_opens_files_outside_its_directories() -> None:
    _run_fuzz()
    outside = sorted({(who, p) for p, who in _opens if _outside(p) and who not in KNOWN_OPENERS})
    assert outside == [], f"handlers opened files outside their directories: {outside}"


def test_config_load_stays_in_its_directory() -> None:
    _run_fuzz()
    outside = sorted({(who, p) for p, who in _opens if _outside(p) and who in KNOWN_OPENERS})
    assert outside == [], f"opened outside its directory: {outside}"
