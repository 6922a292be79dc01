"""Where the record of a failed inference goes, so that a failed run never costs a good one.

``parsel edit ... -o OUTDIR`` writes the record of prompts and replies even when no edit
could be inferred: it is what says why. When OUTDIR does not exist yet it is created
holding only ``record.jsonl``; when it exists (a previous run's program and report), it is
left untouched and the record goes beside it, to ``OUTDIR.failed-record.jsonl``. The
error says which.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from parsel_core.errors import ParselError
from parsel_core.io import atomic_write_text


def failed_record_path(outdir: str | Path) -> Path:
    """The file beside an existing OUTDIR that receives a failed run's record."""
    target = Path(outdir)
    return target.with_name(f"{target.name}.failed-record.jsonl")


def keep_failed_record(error: ParselError, outdir: str | Path, record_text: str) -> ParselError:
    """Write a failed inference's record without touching a previous OUTDIR; returns the error
    to raise, its message extended with where the record went."""
    target = Path(outdir)
    try:
        if target.exists():
            path = failed_record_path(target)
            atomic_write_text(path, record_text)
            note = f"{outdir} is kept as it was; the record of this run is in {path}"
        else:
            staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.resolve().parent))
            atomic_write_text(staging / "record.jsonl", record_text)
            os.replace(staging, target)
            note = f"the record of this run is in {target / 'record.jsonl'}"
    except (OSError, ParselError) as exc:
        note = f"the record could not be written: {exc}"
    error.args = (f"{error} ({note})",)
    return error
