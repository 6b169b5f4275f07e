"""``handmocap label``, ``handmocap fill`` and ``handmocap bench label``: the review engine from the shell."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from app.cli_common import add_json_flag, print_json, progress_printer
from core.errors import InputError


def _load_review(path: str):
    """A review of a labelled take: our labelled C3D (labels, fills, edits) or any labelled file."""
    from core.io import load_take
    from core.session import ReviewTake, review_from_labelled_c3d

    if Path(path).suffix.lower() == ".c3d":
        return review_from_labelled_c3d(path)
    return ReviewTake.from_labelled_take(load_take(path))


def command_label(args: argparse.Namespace) -> int:
    from core.batch import auto_label
    from core.io import load_take
    from core.session import ReviewTake, export_labelled_c3d

    take = load_take(args.raw)
    outcome = auto_label(take, args.layout, args.hands, args.objects, args.online,
                         progress=None if args.quiet else progress_printer())
    review = ReviewTake.unlabelled(take)
    outcome.command.do(review)
    export_labelled_c3d(review, args.out)
    report = outcome.report | {"source": str(args.raw), "output": str(args.out), "layout": args.layout,
                               "hands": args.hands}
    if args.report:
        Path(args.report).write_text(json.dumps(report, indent=2), encoding="utf-8")
    residual = report["mean_residual_mm"]
    print(f"labelled {report['frames']} frames ({report['frames_per_s']} frames/s): "
          f"{100 * report['labelled_share']:.1f} % of label samples found, "
          f"{report['ghost_points']} ghost points left unlabelled, mean IK residual "
          f"{'n/a' if residual is None else f'{residual:.2f} mm'} -> {args.out}")
    for model in report["models"]:
        first = model["first_frame_tracked"]
        print(f"  {model['name']:<12} {model['kind']:<7} tracked from frame "
              f"{'never' if first < 0 else first + take.first_frame}, {100 * model['labelled_share']:.1f} % labelled")
    return 0


def command_fill(args: argparse.Namespace) -> int:
    from core.batch import fill_review_gaps, find_review_gaps, gap_groups
    from core.session import PROVENANCE_NAMES, export_labelled_c3d

    review = _load_review(args.labelled)
    if not review.n_labels:
        raise InputError(f"{args.labelled} has no labelled points; label it first (handmocap label)")
    groups = gap_groups(review)
    gaps = find_review_gaps(review, groups)
    command = fill_review_gaps(review, groups, args.max_gap, args.method,
                               progress=None if args.quiet else progress_printer())
    counts: dict[str, int] = {}
    if command is not None:
        command.do(review)
        for fill in command.fills:
            counts[fill.method] = counts.get(fill.method, 0) + 1
    export_labelled_c3d(review, args.out)
    short = [gap for gap in gaps if gap.length <= args.max_gap and gap.filled_method is None]
    methods = ", ".join(f"{count} {name}" for name, count in sorted(counts.items())) or "none"
    still = int((review.provenance == -1).sum())
    print(f"{len(gaps)} gaps, {len(short)} of at most {args.max_gap} frames; filled {sum(counts.values())} "
          f"({methods}); {still} samples still missing -> {args.out}")
    if args.json:
        print_json({"gaps": len(gaps), "short_gaps": len(short), "filled": counts, "missing_samples": still,
                    "codes": {str(code): name for code, name in PROVENANCE_NAMES.items()}})
    return 0


def command_bench_label(args: argparse.Namespace) -> int:
    from core.labeling.bench import bench_label

    figures = bench_label(frames=args.frames) if args.frames else bench_label()
    print(f"labelling + IK: one hand {figures['frames_per_s_one_hand']:.0f} frames/s, "
          f"scene {figures['frames_per_s_scene']:.0f} frames/s")
    if args.json:
        print_json(figures)
    return 0


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``label``, ``fill`` and ``bench label`` to the ``handmocap`` parser."""
    label = commands.add_parser("label", help="automatically label the raw points of a take (hands and objects)")
    label.add_argument("raw", help="raw take: C3D with unlabelled points or fragments, Qualisys TSV, TRC")
    label.add_argument("--layout", required=True, help="marker layout of the hands (name or JSON file)")
    label.add_argument("--hands", choices=["right", "left", "both"], default="right")
    label.add_argument("--objects", metavar="SPEC.json", help="rigid objects in the scene (see docs)")
    label.add_argument("--online", action="store_true", help="causal tracking only (no backward pass)")
    label.add_argument("--out", required=True, metavar="LABELLED.c3d")
    label.add_argument("--report", metavar="REPORT.json", help="write what was found as JSON")
    label.add_argument("--quiet", action="store_true", help="no progress output")
    label.set_defaults(handler=command_label)

    fill = commands.add_parser("fill", help="fill the short gaps of a labelled take")
    fill.add_argument("labelled", metavar="LABELLED.c3d", help="labelled take (our labelled C3D, or any "
                      "labelled C3D/TSV/TRC/CSV)")
    fill.add_argument("--max-gap", type=int, required=True, metavar="FRAMES", help="longest gap to fill")
    fill.add_argument("--method", choices=["auto", "model", "spline", "linear", "pattern", "rigid"], default="auto",
                      help="auto: per gap, the method with the lowest fill-check error that applies")
    fill.add_argument("--out", required=True, metavar="FILLED.c3d")
    fill.add_argument("--quiet", action="store_true", help="no progress output")
    add_json_flag(fill)
    fill.set_defaults(handler=command_fill)

    bench = bench_commands.add_parser("label", help="labelling + IK frames per second (one hand; scene)")
    bench.add_argument("--frames", type=int, help="frames per simulated take")
    add_json_flag(bench)
    bench.set_defaults(handler=command_bench_label)
