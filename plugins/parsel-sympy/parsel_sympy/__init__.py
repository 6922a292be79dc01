"""The sympy CAS backend for parsel: the reference backend, with a general solver."""

from __future__ import annotations

from parsel_core import hookimpl


@hookimpl
def parsel_cas_backends():
    from parsel_sympy.backend import SympyBackend

    return [SympyBackend]
