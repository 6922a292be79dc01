"""``parsel eval`` and ``parsel batch``: the command-line side of parsel-batch."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from typing import Any

from parsel_batch.batch import check_dask_address, log_outcome, ordered, read_results, run_batch, run_cases
from parsel_batch.cases import Case, read_cases
from parsel_batch.metrics import summarise
from parsel_batch.runner import RunDefaults
from parsel_core.cli import bounded_int
from parsel_core.errors import ParselError
from parsel_core.verbosity import add_verbosity_options, shows_progress

EVAL_FORMAT = "parsel.eval"
EVAL_VERSION = 1
#: Exit status when every case ran but some failed (bad input is 2, as everywhere in parsel).
EXIT_FAILED_CASES = 1
EXIT_INTERRUPTED = 130
#: The most local worker processes ``--workers`` takes.
MAX_WORKERS = 256


def available_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _fmt(value: Any, kind: str) -> str:
    if value is None:
        return "-"
    if kind == "bool":
        return "yes" if value else "no"
    if kind == "percent":
        return f"{100 * value:.1f}"
    if kind == "distance":
        return f"{value:.3f}"
    return f"{value:.2f}"


COLUMNS = (("J_prog", "J(prog)", "ratio"), ("D_geo", "D(geo)", "distance"), ("rel", "%Rel", "percent"),
           ("acc_se", "Acc(SE)", "bool"), ("acc_r", "Acc(R)", "ratio"), ("J_T", "J(T)", "ratio"),
           ("match", "Match", "bool"))


def summary_data(records: Sequence[dict[str, Any]], cases: Sequence[Case]) -> dict[str, Any]:
    ok = sum(r.get("status") == "ok" for r in records)
    return {"cases": len(cases), "finished": len(records), "ok": ok, "failed": len(records) - ok,
            "metrics": summarise(r.get("metrics") for r in records if r.get("status") == "ok")}


def print_table(records: Sequence[dict[str, Any]], cases: Sequence[Case], stream=None) -> None:
    """One row per case (file order), failures with their one-line reason, then the means."""
    stream = stream or sys.stdout
    by_id = {r["id"]: r for r in records}
    width = max([len("case")] + [len(c.id) for c in cases])
    header = f"{'case':<{width}}  {'status':<7}{'ops':>4}" + "".join(f"{title:>9}" for _, title, _ in COLUMNS) \
        + f"{'time s':>9}"
    print(header, file=stream)
    for case in cases:
        record = by_id.get(case.id)
        if record is None:
            print(f"{case.id:<{width}}  {'not run':<7}", file=stream)
            continue
        metrics = record.get("metrics") or {}
        elapsed = record.get("elapsed_s")
        row = f"{case.id:<{width}}  {record.get('status', '?'):<7}{record.get('ops', '-')!s:>4}"
        row += "".join(f"{_fmt(metrics.get(key), kind):>9}" for key, _, kind in COLUMNS)
        row += f"{'-' if elapsed is None else f'{elapsed:.2f}':>9}"
        print(row, file=stream)
        if record.get("status") != "ok":
            error = record.get("error") or {}
            print(f"{'':<{width}}    {error.get('type', 'Error')}: {error.get('message', '')}", file=stream)
    summary = summary_data(records, cases)
    print(f"\n{summary['cases']} cases: {summary['ok']} ok, {summary['failed']} failed"
          + (f", {summary['cases'] - summary['finished']} not run" if summary['finished'] < summary['cases'] else ""),
          file=stream)
    means = means_line(summary["metrics"])
    if means:
        print(means, file=stream)


def means_line(metrics: dict[str, Any]) -> str:
    """``means (cases): J(prog) 0.83 (12), ...`` for the metrics defined on at least one case."""
    parts = []
    for key, title, kind in COLUMNS:
        entry = metrics[key]
        if entry["cases"]:
            mean = entry["mean"]
            value = f"{100 * mean:.1f}%" if kind in ("percent", "bool") else _fmt(mean, kind)
            parts.append(f"{title} {value} ({entry['cases']})")
    return "means (cases): " + ", ".join(parts) if parts else ""


def cmd_eval(args: argparse.Namespace) -> int:
    """Run cases (or read a batch's results) and score them against their ground truth."""
    cases = read_cases(args.cases)
    if args.results:
        records = ordered(read_results(args.results), cases)
    else:
        from parsel_batch.batch import progress_bar

        defaults = RunDefaults(backend=args.backend)
        bar = progress_bar(len(cases), shows_progress())
        done = []
        for outcome in run_cases(cases, defaults, args.workers):
            done.append(outcome.record)
            log_outcome(outcome)
            bar.update(1)
        bar.close()
        records = ordered(done, cases)
    summary = summary_data(records, cases)
    if args.json:
        print(json.dumps({"format": EVAL_FORMAT, "version": EVAL_VERSION, "cases": records, "summary": summary},
                         indent=1))
    else:
        print_table(records, cases)
    return EXIT_FAILED_CASES if summary["failed"] or summary["finished"] < summary["cases"] else 0


def cmd_batch(args: argparse.Namespace) -> int:
    """Run many cases into OUTDIR, resumably, on local processes or a Dask cluster."""
    cases = read_cases(args.cases)
    if args.workers is not None and args.workers < 0:
        raise ParselError("--workers must be 0 (in this process) or more")
    if args.dask and args.workers is not None:
        raise ParselError("--workers and --dask exclude each other (the cluster decides its workers)")
    if args.dask:
        check_dask_address(args.dask)  # before OUTDIR is made
    workers = available_cpus() if args.workers is None else args.workers
    try:
        summary = run_batch(cases, args.output, workers=workers, dask=args.dask,
                            defaults=RunDefaults(backend=args.backend), retry_failed=args.retry_failed,
                            progress=shows_progress() and not args.no_progress)
    except KeyboardInterrupt:
        print(f"\ninterrupted: finished cases are kept in {args.output}; run the same command to resume",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    where = f"dask {args.dask}" if args.dask else f"{workers} worker process(es)" if workers else "this process"
    if args.json:
        print(json.dumps({"output": args.output, "cases": summary.total, "ran": summary.ran,
                          "failed": summary.failed, "failed_now": summary.failed_now, "skipped": summary.skipped,
                          "where": where, "summary": summary_data(summary.records, cases),
                          "failures": [{"id": r["id"], **(r.get("error") or {})} for r in summary.records
                                       if r.get("status") != "ok"]}, indent=1))
        return EXIT_FAILED_CASES if summary.failed else 0
    print(f"{summary.total} cases: {summary.ran} run on {where} ({summary.failed_now} failed), "
          f"{summary.skipped} already done -> {args.output}")
    means = means_line(summarise(r.get("metrics") for r in summary.records if r.get("status") == "ok"))
    if means:
        print(means)
    for record in summary.records:
        if record.get("status") != "ok":
            error = record.get("error") or {}
            print(f"  failed: {record['id']}: {error.get('type')}: {error.get('message')}")
    return EXIT_FAILED_CASES if summary.failed else 0


def register(subparsers: Any) -> None:
    """Add ``eval`` and ``batch`` to the ``parsel`` command line."""
    p = subparsers.add_parser("eval", help="score inferred programs against ground truth (J, D, %%Rel, LLM accuracy)",
                              description="Run the cases of CASES.jsonl (schema: docs/evaluation.md) and print "
                                          "J(prog), D(geo), %Rel and, for language-model outputs, Acc(SE), "
                                          "Acc(R), J(T) and Match per case, then their means. Exit status 1 when a "
                                          "case failed.")
    p.add_argument("cases", metavar="CASES.jsonl", help="one case per line (schema: docs/evaluation.md)")
    p.add_argument("--json", action="store_true", help="machine-readable output (format parsel.eval)")
    p.add_argument("--workers", type=bounded_int("--workers", 0, MAX_WORKERS), default=0, metavar="N",
                   help=f"local worker processes, 0 to {MAX_WORKERS} (default 0: run in this process)")
    p.add_argument("--results", metavar="OUTDIR",
                   help="do not run: score the records a `parsel batch` run wrote to OUTDIR")
    p.add_argument("--backend", metavar="NAME", help="CAS backend for cases that do not choose one")
    add_verbosity_options(p, verbose_help="also print each case's status, ops and time on stderr as it finishes")
    p.set_defaults(func=cmd_eval)

    p = subparsers.add_parser("batch", help="run many cases, resumably, on local processes or a Dask cluster",
                              description="Run every case of CASES.jsonl not already done in OUTDIR, writing "
                                          "OUTDIR/<case id>/ and a line of OUTDIR/results.jsonl as each finishes. "
                                          "Interrupted runs resume where they stopped. Exit status 1 when a case "
                                          "failed (its error is in its record).")
    p.add_argument("cases", metavar="CASES.jsonl", help="one case per line (schema: docs/evaluation.md)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR",
                   help="output folder: OUTDIR/<case id>/ and OUTDIR/results.jsonl")
    p.add_argument("--workers", type=bounded_int("--workers", 0, MAX_WORKERS), metavar="N",
                   help=f"local worker processes, 0 to {MAX_WORKERS} (default: the CPUs available; 0 runs in this "
                        "process)")
    p.add_argument("--dask", metavar="ADDRESS", help="run on the Dask scheduler at ADDRESS (tcp://host:8786)")
    p.add_argument("--retry-failed", action="store_true", help="run failed cases again instead of skipping them")
    p.add_argument("--no-progress", action="store_true", help=argparse.SUPPRESS)  # the old spelling of --quiet
    p.add_argument("--json", action="store_true", help="print the run's summary as JSON")
    p.add_argument("--backend", metavar="NAME", help="CAS backend for cases that do not choose one")
    add_verbosity_options(p, verbose_help="also print each case's status, ops and time on stderr as it finishes")
    p.set_defaults(func=cmd_batch)
