"""Batch runs: many cases, results written as they finish, resumable, local or on Dask.

Output layout (docs/evaluation.md)::

    OUTDIR/results.jsonl            one record per finished case (completion order)
    OUTDIR/<case id>/result.json    the record; its presence marks the case done
    OUTDIR/<case id>/program.json   the program (ok cases)
    OUTDIR/<case id>/report.json    the relation report (ok cases)
    OUTDIR/<case id>/error.txt      the full traceback (failed cases)

Durability: workers only compute; this process writes. A case's folder is written in
a hidden staging folder and renamed into place, so it appears whole or not at all; its
record is then appended to results.jsonl in one ``write`` and flushed to disk. A run
killed at any point loses only the cases in flight. On start, a run finds the finished
cases by their folders, skips them, and repairs results.jsonl so that it holds exactly
one record per finished case (a record whose append was cut off is re-added from the
case's result.json; a truncated last line is dropped).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import uuid
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from parsel_batch.cases import Case
from parsel_batch.runner import CaseOutcome, RunDefaults, deterministic, error_summary, run_case
from parsel_core.blas import THREAD_VARIABLES
from parsel_core.errors import ParselError

RESULTS = "results.jsonl"
RESULT = "result.json"
STAGING_PREFIX = ".staging-"


# -- the output folder --------------------------------------------------------------------


def _fsync_dir(path: Path) -> None:
    """Make a rename durable (POSIX); a no-op where directories cannot be opened."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _line(record: dict[str, Any]) -> str:
    return json.dumps(record, sort_keys=False, separators=(",", ":")) + "\n"


