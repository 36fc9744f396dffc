"""Shared pytest setup: the network-namespace lab fixture for tests that need real networking."""

from tests.netns import netns_lab  # noqa: F401  (fixture)
