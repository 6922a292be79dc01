"""The symengine CAS backend for parsel: the fast one (a C++ CAS with a sympy-like API)."""

from __future__ import annotations

from parsel_core import hookimpl


@hookimpl
def parsel_cas_backends():
    from parsel_symengine.backend import SymengineBackend

    return [SymengineBackend]
