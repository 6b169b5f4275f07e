"""``handmocap live``: the stand-in server (``serve``), a recording from a capture system (``record``) and
the recovery of a recording's journal after a crash (``recover``)."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

from handmocap.app.cli.common import add_json_flag, add_outputs, add_rate_argument, check_outputs, print_json
from handmocap.core.errors import InputError


def command_serve(args: argparse.Namespace) -> int:
    """``handmocap live serve``: replay a take over QTM's RT protocol or NatNet on 127.0.0.1 until Ctrl+C."""
    from handmocap.core.io import load_take
    from handmocap.core.live.server import StandInServer, make_replay

    take = load_take(args.take, frame_rate=args.rate)
    replay = make_replay(take, args.rate, unlabelled=args.unlabelled)
    server = StandInServer(replay, args.protocol, args.port, loop_take=not args.once, password=args.password or "")
    print(f"serving {Path(args.take).name} ({replay.frames} frames at {replay.rate:g} Hz, "
          f"{'unlabelled' if args.unlabelled else f'{len(replay.labels)} labelled markers'}) over "
          f"{'QTM RT' if args.protocol == 'qtm' else 'NatNet'} on 127.0.0.1:{args.port}; Ctrl+C stops",
          file=sys.stderr, flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        import asyncio  # imported by the live commands only (start-up of every other command)

        asyncio.run(server.serve(args.seconds))
    print(f"sent {server.frames_sent} frames", file=sys.stderr)
    return 0


def command_record(args: argparse.Namespace) -> int:
    """``handmocap live record``: record from QTM or Motive, labelling live; the take goes into the session."""
    from handmocap.core.live.capture import LiveCapture, live_report
    from handmocap.core.live.systems import make_source
    from handmocap.core.model.lab_template import load_lab_template

    check_outputs(args)
    if args.seconds is not None and not args.seconds > 0:
        raise InputError("--seconds must be positive")
    kind, address = ("qtm", args.qtm) if args.qtm else ("natnet", args.natnet)
    source = make_source(kind, address)
    layout = load_lab_template(args.layout) or args.layout
    out = Path(args.out)
    session = Path(args.session) if args.session else out.parent / "handmocap-session"
    capture = LiveCapture(source, layout, args.hands, args.objects, session, name=args.name or out.stem,
                          follow_system=args.follow or (kind == "qtm" and args.control), unseen_seconds=args.unseen)
    capture.start(timeout=args.timeout)
    if not args.quiet:
        print(f"recording from {source.label} at {source.address}"
              + (f" ({capture.frame_rate:g} Hz)" if capture.frame_rate else "")
              + (f" for {args.seconds:g} s" if args.seconds else "; Ctrl+C stops"), file=sys.stderr, flush=True)
    started = time.monotonic()
    try:
        if kind == "qtm" and args.control:
            _control(capture, args)
        capture.run_for(args.seconds if args.seconds else 10 ** 9)
    except KeyboardInterrupt:
        pass
    finally:
        if kind == "qtm" and args.control:
            for command in ("stop", "releasecontrol"):
                with contextlib.suppress(InputError):
                    capture.control(command)
    result = capture.stop(out, overwrite=args.overwrite)
    report = live_report(result) | {"seconds": round(time.monotonic() - started, 2),
                                    "out": str(result.out) if result.out else None,
                                    "session": str(session), "take": result.take_id}
    for message in result.messages:
        print(message, file=sys.stderr)
    for line in result.summary:
        print(line, file=sys.stderr)
    figures = {key: report[key] for key in ("frames_received", "frames_dropped", "latency_ms_p50", "latency_ms_p99",
                                            "labelled_share", "startup_ms", "out", "take")}
    if not args.quiet:
        for key, value in figures.items():
            print(f"  {key:<20} {value}")
    if args.json:
        print_json({key: value for key, value in report.items() if key != "labelling"}
                   | {"labelling_models": report.get("labelling", {}).get("models", [])})
    return 2 if not result.figures["frames_received"] or capture.recording_error else 0


def _control(capture, args: argparse.Namespace) -> None:
    """Take control of QTM, start a new measurement and its capture (the recording follows)."""
    for command, argument in (("takecontrol", args.password or ""), ("new", ""), ("start", "")):
        answer = capture.control(command, argument)
        if not args.quiet:
            print(f"QTM: {answer}", file=sys.stderr)


def command_recover(args: argparse.Namespace) -> int:
    """``handmocap live recover``: the take of a recording's journal (after a crash) as a C3D."""
    from handmocap.core.io.c3d_writer import write_c3d
    from handmocap.core.live.recorder import read_journal

    check_outputs(args)
    journal = read_journal(args.journal)
    if not journal.points:
        raise InputError(f"{args.journal} holds no frame")
    take = journal.take()
    write_c3d(take, args.out)
    figures = {"frames": len(journal.points), "labelled_frames": len(journal.labels), "points": take.n_markers,
               "frame_rate_hz": take.frame_rate, "out": str(args.out)}
    print(f"recovered {figures['frames']} frames ({figures['labelled_frames']} with live labels) into {args.out}")
    if args.json:
        print_json(figures)
    return 0


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``live serve``, ``live record`` and ``live recover`` to the ``handmocap`` parser."""
    live = commands.add_parser("live", help="live capture from QTM or Motive: record with live labels; the "
                               "stand-in server")
    sub = live.add_subparsers(dest="live_command", metavar="COMMAND", required=True)

    serve = sub.add_parser("serve", help="replay a take over QTM's real-time protocol or NatNet on 127.0.0.1")
    serve.add_argument("take", metavar="TAKE", help="the take to replay (any format handmocap reads)")
    serve.add_argument("--protocol", choices=("qtm", "natnet"), required=True,
                       help="qtm: Qualisys real-time protocol; natnet: OptiTrack NatNet")
    serve.add_argument("--port", type=int, required=True, help="QTM: the little-endian port (clients use it as "
                       "given); NatNet: the command port")
    add_rate_argument(serve)
    serve.add_argument("--unlabelled", action="store_true", help="send every point unlabelled, shuffled per frame")
    serve.add_argument("--once", action="store_true", help="play the take once (default: loop)")
    serve.add_argument("--seconds", type=float, help="stop after this long (default: Ctrl+C)")
    serve.add_argument("--password", help="QTM: the password TakeControl needs")
    serve.set_defaults(handler=command_serve)

    record = sub.add_parser("record", help="record from QTM or Motive, labelling live; the take goes into the "
                            "session with the live labels as its first review step")
    where = record.add_mutually_exclusive_group(required=True)
    where.add_argument("--qtm", metavar="HOST:PORT", help="Qualisys QTM (the little-endian RT port, 22223)")
    where.add_argument("--natnet", metavar="HOST[:PORT]", help="OptiTrack Motive, NatNet unicast (command port 1510)")
    record.add_argument("--layout", default="dense", help="marker layout or lab template (name or JSON file)")
    record.add_argument("--hands", choices=("auto", "right", "left", "both"), default="auto",
                        help="auto (default): the labeller decides which hands the capture shows")
    record.add_argument("--objects", metavar="SPEC.json", help="rigid objects of the scene")
    record.add_argument("--seconds", type=float, help="record this long (default: until Ctrl+C)")
    record.add_argument("--out", required=True, metavar="TAKE.c3d", help="the take written (raw points as received)")
    record.add_argument("--session", metavar="DIR", help="the session the take enters (default: "
                        "handmocap-session beside --out; created when missing)")
    record.add_argument("--name", help="the take's name (default: the file name of --out)")
    record.add_argument("--control", action="store_true", help="QTM: take control, start a new capture and stop "
                        "it at the end (the recording follows QTM's start and stop)")
    record.add_argument("--follow", action="store_true", help="record only while QTM captures (its start/stop)")
    record.add_argument("--password", help="QTM: the password for --control")
    record.add_argument("--unseen", type=float, default=3.0, help="alarm when a marker is not seen for this many "
                        "seconds (default 3)")
    record.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for the system (default 5)")
    record.add_argument("--quiet", action="store_true", help="no progress or figures on the terminal")
    add_outputs(record, "out")
    add_json_flag(record)
    record.set_defaults(handler=command_record)

    recover = sub.add_parser("recover", help="write the take of a recording's journal (after a crash)")
    recover.add_argument("journal", metavar="JOURNAL.hmlj", help="<session>/live/<name>.hmlj")
    recover.add_argument("--out", required=True, metavar="TAKE.c3d", help="the take to write from the journal")
    add_outputs(recover, "out")
    add_json_flag(recover)
    recover.set_defaults(handler=command_recover)
