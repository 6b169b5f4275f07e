"""The ``handmocap`` command: GUI launcher and the command-line tools (same engine as the GUI).

Errors are one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
from pathlib import Path

from handmocap.app.cli import batch as batch_commands
from handmocap.app.cli import calibrate as calibrate_commands
from handmocap.app.cli import camera as camera_commands
from handmocap.app.cli import depth as depth_commands
from handmocap.app.cli import export as export_commands
from handmocap.app.cli import fusion as fusion_commands
from handmocap.app.cli import layout as layout_commands
from handmocap.app.cli import live as live_commands
from handmocap.app.cli import review as review_commands
from handmocap.app.cli.common import (
    DeferredHelpFormatter,
    add_frames_command,
    add_outputs,
    add_rate_argument,
    check_output,
    check_outputs,
    print_figures,
    print_json,
    print_summary,
    progress_printer,
)
from handmocap.app.cli.progress import close_all as close_progress
from handmocap.core.blas import limit_blas_threads
from handmocap.core.errors import HandMocapError, InputError

#: modules that add their own subcommands (``register(commands, bench_commands, evaluate_commands)``)
SUBCOMMAND_MODULES = (layout_commands, review_commands, calibrate_commands, camera_commands, export_commands,
                      batch_commands, fusion_commands, live_commands, depth_commands)

EXIT_ERROR = 2


class _VersionAction(argparse.Action):
    """``--version``: the installed version, read only when asked for (reading it costs a tenth of a second)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, **_: object) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="show the program's version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        import handmocap

        print(f"handmocap {handmocap.__version__}")
        parser.exit()


def command_gui(args: argparse.Namespace) -> int:
    """``handmocap gui``: run the application on the given takes; with --screenshot, exit 1 when it is not saved."""
    from handmocap.app.gui.launch import run_gui

    return run_gui(args.files, screenshot=args.screenshot, frame=args.frame, solve=args.solve, demo=args.demo,
                   size=args.size, frame_rate=args.rate)


def command_info(args: argparse.Namespace) -> int:
    """``handmocap info``: print a take's frames, rate, units, markers, vendor, missing share; exit 2 on bad input."""
    from handmocap.core.io import load_take

    take = load_take(args.file, frame_rate=args.rate)
    missing = take.missing_fraction
    info = {
        "file": str(args.file), "vendor": take.vendor, "frames": take.n_frames,
        "frame_rate_hz": take.frame_rate, "first_frame": take.first_frame,
        "duration_s": round(take.n_frames / take.frame_rate, 3), "units": take.source_units,
        "markers": take.n_markers, "missing_share": round(float(missing), 4),
        "marker_names": list(take.marker_names),
    }
    from handmocap.core.io.system_labels import SYSTEM_GROUP, system_labels_summary

    system = system_labels_summary(take.parameters.get(SYSTEM_GROUP))
    if system:
        info["system_labels"] = system
    if args.json:
        print_json(info)
        return 0
    print(f"{Path(args.file).name}: {info['vendor']}, {take.n_frames} frames at {take.frame_rate:g} Hz "
          f"({info['duration_s']} s, first frame {take.first_frame}), units {take.source_units}")
    print(f"{take.n_markers} markers, {100 * missing:.1f} % of samples missing")
    if system:
        kept = f"; per point in {system['file']}" if system.get("file") else ""
        print(f"recorded live with the labels of {system['source']}: {system['labels']} labels, "
              f"{100 * system['labelled_share']:.1f} % of the points labelled by it{kept}")
    per_marker = take.missing_fraction_per_marker
    for name, share in zip(take.marker_names, per_marker, strict=True):
        print(f"  {name:<32} {100 * (1 - share):6.1f} % observed")
    return 0


