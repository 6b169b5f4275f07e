"""``handmocap batch``: run a pipeline on every take of a session (or a folder of takes) on Dask.

Progress is the one progress line of every long command (:mod:`app.cli.progress`: the take counts, a bar of
the frames processed, frames/s, the time spent and left, in place; quiet when stderr is not a terminal).
Ctrl+C stops cleanly: finished takes are kept, the others are untouched, and the same command resumes.
Exit status: 0 when every take is done (or up to date), 1 when some failed (the reasons are printed and in
the report), 2 on an error or when interrupted.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys

from handmocap.app.cli.common import OVERWRITE_HELP, add_json_flag
from handmocap.app.cli.progress import ProgressLine
from handmocap.core.errors import InputError


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "?"
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"


class _ProgressLine:
    """The batch's progress on the one progress line (:mod:`app.cli.progress`): the take counts as its text,
    the frames of the finished takes as its bar."""

    def __init__(self, plan) -> None:
        self.frames_total = max(sum(job.frames for job in plan.jobs), 1)
        self.line = ProgressLine(f"takes 0/{len(plan.jobs)}", self.frames_total)
        self.dashboard_told = False

    def __call__(self, progress) -> None:
        console = self.line.console         # (set when the line is enabled)
        if progress.dashboard and not self.dashboard_told and self.line.enabled and console is not None:
            console.print(f"Dask dashboard: {progress.dashboard}")
            self.dashboard_told = True
        done, failed, skipped = (progress.count(state) for state in ("done", "failed", "skipped"))
        self.line.describe(f"takes {done + failed + skipped}/{progress.total}: {done} done, {failed} failed, "
                           f"{skipped} skipped, {progress.count('running')} running")
        self.line(min(progress.frames / self.frames_total, 0.999))

    def close(self) -> None:
        self.line.close()


def command_batch(args: argparse.Namespace) -> int:
    """``handmocap batch``: run the pipeline on the session's takes that need it and write the study report;
    exit 1 when a take failed, 2 on bad input or an interruption."""
    from handmocap.core.batch.pipeline import load_pipeline
    from handmocap.core.batch.report import write_study_report
    from handmocap.core.batch.runner import check_pipeline_inputs, open_study, plan_batch, run_batch
    from handmocap.core.batch.scheduler import check_scheduler_address
    from handmocap.core.batch.state import read_state

    # everything that can be checked is, before a session, an output folder or a cluster is made
    if args.scheduler is not None:
        args.scheduler = check_scheduler_address(args.scheduler)
    elif args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    pipeline = load_pipeline(args.pipeline)
    check_pipeline_inputs(pipeline)
    rejected: dict[str, str] = {}
    session = open_study(args.study, pipeline, rejected)
    plan = plan_batch(session, pipeline, args.only, args.redo, args.overwrite, rejected)
    unreadable = len(plan.failed) + len(plan.rejected)
    print(f"session {session.folder}: {len(plan.jobs)} takes to process, {len(plan.up_to_date)} up to date"
          f"{f', {unreadable} cannot be read' if unreadable else ''}; exports to {plan.output}")
    stop = {"asked": False}

    def interrupt(signum, frame) -> None:
        if stop["asked"]:
            raise KeyboardInterrupt
        stop["asked"] = True
        print("\nstopping: finished takes are kept (Ctrl+C again to quit at once)", file=sys.stderr)

    previous = signal.signal(signal.SIGINT, interrupt)
    printer = _ProgressLine(plan)
    try:
        progress = run_batch(plan, args.workers, args.scheduler, printer, lambda: stop["asked"])
    finally:
        signal.signal(signal.SIGINT, previous)
        printer.close()
    state = read_state(session.folder, plan.up_to_date)
    rows = [progress.summaries.get(job.take_id) or {"take": job.take_id, "name": job.name, "status": "queued"}
            for job in plan.jobs]
    rows += [{"take": take_id, "name": session.take(take_id).name} | state[take_id].get("summary", {})
             | {"status": "done"}
             for take_id in plan.up_to_date]
    rows += [progress.summaries[take_id] | {"name": session.take(take_id).name} for take_id in plan.failed]
    rows += [progress.summaries[file] for file in plan.rejected]
    report = write_study_report(session.folder, session.name, rows)
    done, failed = progress.count("done"), progress.count("failed")
    print(f"{done} takes processed ({progress.frames} frames, {progress.frames_per_s:.0f} frames/s, "
          f"{_duration(progress.elapsed)}), {failed} failed, {progress.count('skipped')} skipped, "
          f"{len(plan.up_to_date)} up to date; report {report}")
    for summary in progress.summaries.values():
        if summary["status"] in ("failed", "skipped"):
            print(f"  {summary['status']}: {summary.get('name', summary['take'])}: {summary['reason']}")
    if args.json:
        print(json.dumps({"done": done, "failed": failed, "skipped": progress.count("skipped"),
                          "up_to_date": len(plan.up_to_date), "frames": progress.frames,
                          "seconds": round(progress.elapsed, 3), "report": str(report),
                          "takes": [_without_trace(row) for row in rows]}))
    if progress.interrupted:
        raise InputError(f"interrupted: {done} finished takes are kept; run the same command to resume")
    return 1 if failed else 0


def _without_trace(row: dict) -> dict:
    return {key: value for key, value in row.items() if key != "trace"}


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``batch`` to the ``handmocap`` parser."""
    batch = commands.add_parser("batch", help="run a pipeline (label, calibrate, fill, solve, export) on every "
                                "take of a session on Dask; resumable")
    batch.add_argument("study", metavar="SESSION_OR_FOLDER",
                       help="a session folder, or a folder of takes (a session is made in it: handmocap-session)")
    batch.add_argument("--pipeline", required=True, metavar="P.toml", help="pipeline file (TOML or JSON; see README)")
    batch.add_argument("--only", metavar="GLOB", help="only the takes whose name or id matches (e.g. 'S01_*')")
    batch.add_argument("--redo", action="store_true", help="also the takes already done with the same inputs")
    batch.add_argument("--workers", type=int, default=2, help="local worker processes (default 2)")
    batch.add_argument("--scheduler", metavar="tcp://HOST:8786",
                       help="use this Dask scheduler instead of a local cluster (its workers must see the session "
                            "and the takes at the same paths)")
    batch.add_argument("--overwrite", action="store_true",
                       help=f"{OVERWRITE_HELP}; the exports an earlier batch of a take wrote are its own, replaced "
                            "when the take runs again")
    add_json_flag(batch)
    batch.set_defaults(handler=command_batch)
