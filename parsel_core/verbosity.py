"""How much the command line says on stderr: one ``--quiet`` / ``--verbose`` pair for every verb.

Library code never prints what is not a result: it logs to the ``parsel`` logger, INFO
for notes and DEBUG for solver statistics and timings, and asks :func:`shows_progress`
whether to draw a progress display. The command line sets the level once per run
(:func:`verbosity`): ``--quiet`` keeps only warnings and errors (no progress, no notes),
the default adds notes and progress, ``--verbose`` adds the statistics. Plugins add the
pair to their verbs with :func:`add_verbosity_options`, so the flags mean the same on
every verb.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

#: The logger every part of parsel writes its notes (INFO) and statistics (DEBUG) to.
logger = logging.getLogger("parsel")

QUIET, NORMAL, VERBOSE = logging.WARNING, logging.INFO, logging.DEBUG


def add_verbosity_options(parser: argparse.ArgumentParser, *, verbose_help: str | None = None) -> None:
    """``--quiet`` and ``--verbose`` (exclusive), with help saying what --verbose adds on this verb."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true",
                       help="print results only: no progress or notes on stderr (errors and warnings still show)")
    group.add_argument("-v", "--verbose", action="store_true",
                       help=verbose_help or "also print statistics and timings on stderr")


def level_of(args: argparse.Namespace) -> int:
    """The logging level a parsed command line asks for (verbs without the options: the default)."""
    if getattr(args, "quiet", False):
        return QUIET
    if getattr(args, "verbose", False):
        return VERBOSE
    return NORMAL


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is at the time (tests and callers may swap it)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    def emit(self, record: logging.LogRecord) -> None:
        self.setStream(sys.stderr)
        super().emit(record)


@contextmanager
def verbosity(level: int) -> Iterator[None]:
    """Show the ``parsel`` logger's records at ``level`` and above on stderr for the block's duration."""
    previous_level, previous_propagate = logger.level, logger.propagate
    handler = None
    if not any(isinstance(h, _StderrHandler) for h in logger.handlers):  # one, also for a command run by another (demo)
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("parsel: %(message)s"))
        logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False  # one line per record, however the host configured logging
    try:
        yield
    finally:
        if handler is not None:
            logger.removeHandler(handler)
        logger.setLevel(previous_level)
        logger.propagate = previous_propagate


def shows_progress() -> bool:
    """Whether progress displays are wanted (not under ``--quiet``)."""
    return logger.isEnabledFor(NORMAL)


def log_solver_stats(stats: Mapping[str, Any], timings: Mapping[str, float] | None = None,
                     rejected: Iterable[str] = (), what: str = "solver") -> None:
    """``--verbose``: a solver's counters, its times per stage and why each lost relation was lost."""
    if not logger.isEnabledFor(VERBOSE):
        return
    if timings:
        logger.debug("timings: " + ", ".join(f"{k.removesuffix('_s')} {v:.3f} s" for k, v in timings.items()))
    counters = {k: v for k, v in stats.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
                and not k.endswith("_s")}
    if counters:
        logger.debug(f"{what}: " + ", ".join(f"{k.replace('_', ' ')} {v:g}" for k, v in counters.items()))
    stages = stats.get("time_s")
    if isinstance(stages, Mapping) and stages:
        logger.debug(f"{what} time: " + ", ".join(f"{k} {float(v):.3f} s" for k, v in stages.items()))
    losses = stats.get("losses") if isinstance(stats.get("losses"), Mapping) else {}
    for rid in rejected:
        reason = losses.get(rid)
        if isinstance(reason, (list, tuple)) and reason:
            text = str(reason[0]) + (f" (part {reason[1]})" if len(reason) > 1 and reason[1] else "")
        else:
            text = "no reason recorded"
        logger.debug(f"lost: {rid}: {text}")