@dataclass
class OutputDir:
    """The batch's OUTDIR: finished cases, the results log, and atomic commits of new ones."""

    path: Path
    done: dict[str, dict[str, Any]] = field(default_factory=dict)

    @classmethod
    def open(cls, path: str | Path, cases: Sequence[Case], retry_failed: bool = False) -> OutputDir:
        """Create or reopen OUTDIR, find finished cases and repair results.jsonl."""
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise ParselError(f"{path}: exists and is not a directory")
        if path.is_dir() and not (path / RESULTS).exists():
            others = sorted(e.name for e in path.iterdir() if not e.name.startswith(STAGING_PREFIX))
            if others and not any((path / name / RESULT).is_file() for name in others):
                # not a batch OUTDIR (nor one killed before its first log line): not this run's to repair
                raise ParselError(f"{path}: holds files that are not a batch's results (e.g. {others[0]!r}); "
                                  "choose an empty or new folder")
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ParselError(f"{path}: cannot create output directory: {exc.strerror}") from None
        for stale in path.glob(f"{STAGING_PREFIX}*"):  # a killed run's half-written folders
            shutil.rmtree(stale, ignore_errors=True)
        out = cls(path)
        for case in cases:
            marker = path / case.id / RESULT
            if not marker.is_file():
                continue
            try:
                record = json.loads(marker.read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError):
                continue  # unreadable: run the case again
            if retry_failed and record.get("status") != "ok":
                continue
            out.done[case.id] = record
        out._repair_results({c.id for c in cases})
        return out

    @property
    def results_path(self) -> Path:
        return self.path / RESULTS

    def _repair_results(self, known: set[str]) -> None:
        """Exactly one line per finished case, in the order they were first logged.

        Lines of cases not in this cases file (``known``) are kept as they are: the log
        is not this run's to prune.
        """
        kept: list[str] = []
        logged: set[str] = set()
        original = ""
        if self.results_path.exists():
            original = self.results_path.read_text(encoding="utf-8")
            for raw in original.splitlines(keepends=True):
                try:
                    record = json.loads(raw)
                except json.JSONDecodeError:
                    continue  # an append cut off by a kill
                case_id = record.get("id") if isinstance(record, dict) else None
                if not isinstance(case_id, str) or case_id in logged or not raw.endswith("\n"):
                    continue
                if case_id in self.done or case_id not in known:
                    logged.add(case_id)
                    kept.append(raw)
        for case_id, record in self.done.items():
            if case_id not in logged:
                kept.append(_line({**record, "elapsed_s": record.get("elapsed_s")}))
        text = "".join(kept)
        if text != original:
            from parsel_core.io import atomic_write_text

            atomic_write_text(self.results_path, text)

    def commit(self, outcome: CaseOutcome) -> None:
        """Write the case's folder atomically, then log its record (one append, flushed)."""
        record = outcome.record
        staging = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{outcome.id}-", dir=self.path))
        try:
            for name, text in sorted(outcome.files.items()):
                (staging / name).write_text(text, encoding="utf-8")
            marker = deterministic(record)
            (staging / RESULT).write_text(json.dumps(marker, indent=1) + "\n", encoding="utf-8")
            for name in os.listdir(staging):
                with open(staging / name, "rb") as handle:
                    os.fsync(handle.fileno())
            target = self.path / outcome.id
            if target.exists():  # a failed case being retried
                trash = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}old-{outcome.id}-", dir=self.path))
                os.replace(target, trash / "previous")
                os.replace(staging, target)
                shutil.rmtree(trash, ignore_errors=True)
            else:
                os.replace(staging, target)
            _fsync_dir(self.path)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
        fd = os.open(self.results_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            data = _line(record).encode("utf-8")
            written = os.write(fd, data)
            while written < len(data):  # a short write is resumed, never duplicated
                written += os.write(fd, data[written:])
            os.fsync(fd)
        finally:
            os.close(fd)
        self.done[outcome.id] = record


def read_results(path: str | Path) -> list[dict[str, Any]]:
    """The records of a results.jsonl (or of OUTDIR), skipping a cut-off last line."""
    path = Path(path)
    if path.is_dir():
        path = path / RESULTS
    records = []
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ParselError(f"{path}: cannot read results: {exc.strerror}") from None
    for raw in text.splitlines():
        try:
            records.append(json.loads(raw))
        except json.JSONDecodeError:
            continue
    return records


# -- executors ----------------------------------------------------------------------------


def _failure(case: Case, exc: BaseException, where: str) -> CaseOutcome:
    """A record for a case whose worker, not the case, failed (a dead process, a lost Dask worker)."""
    record = {"id": case.id, "kind": case.kind, "mode": case.mode, "request": case.request, "status": "failed",
              "error": {**error_summary(exc), "where": where}, "elapsed_s": None}
    return CaseOutcome(case.id, record, {"error.txt": f"{where}: {type(exc).__name__}: {exc}\n"})


def run_serial(cases: Sequence[Case], defaults: RunDefaults) -> Iterator[CaseOutcome]:
    """In this process, one after the other (``--workers 0``): no pickling, easy to debug."""
    for case in cases:
        yield run_case(case, defaults)


def die_with_parent(parent: int) -> None:
    """Make this worker process end when the batch process that started it ends, however it ends.

    On Linux the kernel sends SIGKILL when the parent dies (``PR_SET_PDEATHSIG``); a
    watchdog thread covers other systems and the instant before the call. Ctrl-C is left
    to the parent, which stops its workers itself, so workers print nothing on SIGINT.
    """
    import signal
    import threading
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1: PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    if os.getppid() != parent:  # the parent died before the call above
        os._exit(1)
    threading.Thread(target=watch, name="parsel-parent-watch", daemon=True).start()


def start_worker(defaults: RunDefaults, parent: int) -> None:
    """A local worker's initializer: tie its life to the parent's, then warm up."""
    die_with_parent(parent)
    warm_up(defaults)


def warm_up(defaults: RunDefaults) -> None:
    """Load the plugins and the CAS backend once per worker, so the first case's time is its own."""
    from parsel_core.plugins import get_cas_backend, solvers

    try:
        solvers()
        get_cas_backend(defaults.backend)
    except Exception:  # a warm-up only: whatever fails here is reported by the cases it affects
        pass


def run_local(cases: Sequence[Case], defaults: RunDefaults, workers: int) -> Iterator[CaseOutcome]:
    """On ``workers`` local processes (spawned, so no lock or thread is inherited mid-use).

    At most ``workers`` cases are in flight, so a killed run loses at most that many and
    a pool that breaks has few suspects. If a worker process dies (killed, out of
    memory, a crash in native code) the pool breaks and every case in flight fails with
    it; those cases then run one at a time on a fresh pool, so a death can only be the
    running case's own, and that case is recorded as failed. The others go on.
    """
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    with _single_threaded_children():
        yield from _run_pools(cases, defaults, workers, context)


@contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Worker processes start with one BLAS/OpenMP thread each (unless the user set a size).

    One process per core already uses every core; letting each also start a thread per
    core oversubscribes the machine and makes N workers slower than one.
    """
    added = [name for name in THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _run_pools(cases: Sequence[Case], defaults: RunDefaults, workers: int, context: Any) -> Iterator[CaseOutcome]:
    queue = deque(cases)
    suspects: deque[Case] = deque()  # in flight when a pool broke
    while queue or suspects:
        executor = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=start_worker,
                                       initargs=(defaults, os.getpid()))
        finished_normally = False
        try:
            broken = False
            while suspects and not broken:
                case = suspects.popleft()
                try:
                    outcome = executor.submit(run_case, case, defaults).result()
                except BrokenProcessPool as exc:
                    outcome = _failure(case, exc, "local worker process died while running this case")
                    broken = True
                yield outcome
            in_flight: dict[Future, Case] = {}
            while not broken and (queue or in_flight):
                while queue and len(in_flight) < workers:
                    case = queue.popleft()
                    try:
                        in_flight[executor.submit(run_case, case, defaults)] = case
                    except BrokenProcessPool:  # the pool broke since the last wait
                        queue.appendleft(case)  # it never started, so it is no suspect
                        broken = True
                        break
                if not broken:
                    finished, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                    broken = any(isinstance(f.exception(), BrokenProcessPool) for f in finished)
                if broken:
                    finished = wait(in_flight).done  # a broken pool fails every future at once
                for future in sorted(finished, key=lambda f: in_flight[f].line):
                    case = in_flight.pop(future)
                    exc = future.exception()
                    if isinstance(exc, BrokenProcessPool):
                        suspects.append(case)
                    elif exc is not None:  # pickling problems and the like: the case's failure
                        yield _failure(case, exc, "local executor")
                    else:
                        yield future.result()
            finished_normally = True
        finally:
            # Interrupted (Ctrl-C, the consumer stopped): stop the cases in flight, do not wait for them.
            if not finished_normally:
                for process in list(getattr(executor, "_processes", {}).values()):
                    process.terminate()
            executor.shutdown(wait=finished_normally, cancel_futures=True)


def check_dask_address(address: str) -> None:
    """``[tcp://]HOST:PORT`` with a port from 1 to 65535, refused in one line before any connection is tried."""
    import re

    if address.startswith("inproc://"):  # a cluster in this process (tests)
        return
    match = re.fullmatch(r"(?:(?:tcp|tls|ucx|ws|wss)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})", address)
    if not match or not 1 <= int(match[2]) <= 65535:
        raise ParselError(f"--dask {address!r}: expected a scheduler address like tcp://HOST:8786")


def run_dask(cases: Sequence[Case], defaults: RunDefaults, address: str) -> Iterator[CaseOutcome]:
    """On a Dask distributed cluster at ``address`` (an existing scheduler).

    Every case is one task; workers must have parsel and its plugins installed and see
    the shape files at the paths the cases name (bundled examples always work). Results
    come back to this process, which writes them, so OUTDIR need not be shared. A task
    lost with its worker is retried by the scheduler; one that still fails is recorded.
    """
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise ParselError(f"--dask needs the Dask distributed client: pip install \"dask[distributed]\" ({exc})") \
            from None
    check_dask_address(address)
    try:
        client = Client(address, timeout=30)
    except (OSError, TimeoutError) as exc:
        raise ParselError(f"--dask {address}: cannot reach the scheduler: {exc}") from None
    token = uuid.uuid4().hex[:8]
    try:
        futures = {}
        for case in cases:
            future = client.submit(run_case, case, defaults, key=f"parsel-case-{case.id}-{token}",
                                   pure=False, retries=1)
            futures[future.key] = (future, case)
        for future in as_completed([f for f, _ in futures.values()]):
            case = futures[future.key][1]
            try:
                outcome = future.result()
            except Exception as exc:  # the worker, not the case, failed
                outcome = _failure(case, exc, f"dask task {future.key}")
            future.release()
            yield outcome
    finally:
        client.close()


# -- progress -----------------------------------------------------------------------------


def progress_bar(total: int, enabled: bool, stream: TextIO | None = None) -> Any:
    """The core's progress display (parsel_core.progress): a bar on a terminal, lines elsewhere."""
    from parsel_core.progress import progress

    return progress(total, "cases", unit="case", enabled=enabled, stream=stream)


def log_outcome(outcome: CaseOutcome) -> None:
    """``--verbose``: one line per finished case (status, ops, time, the error's first line)."""
    from parsel_core.verbosity import VERBOSE, logger

    if not logger.isEnabledFor(VERBOSE):
        return
    record = outcome.record
    elapsed = record.get("elapsed_s")
    error = record.get("error") or {}
    logger.debug(f"case {record.get('id')}: {record.get('status')}, {record.get('ops', '-')} ops"
                 + (f", {elapsed:.2f} s" if isinstance(elapsed, (int, float)) else "")
                 + (f"; {error.get('type')}: {error.get('message')}" if error else ""))


# -- the batch ----------------------------------------------------------------------------


@dataclass
class BatchSummary:
    """What a batch run did: cases run now, skipped as already done, and failures overall."""

    total: int
    ran: int
    skipped: int
    failed_now: int
    records: list[dict[str, Any]]

    @property
    def failed(self) -> int:
        return sum(r.get("status") != "ok" for r in self.records)


def run_cases(cases: Sequence[Case], defaults: RunDefaults, workers: int = 0,
              dask: str | None = None) -> Iterator[CaseOutcome]:
    """Outcomes as they finish, on the chosen executor."""
    if dask:
        return run_dask(cases, defaults, dask)
    if workers <= 0 or len(cases) == 0:
        return run_serial(cases, defaults)
    return run_local(cases, defaults, min(workers, len(cases)))


def run_batch(cases: Sequence[Case], outdir: str | Path, *, workers: int = 0, dask: str | None = None,
              defaults: RunDefaults | None = None, retry_failed: bool = False, progress: bool = True,
              on_outcome: Callable[[CaseOutcome], None] | None = None) -> BatchSummary:
    """Run the cases not yet done in ``outdir``; each is committed as soon as it finishes."""
    defaults = defaults or RunDefaults()
    out = OutputDir.open(outdir, cases, retry_failed)
    todo = [c for c in cases if c.id not in out.done]
    skipped = len(cases) - len(todo)
    bar = progress_bar(len(todo), progress)
    failed_now = 0
    try:
        for outcome in run_cases(todo, defaults, workers, dask):
            out.commit(outcome)
            log_outcome(outcome)
            failed_now += not outcome.ok
            if on_outcome is not None:
                on_outcome(outcome)
            bar.set_postfix_str(f"failed {failed_now}" if failed_now else "")
            bar.update(1)
    finally:
        bar.close()
    records = [out.done[c.id] for c in cases if c.id in out.done]
    return BatchSummary(len(cases), len(todo), skipped, failed_now, records)


def ordered(records: Iterable[dict[str, Any]], cases: Sequence[Case]) -> list[dict[str, Any]]:
    """Records in the cases file's order (results.jsonl is in completion order)."""
    by_id = {r["id"]: r for r in records}
    return [by_id[c.id] for c in cases if c.id in by_id]
