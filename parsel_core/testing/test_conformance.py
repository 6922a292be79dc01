"""The conformance kit as a pytest test: one parametrized case per check of each plugin.

Run it on an installed plugin with
``python -m pytest --pyargs parsel_core.testing.test_conformance --parsel-plugin NAME``, or
import ``test_parsel_conformance`` into a test module that sets ``PARSEL_PLUGINS``.
The cases come from ``parsel_core.pytest_plugin`` (``pytest_generate_tests``).
"""

from __future__ import annotations

import pytest

from parsel_core.testing.kit import Check, NotApplicable


def test_parsel_conformance(parsel_check: Check) -> None:
    try:
        parsel_check.run()
    except NotApplicable as exc:
        pytest.skip(str(exc))
