"""``handmocap calibrate``, ``handmocap bench calibrate`` and ``handmocap evaluate calibration``:
a subject-specific hand model from a 3D hand scan and 20 landmarks (journal "Hand model generation")."""

from __future__ import annotations

import argparse
from pathlib import Path

from handmocap.app.cli.common import add_json_flag, add_outputs, print_figures, print_summary, progress_printer


def command_calibrate(args: argparse.Namespace) -> int:
    """``handmocap calibrate``: fit the template to a hand scan, write the model (report, glTF), print the fit;
    exit 2 on bad input."""
    from handmocap.core.calibration.pipeline import calibrate_scan, load_template_file

    template = load_template_file(args.template, side=args.side)
    result = calibrate_scan(args.scan, args.landmarks, template=template,
                            progress=None if args.quiet else progress_printer("fitting the scan"),
                            clean=not args.no_clean, strictness=args.strictness)
    result.save(args.out, args.report)
    if args.gltf:
        from handmocap.core.model.gltf import save_gltf_hand

        save_gltf_hand(result.model, args.gltf)
    summary = result.report.to_json()
    for note in summary["notes"]:
        print(f"note: {note}")
    scan_to_model = summary["scan_to_model_mm"]
    print(f"calibrated {Path(args.scan).name}: scale {result.alignment.scale:.3f}, landmark RMS "
          f"{summary['landmark_rms_mm']:.2f} mm, scan-to-model mean {scan_to_model['mean']:.2f} mm "
          f"(p95 {scan_to_model['p95']:.2f}, max {scan_to_model['max']:.2f}) -> {args.out}")
    for warning in summary["warnings"]:
        print(f"warning: {warning}")
    return 0


def command_bench_calibrate(args: argparse.Namespace) -> int:
    """``handmocap bench calibrate``: print the seconds of the whole calibration of a synthetic scan."""
    from handmocap.core.evaluation.calibration import bench_calibrate

    figures = bench_calibrate(n_points=args.points)
    print_summary(f"calibrated a {figures['scan_points']:,}-point scan in {figures['seconds']:.1f} s", figures,
                  args.json)
    return 0


def command_evaluate_calibration(args: argparse.Namespace) -> int:
    """``handmocap evaluate calibration``: print the calibration accuracy on synthetic re-proportioned subjects."""
    from handmocap.core.evaluation.calibration import SUBJECTS, evaluate_calibration

    subjects = min(args.subjects or len(SUBJECTS), len(SUBJECTS))
    print_figures(evaluate_calibration(subjects=subjects, n_points=args.points), args.json)
    return 0


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add the calibration subcommands to the ``handmocap`` parser."""
    calibrate = commands.add_parser("calibrate", help="fit the hand model to a 3D scan of a subject's hand",
                                    description="Fit the template to a hand scan (PLY/OBJ) with 20 landmarks: "
                                    "skin filter, ICP + IK alignment, non-rigid fit, joint relocation.")
    calibrate.add_argument("scan", help="hand scan (.ply or .obj point cloud or mesh, mm or m)")
    calibrate.add_argument("--landmarks", required=True, metavar="LM.json", help="landmark positions on the scan")
    calibrate.add_argument("--template", metavar="FILE",
                           help="template hand: .npz hand model or .gltf/.glb skinned hand (default: shipped)")
    calibrate.add_argument("--side", choices=["right", "left"], default="right",
                           help="hand side of the shipped template (default right)")
    calibrate.add_argument("--out", required=True, metavar="SUBJECT.npz", help="calibrated hand model")
    calibrate.add_argument("--report", metavar="REPORT.json", help="also write the calibration report")
    calibrate.add_argument("--gltf", metavar="SUBJECT.glb", help="also export the model as glTF (.gltf/.glb)")
    calibrate.add_argument("--strictness", type=float, default=0.5, help="skin filter strictness 0..1 (default 0.5)")
    calibrate.add_argument("--no-clean", action="store_true", help="skip the skin and outlier filters")
    calibrate.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(calibrate, "out", "report", "gltf")
    calibrate.set_defaults(handler=command_calibrate)

    bench = bench_commands.add_parser("calibrate", help="seconds of the whole calibration of a 200 000-point scan")
    bench.add_argument("--points", type=int, default=200_000, help="hand points in the synthetic scan")
    add_json_flag(bench)
    bench.set_defaults(handler=command_bench_calibrate)

    evaluate = evaluate_commands.add_parser("calibration",
                                            help="calibration accuracy on synthetic re-proportioned subjects")
    evaluate.add_argument("--subjects", type=int, help="number of subjects (default 5)")
    evaluate.add_argument("--points", type=int, default=200_000, help="hand points per synthetic scan")
    add_json_flag(evaluate)
    evaluate.set_defaults(handler=command_evaluate_calibration)
