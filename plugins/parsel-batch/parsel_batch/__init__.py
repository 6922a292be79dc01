"""Evaluation and batch runs for parsel: ParSEL's metrics, ``parsel eval`` and ``parsel batch``.

* :mod:`parsel_batch.metrics`: J(prog), D(geo), %Rel, Acc(SE), Acc(R), J(T), Match
  (reference section 7), as pure functions.
* :mod:`parsel_batch.cases`: the case format (one JSON object per line).
* :mod:`parsel_batch.runner`: one case, start to finish, failures included.
* :mod:`parsel_batch.batch`: many cases, committed as they finish, resumable, on local
  processes or a Dask cluster.
"""

from __future__ import annotations

from parsel_core import hookimpl


@hookimpl
def parsel_register_commands(subparsers):
    from parsel_batch.commands import register

    register(subparsers)
