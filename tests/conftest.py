"""Shared fixtures live in parsel_core.pytest_plugin (so plugin authors get them too)."""

import pytest


@pytest.fixture(autouse=True, scope="session")
def _own_cache_dir(tmp_path_factory):
    """The core's tests keep parsel's caches (entrypoints.py) in a folder of their own,
    not in the user's: they put temporary folders on the import path."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PARSEL_CACHE_DIR", str(tmp_path_factory.mktemp("parsel-cache")))
        yield
