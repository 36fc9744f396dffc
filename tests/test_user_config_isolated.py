"""The suite never writes the user's own configuration (tests/conftest.py)."""

import os
from pathlib import Path

from services.interaction.node import config_path


def test_an_interaction_node_without_config_saves_into_the_runs_own_folder_not_the_users() -> None:
    saved = config_path("")
    assert saved is not None
    assert not saved.is_relative_to(Path.home() / ".config"), saved
    assert saved.is_relative_to(Path(os.environ["XDG_CONFIG_HOME"])), saved
