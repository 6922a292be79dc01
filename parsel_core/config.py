"""Settings: ``PARSEL_*`` environment variables over a ``parsel.toml`` file over defaults.

``parsel.toml`` is read from the current directory, or from ``$PARSEL_CONFIG``::

    [parsel]
    cas_backend = "sympy"
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError

#: The backend used when nothing is configured: the faster one in benchmarks/bench_cas.py.
PREFERRED_BACKENDS = ("symengine", "sympy")


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
    return section


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
