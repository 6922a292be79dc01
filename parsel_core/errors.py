"""Errors that reach the user as one line and exit status 2."""

from __future__ import annotations


class ParselError(Exception):
    """Bad input: the message names the file, part or field at fault.

    The command line prints ``parsel: error: <message>`` and exits with status 2,
    so every message must fit on one line and say what to fix.
    """

    exit_code = 2

    def __str__(self) -> str:
        return " ".join(super().__str__().split())


class UnknownPartError(ParselError):
    """An op, relation or hint names a part the shape does not have."""


class ProgramFormatError(ParselError):
    """A program file or program text that does not parse."""


class ParameterRangeError(ParselError):
    """A parameter value outside its declared range [lo, hi]."""


class UnknownPluginError(ParselError):
    """A backend, operator, loader or provider name nobody registered."""
