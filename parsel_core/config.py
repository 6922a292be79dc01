"""Settings: ``PARSEL_*`` environment variables over a ``parsel.toml`` file over defaults.

``parsel.toml`` is read from the current directory, or from ``$PARSEL_CONFIG``::

    [parsel]
    cas_backend = "sympy"
"""

from __future__ import annotations

import copy
import difflib
import functools
import math
import os
import warnings
from dataclasses import dataclass
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
    known = (*KNOWN_KEYS, *LIMITS)  # the limits (below) are settings too
    for key in section:
        if key in known or (str(path), key) in _warned:
            continue
        _warned.add((str(path), key))
        close = difflib.get_close_matches(key, known, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else (
            f" (known: {', '.join(KNOWN_KEYS)}, and the max_* limits in the README)")
        warnings.warn(f"{path}: [parsel] {key!r} is not a setting parsel reads and is ignored{hint}", ConfigWarning,
                      stacklevel=3)


def _warn_outside(path: Path, data: dict[str, Any]) -> None:
    """Keys and tables outside ``[parsel]`` are never read: each is warned about once, naming
    the setting it looks like (a ``relation_tolerence`` above the table, a ``[parsl]`` table)."""
    known = (*KNOWN_KEYS, *LIMITS)
    for key, value in data.items():
        if key == "parsel" or (str(path), f"/{key}") in _warned:
            continue
        _warned.add((str(path), f"/{key}"))
        if isinstance(value, dict):
            close = difflib.get_close_matches(key, ["parsel"], n=1)
            hint = "; did you mean [parsel]?" if close else "; parsel reads only the [parsel] table"
            warnings.warn(f"{path}: table [{key}] is not read and is ignored{hint}", ConfigWarning, stacklevel=3)
            continue
        close = difflib.get_close_matches(key, known, n=1)
        hint = f"; did you mean {close[0]!r} in the [parsel] table?" if close else (
            "; parsel reads only the [parsel] table")
        warnings.warn(f"{path}: {key!r} is outside the [parsel] table and is ignored{hint}", ConfigWarning,
                      stacklevel=3)


def config_path() -> Path:
    """The configuration file: ``PARSEL_CONFIG``, else ``parsel.toml`` in the working directory."""
    return Path(_config_name())


def _config_name() -> str:
    """:func:`config_path` as text (every limit reads it: no ``Path`` built on the way)."""
    return os.environ.get("PARSEL_CONFIG", "parsel.toml")


def load_settings() -> dict[str, Any]:
    """The ``[parsel]`` table of the configuration file (empty when there is none)."""
    if not os.path.isfile(_config_name()):
        if "PARSEL_CONFIG" in os.environ:
            raise ParselError(f"{config_path()}: configuration file (PARSEL_CONFIG) does not exist")
        return {}
    import tomllib  # (only where there is a file to read: most runs have none)

    path = config_path()
    try:
        data = _parsed(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ParselError(f"{path}: cannot read configuration: {exc}") from None
    section = data.get("parsel", {})
    if not isinstance(section, dict):
        raise ParselError(f"{path}: [parsel] must be a table")
    _warn_outside(path, data)
    _warn_unknown(path, section)
    return {key: copy.deepcopy(value) if isinstance(value, (dict, list)) else value for key, value in section.items()}


@functools.lru_cache(maxsize=8)
def _parsed(text: str) -> dict[str, Any]:
    """The TOML document ``text``, parsed once: limits are read where the numbers they bound
    are (each number of a ShapeAssembly file, each amount parsed), and parsing takes about
    ten times as long as reading the file again. Keyed by the text, so an edited file is
    parsed anew. Callers get copies (:func:`load_settings`)."""
    import tomllib

    return tomllib.loads(text)


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


# -- limits -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Limit:
    """A bound on input size, checked before the expensive work starts."""

    name: str
    default: float
    what: str


#: Every limit parsel enforces (README, "Limits"). Raise one with ``[parsel] <name> = N`` in
#: parsel.toml or the environment variable ``PARSEL_<NAME>``; the defaults keep one command's
#: memory to a few GiB at most (benchmarks/fuzz.py prints the peak).
LIMITS: dict[str, Limit] = {limit.name: limit for limit in (
    Limit("max_file_mb", 200, "size of a shape, program or cases file, in MiB"),
    Limit("max_parts", 1000, "parts in one shape"),
    Limit("max_detect_parts", 300, "parts of a shape whose relations are detected (it grows faster than the square)"),
    Limit("max_faces", 300_000, "triangles in one shape file (all parts together)"),
    Limit("max_vertices", 300_000, "vertices in one shape file (all parts together)"),
    Limit("max_ops", 2000, "ops in one program"),
    Limit("max_program_lines", 20_000, "lines of a text program or ShapeAssembly program"),
    Limit("max_expression_chars", 2000, "characters in one amount expression"),
    Limit("max_expression_depth", 200, "nesting depth of one amount expression (a sum of n terms is n deep)"),
    Limit("max_instances", 1000, "instances of one symmetry group after ChangeCount / ChangeDelta"),
    Limit("max_samples", 10_000, "parameter samples of a relation check (check --steps)"),
    Limit("max_sweep", 1000, "files one apply --sweep writes"),
    Limit("max_magnitude", 1e6, "absolute value of a coordinate, size or amount (in shape units)"),
)}


def limit(name: str) -> float:
    """The value of a limit: ``PARSEL_<NAME>``, else parsel.toml, else its default."""
    entry = LIMITS[name]
    env = f"PARSEL_{name.upper()}"
    raw: Any = os.environ.get(env)
    from_env = raw is not None
    if not from_env:
        raw = load_settings().get(name, entry.default)
    try:
        value = float(raw)
    except (TypeError, ValueError, OverflowError):
        value = math.nan
    if isinstance(raw, bool) or not math.isfinite(value) or value <= 0:
        where = env if from_env else f"{config_path()}: [parsel] {name}"
        raise ParselError(f"{where} must be a positive number, not {raw!r}")
    return value


def over_limit(name: str, what: str, value: float, bound: float | None = None) -> ParselError:
    """The one-line error for ``what`` exceeding limit ``name``, saying how to raise it
    (``bound``: the limit's value as it was checked; read here when not given)."""
    bound = limit(name) if bound is None else bound
    return ParselError(f"{what}: {value:g} is over the limit {name} = {bound:g} (raise it with "
                       f"PARSEL_{name.upper()} or [parsel] {name} in parsel.toml)")


def check_limit(name: str, what: str, value: float, bound: float | None = None) -> None:
    """Raise the one-line error when ``value`` exceeds limit ``name`` (``bound``: its value,
    when the caller has read it once for many values; read here when not given)."""
    bound = limit(name) if bound is None else bound
    if not value <= bound:  # also refuses NaN
        raise over_limit(name, what, value, bound)
