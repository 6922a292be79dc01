"""Fixtures for plugin authors, loaded by pytest automatically once parsel is installed.

* ``parsel_shape``: the built-in ``tiny_table`` shape (11 parts, 26 relations).
* ``parsel_register``: register a throwaway plugin for one test, unregistered after.
* ``parsel_backend``: each installed CAS backend in turn (the test runs once per backend).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest


@pytest.fixture
def parsel_shape():
    from parsel_core.examples import tiny_table

    return tiny_table()


@pytest.fixture
def parsel_register() -> Iterator[Callable[[Any], Any]]:
    from parsel_core.plugins import get_plugin_manager

    pm = get_plugin_manager()
    names: list[str] = []

    def register(plugin: Any, name: str | None = None) -> Any:
        names.append(pm.register(plugin, name=name))
        return pm

    yield register
    for name in names:
        pm.unregister(name=name)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "parsel_backend" in metafunc.fixturenames:
        from parsel_core.plugins import cas_backend_names

        metafunc.parametrize("parsel_backend", cas_backend_names(), indirect=True)


@pytest.fixture
def parsel_backend(request):
    from parsel_core.plugins import get_cas_backend

    return get_cas_backend(request.param)
