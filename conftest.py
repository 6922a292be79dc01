"""Fixtures for every test of this repository (the core's and the bundled plugins').

Fixtures plugin authors can use too live in ``parsel_core.pytest_plugin``.
"""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _no_progress_unless_asked(monkeypatch):
    """Progress and "working" lines appear after 2 s of work, so on a slow or busy machine a
    test of a command's stderr would see them and on a fast one not: here they wait an hour.
    Tests of progress set ``parsel_core.progress.DELAY`` themselves (to 0)."""
    from parsel_core import progress

    monkeypatch.setattr(progress, "DELAY", 3600.0)