def command_simulate(args: argparse.Namespace) -> int:
    """``handmocap simulate``: write a synthetic take and its ground truth; exit 2 on bad input."""
    from handmocap.core.io import save_take
    from handmocap.core.simulate import save_truth, simulate_take

    if args.frames <= 0:
        raise InputError("--frames must be positive")
    with progress_printer("simulating", args.frames) as progress:
        simulated = simulate_take(layout=args.layout, n_frames=args.frames, seed=args.seed, noise_mm=args.noise,
                                  ghost_rate=args.ghosts, occlusion=args.occlusion, unlabelled=args.unlabelled,
                                  progress=lambda fraction: progress(0.9 * fraction))
        save_take(simulated.take, args.out)
        if args.truth:
            save_truth(simulated.truth, args.truth)
        progress(1.0)
    take = simulated.take
    print(f"wrote {args.out} ({take.n_frames} frames, {take.n_markers} point columns, "
          f"{100 * take.missing_fraction:.1f} % missing)" + (f" and truth {args.truth}" if args.truth else ""))
    return 0


def command_solve(args: argparse.Namespace) -> int:
    """``handmocap solve``: write the inverse kinematics of each hand of a labelled take (result, CSV; one file
    per hand when there are two); exit 2 on bad input."""
    from handmocap.core.io import load_take
    from handmocap.core.prior import PosturePrior
    from handmocap.core.review.export import per_hand_path
    from handmocap.core.workflows.solving import solve_take, take_hands

    take = load_take(args.take, frame_rate=args.rate)
    hands = take_hands(take, args.layout, args.side)
    if len(hands) > 1:  # one file per hand: check them all before any work, as add_outputs does for --out
        for output in [args.out, args.csv] if args.csv else [args.out]:
            for hand in hands:
                check_output(per_hand_path(output, hand.side), args.overwrite)
    prior = PosturePrior.load(args.prior) if args.prior else None
    progress = progress_printer("solving", take.n_frames * len(hands)) if not args.quiet else None
    for solved in solve_take(take, hands, args.template, prior, args.method, progress):
        hand, result, what = solved.hand, solved.result, solved.model
        out = Path(args.out) if len(hands) == 1 else per_hand_path(args.out, hand.side)
        result.save(out)
        if args.csv:
            result.save_csv(args.csv if len(hands) == 1 else per_hand_path(args.csv, hand.side))
        layout = Path(hand.layout_name).stem
        print(f"solved {take.n_frames} frames of the {hand.side} hand ({len(hand.labels)} markers of layout "
              f"'{layout}') with {args.method} IK on {what}: mean residual {result.mean_residual_mm:.2f} mm -> {out}")
    return 0


def command_bench_ik(args: argparse.Namespace) -> int:
    """``handmocap bench ik``: print the layered IK frames per second on a simulated take."""
    from handmocap.core.evaluation.ik import bench_ik

    figures = bench_ik(frames=args.frames or 3000)
    print_summary(f"layered IK, {figures['markers']} markers: {figures['frames_per_s']:.0f} frames/s", figures,
                  args.json)
    return 0


def command_bench_load(args: argparse.Namespace) -> int:
    """``handmocap bench load``: print the seconds to read a generated 40-marker C3D."""
    from handmocap.core.io.generate import bench_load

    figures = bench_load(n_frames=args.frames or 100_000)
    print_summary(f"read {figures['frames']} frames × {figures['markers']} markers in {figures['seconds']:.3f} s",
                  figures, args.json)
    return 0


def command_evaluate_ik(args: argparse.Namespace) -> int:
    """``handmocap evaluate ik``: print layered against standard IK (grasp-4) and dense accuracy."""
    from handmocap.core.evaluation.ik import evaluate_ik

    print_figures(evaluate_ik(frames=args.frames or 1500), args.json)
    return 0


def command_template(args: argparse.Namespace) -> int:
    """``handmocap template build``: write the template hand mesh (default: the shipped file)."""
    from handmocap.core.model.template_mesh import DEFAULT_TEMPLATE_PATH, write_default_template

    path = check_output(args.out or DEFAULT_TEMPLATE_PATH, args.overwrite)
    write_default_template(path)
    print(f"wrote template {path}")
    return 0


