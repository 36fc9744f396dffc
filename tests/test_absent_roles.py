"""``--absent ROLE`` (``BATTEUR_ABSENT``): a misspelt role silenced nothing and said nothing; it is refused naming the
roles there are. A role given twice counts once."""

from __future__ import annotations

import pytest

from common.config import SettingsError, load_settings


def test_an_unknown_absent_role_is_refused_naming_the_roles() -> None:
    with pytest.raises(SettingsError, match=r"'grahpics'.*physics, interaction, sound, graphics"):
        load_settings({"role": "physics", "absent": ["sound", "grahpics"]})


def test_an_absent_role_given_twice_counts_once() -> None:
    settings = load_settings({"role": "physics", "absent": ["graphics", "sound", "graphics"]})
    assert settings.absent == ["graphics", "sound"]
