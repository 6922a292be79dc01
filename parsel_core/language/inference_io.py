"""Where the record of a failed inference goes, so that a failed run never costs a good one.

``parsel edit ... -o OUTDIR`` keeps the record of prompts and replies even when no edit
could be inferred: it is what says why. It goes *beside* OUTDIR, to
``OUTDIR.failed-record.jsonl``, and never into it: an existing OUTDIR (a previous run's
program and report) is left untouched and a missing one is not created, so a failed run
leaves no partial output. The error says where the record went.
"""

from __future__ import annotations

from pathlib import Path

from parsel_core.errors import ParselError
from parsel_core.io import atomic_write_text


def failed_record_path(outdir: str | Path) -> Path:
    """The file beside OUTDIR that receives a failed run's record."""
    target = Path(outdir)
    return target.with_name(f"{target.name}.failed-record.jsonl")


def keep_failed_record(error: ParselError, outdir: str | Path, record_text: str) -> ParselError:
    """Write a failed inference's record beside OUTDIR, never touching OUTDIR; returns the
    error to raise, its message extended with where the record went."""
    target = Path(outdir)
    path = failed_record_path(target)
    try:
        atomic_write_text(path, record_text)
        kept = f"{outdir} is kept as it was" if target.exists() else f"no {outdir} is written"
        note = f"{kept}; the record of this run is in {path}"
    except (OSError, ParselError) as exc:
        note = f"the record could not be written: {exc}"
    error.args = (f"{error} ({note})",)
    return error