def command_prior(args: argparse.Namespace) -> int:
    """``handmocap prior build``: write a posture prior from solved takes or the canonical postures, and describe it."""
    from handmocap.core.prior import DEFAULT_PRIOR_PATH, build_default_prior, build_prior_from_results, describe_prior

    if args.results:
        path = check_output(args.out or "prior.npz", args.overwrite)
        prior = build_prior_from_results([Path(p) for p in args.results])
    else:
        path = check_output(args.out or DEFAULT_PRIOR_PATH, args.overwrite)
        prior = build_default_prior()
    prior.save(path)
    print(describe_prior(prior))
    print(f"wrote prior {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:  # noqa: PLR0915 - a statement per option of each command
    """The ``handmocap`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(prog="handmocap", description="Hand Mocap Studio: optical hand motion "
                                     "capture review, labelling, gap filling and calibration.",
                                     formatter_class=DeferredHelpFormatter)
    parser.add_argument("--version", action=_VersionAction)
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    gui = commands.add_parser("gui", help="start the application (demo session when no file is given)")
    gui.add_argument("files", nargs="*", help="takes to open (C3D, TSV, TRC, CSV, TXT)")
    add_rate_argument(gui)
    gui.add_argument("--screenshot", metavar="PNG", help="wait for the solves, save a screenshot and exit")
    gui.add_argument("--frame", type=int, help="frame to show in the screenshot, numbered as in the file (as the "
                     "timeline shows it; default a third of the take)")
    gui.add_argument("--solve", action="store_true", help="solve the opened takes at once")
    gui.add_argument("--demo", action="store_true", help="also open the demo session")
    gui.add_argument("--size", metavar="WxH", help="window size in pixels, e.g. 1366x768 (default 1500x950)")
    add_outputs(gui, "screenshot")
    gui.set_defaults(handler=command_gui)

    info = commands.add_parser("info", help="frames, rate, units, markers, vendor and missing share of a take")
    info.add_argument("file", help="the take file (C3D, TSV, TRC, CSV, TXT)")
    add_rate_argument(info)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.set_defaults(handler=command_info)

    simulate = commands.add_parser("simulate", help="write a synthetic take with ground truth")
    simulate.add_argument("--layout", default="dense", help="marker layout name or JSON file (default dense)")
    simulate.add_argument("--frames", type=int, default=1000, help="frames to simulate (default 1000, at 100 Hz)")
    simulate.add_argument("--seed", type=int, default=0,
                          help="seed of the random motion, noise and ghosts (the same seed gives the same take)")
    simulate.add_argument("--noise", type=float, default=0.0, metavar="MM", help="marker noise σ in mm")
    simulate.add_argument("--ghosts", type=float, default=0.0, metavar="RATE",
                          help="share of frames with ghost points (0..1)")
    simulate.add_argument("--occlusion", action="store_true", help="hide markers the cameras cannot see")
    simulate.add_argument("--unlabelled", action="store_true", help="per-frame shuffled, unnamed points")
    simulate.add_argument("--out", required=True, metavar="TAKE.c3d",
                          help="the take file to write (.c3d, .trc, .csv or .tsv)")
    simulate.add_argument("--truth", metavar="TRUTH.npz",
                          help="also write the ground truth (joint angles, marker positions, visibility, which point "
                               "is which marker) for evaluations")
    add_outputs(simulate, "out", "truth")
    simulate.set_defaults(handler=command_simulate)

    solve = commands.add_parser("solve", help="inverse kinematics of a labelled take")
    solve.add_argument("take", help="the labelled take (C3D, TSV, TRC, CSV)")
    add_rate_argument(solve)
    solve.add_argument("--layout", help="marker layout or lab template (name or JSON file) the take is labelled "
                       "with (default: the one its marker names match)")
    solve.add_argument("--prior", help="posture prior .npz (default: the shipped prior)")
    solve.add_argument("--method", choices=["layered", "subspace", "full"], default="layered",
                       help="layered (default): the posture subspace, then all 26 parameters; subspace: the "
                            "subspace only; full: all 26 parameters")
    solve.add_argument("--side", choices=["right", "left"],
                       help="solve this hand only; the side of a hand whose names do not say it (default: every "
                       "hand; the side auto-label calibrated in the file, else right)")
    solve.add_argument("--template", action="store_true",
                       help="solve with the template hand even when the file holds a subject calibration")
    solve.add_argument("--out", required=True, metavar="RESULT.npz",
                       help="the result; with two hands RESULT_right.npz and RESULT_left.npz")
    solve.add_argument("--csv", metavar="ANGLES.csv", help="also write the joint angles as CSV (one per hand)")
    solve.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(solve, "out", "csv")
    solve.set_defaults(handler=command_solve)

    bench = commands.add_parser("bench", help="speed benchmarks (one JSON object as the last line with --json)")
    bench_commands = bench.add_subparsers(dest="bench_command", metavar="WHAT", required=True)
    add_frames_command(bench_commands, "ik", "layered IK frames per second (dense layout, simulated take)",
                       "frames to solve (default 3000)", command_bench_ik)
    add_frames_command(bench_commands, "load", "seconds to read a generated 40-marker C3D",
                       "frames in the generated file (default 100000)", command_bench_load)

    evaluate = commands.add_parser("evaluate", help="accuracy evaluations on simulated data")
    evaluate_commands = evaluate.add_subparsers(dest="evaluate_command", metavar="WHAT", required=True)
    add_frames_command(evaluate_commands, "ik", "layered against standard IK (grasp-4) and dense accuracy",
                       "frames per simulated take (default 1500)", command_evaluate_ik)

    template = commands.add_parser("template", help="regenerate the template hand mesh")
    template.add_argument("action", choices=["build"], help="build: generate the template hand mesh again")
    template.add_argument("--out", help="output .npz (default: resources/template/right_hand.npz)")
    add_outputs(template, "out")
    template.set_defaults(handler=command_template)

    prior = commands.add_parser("prior", help="build a posture prior")
    prior.add_argument("action", choices=["build"],
                       help="build: the posture prior from the canonical postures (or from --results)")
    prior.add_argument("--results", nargs="+", metavar="RESULT.npz",
                       help="solved takes to build from (default: the authored canonical postures)")
    prior.add_argument("--out", help="output .npz (default: resources/priors/default_prior.npz)")
    add_outputs(prior, "out")
    prior.set_defaults(handler=command_prior)

    for module in SUBCOMMAND_MODULES:
        module.register(commands, bench_commands, evaluate_commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``handmocap`` command ``argv`` names (the GUI when none): its exit code, or 2 after one error line."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["gui"])
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # past a file-size limit (ulimit -f) a write fails: one line
    limit_blas_threads()
    try:
        try:
            check_outputs(args)
            return args.handler(args)
        finally:
            close_progress()        # a progress line still drawn ends before an error's one line
    except HandMocapError as error:
        print(f"handmocap: error: {error}", file=sys.stderr)
    except BrokenPipeError:
        # the reader went away (``handmocap info … | head``): stop quietly, as other command-line tools do
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - replaces the closed stream until exit
        return EXIT_ERROR
    except (OSError, ValueError) as error:
        print(f"handmocap: error: {error}", file=sys.stderr)
    except KeyboardInterrupt:
        print("handmocap: interrupted", file=sys.stderr)
    except Exception as error:  # noqa: BLE001 - the user gets one line, the traceback goes to a log
        log = _write_crash_log()
        print(f"handmocap: internal error: {type(error).__name__}: {error} (details in {log})", file=sys.stderr)
    return EXIT_ERROR


def _write_crash_log() -> Path:
    """Save the current traceback to ``~/.cache/handmocap/last-error.log``; returns the path."""
    import traceback

    from handmocap.core.io.durable import write_text_atomic

    log = Path.home() / ".cache" / "handmocap" / "last-error.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(log, traceback.format_exc())
    return log


if __name__ == "__main__":
    sys.exit(main())
