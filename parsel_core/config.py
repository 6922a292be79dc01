"""Settings: ``PARSEL_*`` environment variables over a ``parsel.toml`` file over defaults.

``parsel.toml`` is read from the current directory, or from ``$PARSEL_CONFIG``::

    [parsel]
    cas_backend = "sympy"
"""

from __future__ import annotations

import difflib
import os
import tomllib
import warnings
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError

#: The backend used when nothing is configured: the faster one in benchmarks/bench_cas.py.
PREFERRED_BACKENDS = ("symengine", "sympy")
#: The keys of the ``[parsel]`` table parsel reads; any other is warned about once.
KNOWN_KEYS = ("cas_backend", "relation_tolerance")


class ConfigWarning(UserWarning):
    """A setting parsel does not know (a misspelled key, say): it is ignored."""


_warned: set[tuple[str, str]] = set()


def _warn_unknown(path: Path, section: dict[str, Any]) -> None:
    for key in section:
        if key in KNOWN_KEYS or (str(path), key) in _warned:
            continue
        _warned.add((str(path), key))
        close = difflib.get_close_matches(key, KNOWN_KEYS, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(KNOWN_KEYS)})"
        warnings.warn(f"{path}: [parsel] {key!r} is not a setting parsel reads and is ignored{hint}", ConfigWarning,
                      stacklevel=3)


def config_path() -> Path:
    """The configuration file: ``PARSEL_CONFIG``, else ``parsel.toml`` in the working directory."""
    return Path(os.environ.get("PARSEL_CONFIG", "parsel.toml"))


def load_settings() -> dict[str, Any]:
    """The ``[parsel]`` table of the configuration file (empty when there is none)."""
    path = config_path()
    if not path.is_file():
        if "PARSEL_CONFIG" in os.environ:
            raise ParselError(f"{path}: configuration file (PARSEL_CONFIG) does not exist")
        return {}
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ParselError(f"{path}: cannot read configuration: {exc}") from None
    section = data.get("parsel", {})
    if not isinstance(section, dict):
        raise ParselError(f"{path}: [parsel] must be a table")
    _warn_unknown(path, section)
    return section


def backend_source() -> str:
    """Where the configured backend name comes from, for error messages."""
    if os.environ.get("PARSEL_CAS_BACKEND"):
        return "$PARSEL_CAS_BACKEND"
    return f"cas_backend in {config_path()}"


def default_backend_name(installed: list[str]) -> str:
    """The configured backend, else the preferred installed one."""
    name = os.environ.get("PARSEL_CAS_BACKEND") or load_settings().get("cas_backend")
    if name:
        return str(name)
    for candidate in PREFERRED_BACKENDS:
        if candidate in installed:
            return candidate
    if installed:
        return sorted(installed)[0]
    raise ParselError("no CAS backend is installed (install parsel-sympy or parsel-symengine)")
