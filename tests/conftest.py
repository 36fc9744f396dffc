"""Shared pytest setup: the network-namespace lab fixture for tests that need real networking, and a per-run user
configuration folder."""

import os
import shutil
import tempfile

import pytest

from tests.netns import netns_lab  # noqa: F401  (fixture)

_CONFIG_HOME: str | None = None


def pytest_configure(config: pytest.Config) -> None:
    """Point XDG_CONFIG_HOME at a folder of this run's own, inherited by every node a test starts: an interaction
    node without ``--config`` saves its routes in ``$XDG_CONFIG_HOME/batteur/interaction.yaml``, which was the
    user's own file (a route a test added there reached every later default rig on the machine)."""
    global _CONFIG_HOME
    _CONFIG_HOME = tempfile.mkdtemp(prefix="batteur-tests-config-")
    os.environ["XDG_CONFIG_HOME"] = _CONFIG_HOME


def pytest_unconfigure(config: pytest.Config) -> None:
    if _CONFIG_HOME is not None:
        shutil.rmtree(_CONFIG_HOME, ignore_errors=True)
