"""Shared fixtures live in parsel_core.pytest_plugin (so plugin authors get them too)."""
