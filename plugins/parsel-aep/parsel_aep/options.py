"""AEP's options: the ablation switches of the paper's table 4 and the numeric settings.

They arrive from Python (``solver_options``), batch files (JSON) and the command line
(``parsel edit --solver-option NAME=VALUE``), so each is checked here, once, with an
error naming the option: a ``"0"`` for ``joint`` or a ``samples`` of 1 would otherwise
fail deep inside a solve, or quietly give a program checked at a single sample.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from parsel_core.errors import ParselError

#: Bounds of the whole-number options (inclusive).
SAMPLES_RANGE = (3, 1000)
PASSES_RANGE = (0, 10)


@dataclass(frozen=True)
class AEPOptions:
    """Switches for ablations (paper table 4) and numeric settings."""

    nhbd: bool = True
    breaking: bool = True
    tau: float | None = None
    tau_max: float = 1.0
    #: Parameter values every relation and closed form is checked at, 0 to tau.
    samples: int = 17
    relative_tolerance: float = 1e-4
    backend: str | None = None
    #: Passes of the second look at parts decided too early (0 turns it off).
    repair: int = 2
    #: Whether that second look may also take breaking-edits that lower the total error.
    repair_breaking: bool = False
    #: Rings of neighbours around the broken relations solved jointly (cluster.py; 0: off).
    joint: int = 3

    def __post_init__(self) -> None:
        for name in ("nhbd", "breaking", "repair_breaking"):
            _check(name, getattr(self, name), isinstance(getattr(self, name), bool), "true or false")
        _check("tau", self.tau, self.tau is None or _positive(self.tau), "a positive number (or none: automatic)")
        _check("tau_max", self.tau_max, _positive(self.tau_max), "a positive number")
        _check("relative_tolerance", self.relative_tolerance,
               _positive(self.relative_tolerance) and self.relative_tolerance < 1, "a number between 0 and 1")
        _check("backend", self.backend, self.backend is None or isinstance(self.backend, str), "a backend name")
        _check_whole("samples", self.samples, SAMPLES_RANGE)
        _check_whole("repair", self.repair, PASSES_RANGE)
        _check_whole("joint", self.joint, PASSES_RANGE)

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any]) -> AEPOptions:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ParselError(f"unknown AEP option(s): {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        return cls(**options)


def _positive(value: Any) -> bool:
    """A finite number above zero (``True`` is not a number here)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def _check_whole(name: str, value: Any, bounds: tuple[int, int]) -> None:
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool) and bounds[0] <= value <= bounds[1]
    _check(name, value, ok, f"a whole number from {bounds[0]} to {bounds[1]}")


def _check(name: str, value: Any, ok: bool, expected: str) -> None:
    if not ok:
        raise ParselError(f"AEP option {name}: expected {expected}, got {value!r}")
