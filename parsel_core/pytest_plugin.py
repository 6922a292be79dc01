"""Fixtures for plugin authors, loaded by pytest automatically once parsel is installed.

* ``parsel_shape``: the built-in ``tiny_table`` shape (11 parts, 26 relations).
* ``parsel_register``: register a throwaway plugin for one test, unregistered after.
* ``parsel_backend``: each installed CAS backend in turn (the test runs once per backend).
* ``parsel_check``: the conformance kit's checks (:mod:`parsel_core.testing`) of the plugins
  named by ``--parsel-plugin NAME`` (repeatable) or by the test module's ``PARSEL_PLUGINS``.
* ``parsel_fresh_python``: run code in a new interpreter and read what it printed (start-up
  checks: "importing the plugin does not import trimesh").
"""

from __future__ import annotations

import subprocess
import sys
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


@pytest.fixture
def parsel_fresh_python() -> Callable[[str], str]:
    """``run(code)``: Python ``code`` run in a new interpreter, where nothing is imported yet
    (what a command's start-up pays is then visible in ``sys.modules``); returns what it
    printed, and fails the test with its error output if it exits non-zero."""

    def run(code: str) -> str:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
        if done.returncode != 0:
            pytest.fail(f"python -c exited with {done.returncode}: {done.stderr.strip()}", pytrace=False)
        return done.stdout

    return run


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.getgroup("parsel").addoption(
        "--parsel-plugin", action="append", default=[], metavar="NAME",
        help="run the parsel conformance kit on the installed plugin NAME (its entry-point name; repeatable)")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "parsel_check" in metafunc.fixturenames:
        from parsel_core.testing import plugin_checks

        names = metafunc.config.getoption("parsel_plugin") or list(getattr(metafunc.module, "PARSEL_PLUGINS", []))
        checks = [check for name in names for check in plugin_checks(name)]
        metafunc.parametrize("parsel_check", checks, ids=[check.id for check in checks])
    if "parsel_backend" in metafunc.fixturenames:
        from parsel_core.plugins import cas_backend_names

        metafunc.parametrize("parsel_backend", cas_backend_names(), indirect=True)


@pytest.fixture
def parsel_backend(request):
    from parsel_core.plugins import get_cas_backend

    return get_cas_backend(request.param)
