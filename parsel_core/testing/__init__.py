"""The conformance kit for plugin packages: checks that a plugin honours parsel's interfaces.

A plugin package's CI runs::

    python -m pytest --pyargs parsel_core.testing.test_conformance --parsel-plugin NAME

(``NAME`` is its entry-point name) or keeps a test module that re-uses the kit's test::

    from parsel_core.testing.test_conformance import test_parsel_conformance  # noqa: F401
    PARSEL_PLUGINS = ["taper"]

Either way every hook the plugin implements is checked (:func:`plugin_checks`): hooks
return the right types; each edit operator agrees between the numeric path and the
symbolic path of every installed CAS backend (batched and per sample, whole part and
feature), with its JavaScript point map where the page can build one, and with its
mirror image under a reflection; its bad fields and unknown operands give one-line
``ParselError``s naming the op; its programs round-trip through JSON and text. Loaders
refuse a bad file with a ``ParselError`` naming it, exporters write through a temporary
file, solvers keep the seed edit, providers have the ``complete`` signature, and
importing the plugin opens no network connection. The core's own plugins run the same
checks in ``make test`` (``tests/test_conformance_kit.py``).
"""

from __future__ import annotations

from parsel_core.testing.kit import Check, check_plugin, plugin_checks

__all__ = ["Check", "check_plugin", "plugin_checks"]
