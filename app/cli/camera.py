"""``handmocap camera calibrate|register|overlay|simulate`` and ``handmocap evaluate camera``: a calibrated
camera beside the markers (issue 14)."""

from __future__ import annotations

import argparse
from pathlib import Path

from handmocap.app.cli.common import (
    OVERWRITE_HELP,
    add_json_flag,
    add_outputs,
    add_rate_argument,
    check_outputs,
    print_figures,
    progress_printer,
)
from handmocap.core.errors import InputError


def _squares(text: str) -> tuple[int, int]:
    """``CxR`` as (columns, rows); one line when it is not two whole numbers."""
    try:
        columns, rows = (int(part) for part in str(text).lower().split("x"))
    except ValueError:
        raise InputError(f"a board size must look like 10x7 (across x down), not '{text}'") from None
    return columns, rows


def command_calibrate(args: argparse.Namespace) -> int:
    """``handmocap camera calibrate``: write a camera's intrinsics from board images, folders of them or videos;
    exit 2 on bad input (a board not found says which size or kind was found instead)."""
    from handmocap.core.camera.files import save_camera
    from handmocap.core.camera.intrinsics import BoardSpec, board_views, calibrate_views

    check_outputs(args)
    if args.squares is not None and args.inner_corners is not None:
        raise InputError("give the board's size once: --squares (squares) or --inner-corners (inner corners)")
    if args.inner_corners is not None:
        columns, rows = _squares(args.inner_corners)
        squares = (columns + 1, rows + 1)
    else:
        squares = _squares(args.squares) if args.squares is not None else (7, 5)
    if args.video_views < 4:
        raise InputError("--video-views must be at least 4")
    spec = BoardSpec(args.board, squares, args.square_mm, args.marker_mm, args.dictionary)
    found = board_views(list(args.images), args.video_views)
    views = found.views
    for name, other in found.skipped:
        print(f"skipped {name}: {other[0]}×{other[1]} px, the other images are {found.size[0]}×{found.size[1]}")
    with progress_printer("detecting the board", len(views), "images") as progress:
        result, sensitivity = calibrate_views(views, found.size, spec, Path(args.out).stem,
                                              lambda index: progress(index / len(views)))
        progress(1.0)
    save_camera(result.camera, args.out, {"intrinsics": {**result.report(), "subpixel_window": sensitivity}})
    camera = result.camera
    print(f"calibrated from {int(result.used.sum())} of {len(views)} images: f = {camera.focal[0]:.2f}, "
          f"{camera.focal[1]:.2f} px, principal point {camera.principal_point[0]:.2f}, "
          f"{camera.principal_point[1]:.2f} px, reprojection {result.reprojection_px:.3f} px -> {args.out}")
    if sensitivity:
        low, median, high = sensitivity["window_px"]
        changes = ", ".join(f"{change:+.3f} % at {factor}" for factor, change in
                            sensitivity["focal_change_percent"].items())
        print(f"sub-pixel window: half-width {low}–{high} px (median {median:g}) from the squares' size in each image; "
              f"the focal length moves {changes} that window")
    print(f"hint: {result.report()['coverage_hint']}")
    return 0


def _blobs(args: argparse.Namespace, camera):
    from handmocap.core.camera.extrinsics import detect_blobs
    from handmocap.core.camera.frames import open_frames

    with open_frames(args.video) as video:
        if video.size != camera.size:
            raise InputError(f"{args.video} is {video.size[0]}×{video.size[1]} px but the camera is "
                             f"{camera.size[0]}×{camera.size[1]}")
        depth = open_frames(args.depth, depth_unit_mm=args.depth_unit, frame_rate=video.frame_rate) \
            if args.depth else None
        blobs = [detect_blobs(camera, video.frame(k), depth.frame(k) if depth and k < depth.count else None,
                              args.marker_radius) for k in range(video.count)]
        return blobs, video.timestamps.copy()


def command_register(args: argparse.Namespace) -> int:
    """``handmocap camera register``: write the camera's extrinsics and clock from the take's markers in its
    video; exit 2 on bad input."""
    from handmocap.core.camera.files import load_camera, save_camera
    from handmocap.core.camera.model import CameraClock
    from handmocap.core.camera.registration import register_take
    from handmocap.core.io import load_take

    check_outputs(args)
    camera = load_camera(args.camera)
    if args.offset is not None:
        camera = camera.with_clock(CameraClock(args.offset, camera.clock.rate_ratio))
    take = load_take(args.take, frame_rate=args.rate)
    blobs, times = _blobs(args, camera)
    result = register_take(camera, blobs, times, take.marker_positions, take.frame_rate, args.window)
    save_camera(result.camera, args.out, {"registration": result.report()})
    report = result.report()
    print(f"registered {args.camera} to {Path(args.take).name}: reprojection {report['reprojection_px']:.3f} px "
          f"over {report['matches']} matches ({100 * report['matched_share']:.0f} % of the blobs), offset "
          f"{report['offset_s']:.4f} s = {report['offset_frames']:.2f} mocap frames, rate ratio "
          f"{report['rate_ratio']:.5f}, sync quality {report['quality']:.2f} -> {args.out}")
    if report["residual_mm"] is not None:
        print(f"3D residual {report['residual_mm']:.2f} mm")
    if report["quality"] < 0.5 or report["matched_share"] < 0.5:
        print("warning: weak registration (few blobs explained or a flat sync cost); register from the calibration "
              "object or a marked board first, or give --offset closer to the truth")
    return 0


def command_overlay(args: argparse.Namespace) -> int:
    """``handmocap camera overlay``: write the video with the take's markers drawn on it; exit 2 on bad input."""
    from handmocap.core.camera.files import load_camera
    from handmocap.core.camera.frames import open_frames
    from handmocap.core.camera.overlay import draw_overlay, project_take
    from handmocap.core.camera.writers import write_video
    from handmocap.core.io import is_marker_label, load_take

    check_outputs(args)
    camera = load_camera(args.camera)
    if not camera.registered:
        raise InputError(f"{args.camera} has no extrinsics; run 'handmocap camera register' first")
    take = load_take(args.take, frame_rate=args.rate)
    import numpy as np

    labelled = np.array([is_marker_label(name) for name in take.marker_names], dtype=bool)
    with open_frames(args.video) as video:
        frames = (draw_overlay(video.frame(k), project_take(camera, take.marker_positions, take.frame_rate,
                                                            video.time(k)), labelled)
                  for k in range(video.count))
        count = write_video(args.out, frames, video.frame_rate, video.size)
    print(f"wrote {count} overlay frames -> {args.out}")
    return 0


def command_simulate(args: argparse.Namespace) -> int:
    """``handmocap camera simulate``: write a synthetic take, its camera video, board images and true camera
    to a folder; exit 2 on bad input."""
    from handmocap.core.camera.files import save_camera
    from handmocap.core.camera.intrinsics import BoardSpec
    from handmocap.core.camera.writers import write_depth_frames, write_video
    from handmocap.core.io import save_take
    from handmocap.core.io.durable import write_atomic
    from handmocap.core.simulate.camera import board_views, simulate_camera_take

    folder = Path(args.out_folder)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder} exists and is not a folder")
    if folder.exists() and any(folder.iterdir()) and not args.overwrite:
        raise InputError(f"{folder} is not empty; use --overwrite to replace its files")
    folder.mkdir(parents=True, exist_ok=True)
    simulated = simulate_camera_take(args.seed, args.frames, args.mocap_rate, offset_s=args.offset)
    camera = simulated.camera
    save_take(simulated.simulated.take, folder / "take.c3d")
    rendered = [simulated.render(k, with_depth=args.depth) for k in range(len(simulated.camera_times))]
    write_video(folder / "video.avi", (colour for colour, _ in rendered), simulated.frame_rate, camera.size)
    if args.depth:
        (folder / "depth").mkdir(exist_ok=True)
        # (rendered with depth: none is None)
        write_depth_frames(folder / "depth", (depth for _, depth in rendered if depth is not None), 1.0)
    save_camera(camera, folder / "camera_truth.json")
    (folder / "board").mkdir(exist_ok=True)
    import cv2

    for index, image in enumerate(board_views(camera, BoardSpec(), args.boards, args.seed).images):
        write_atomic(folder / "board" / f"board_{index:02d}.png", cv2.imencode(".png", image)[1].tobytes())
    print(f"wrote {folder}: take.c3d ({simulated.simulated.take.n_frames} frames at {args.mocap_rate:g} Hz), "
          f"video.avi ({len(rendered)} frames at {simulated.frame_rate:g} Hz, clock offset "
          f"{camera.clock.offset_s:.4f} s){', depth/ (1 mm units)' if args.depth else ''}, {args.boards} ChArUco "
          f"7x5 board images in board/, truth camera_truth.json")
    return 0


def command_evaluate_camera(args: argparse.Namespace) -> int:
    """``handmocap evaluate camera``: print the camera calibration accuracy on synthetic cameras."""
    from handmocap.core.evaluation.camera import HELD_OUT_SEEDS, evaluate_camera

    seeds = tuple(args.seeds) if args.seeds else HELD_OUT_SEEDS
    print_figures(evaluate_camera(seeds), args.json)
    return 0


def _add_take_video_camera(parser: argparse.ArgumentParser, take_help: str, video_help: str, camera_help: str
                           ) -> None:
    """The arguments of a command that reads a take, the video filmed with it and its camera: ``take``,
    ``--rate``, ``video``, ``--camera CAMERA.json``."""
    parser.add_argument("take", help=take_help)
    add_rate_argument(parser)
    parser.add_argument("video", help=video_help)
    parser.add_argument("--camera", required=True, metavar="CAMERA.json", help=camera_help)


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add the camera subcommands to the ``handmocap`` parser."""
    camera = commands.add_parser("camera", help="calibrate a camera, register it to the mocap space, overlay")
    actions = camera.add_subparsers(dest="camera_command", metavar="ACTION", required=True)

    calibrate = actions.add_parser("calibrate", help="intrinsics from images of a ChArUco board or a chessboard")
    calibrate.add_argument("images", nargs="+", metavar="IMAGES",
                           help="board images (PNG/JPG/BMP/TIF), folders of them, or videos (MP4/AVI/MOV/MKV)")
    calibrate.add_argument("--board", choices=["charuco", "chessboard"], default="charuco",
                           help="the calibration board in the images (default charuco)")
    calibrate.add_argument("--squares", metavar="CxR",
                           help="squares across x down (default 7x5); OpenCV's 9x6 chessboard has 10x7 squares")
    calibrate.add_argument("--inner-corners", metavar="CxR",
                           help="or the board's inner corners across x down (OpenCV's pattern size, e.g. 9x6)")
    calibrate.add_argument("--video-views", type=int, default=40, metavar="N",
                           help="frames of a video searched for the board, evenly spread (default 40)")
    calibrate.add_argument("--square-mm", type=float, default=30.0, help="square side in mm (default 30)")
    calibrate.add_argument("--marker-mm", type=float, default=22.0, help="ArUco marker side in mm (default 22)")
    calibrate.add_argument("--dictionary", default="DICT_4X4_50", help="ArUco dictionary (default DICT_4X4_50)")
    calibrate.add_argument("--out", required=True, metavar="CAMERA.json", help="the camera to write")
    add_outputs(calibrate, "out")
    calibrate.set_defaults(handler=command_calibrate)

    registration = actions.add_parser("register", help="extrinsics and time offset from the take's markers")
    _add_take_video_camera(registration, "labelled take (C3D, TSV, TRC, CSV)",
                           "the camera's video (MP4/AVI) or folder of frames", "intrinsics (JSON/YAML/XML)")
    registration.add_argument("--depth", metavar="FOLDER", help="registered 16-bit depth frames (RGB-D)")
    registration.add_argument("--depth-unit", type=float, default=1.0, metavar="MM", help="depth unit (default 1)")
    registration.add_argument("--offset", type=float, metavar="S", help="guess of the clock offset (s)")
    registration.add_argument("--window", type=float, default=0.5, metavar="S",
                              help="offset search half-width around the guess (s, default 0.5)")
    registration.add_argument("--marker-radius", type=float, default=3.0, metavar="MM",
                              help="radius of the markers in mm (default 3)")
    registration.add_argument("--out", required=True, metavar="CAMERA.json", help="the registered camera to write")
    add_outputs(registration, "out")
    registration.set_defaults(handler=command_register)

    overlay = actions.add_parser("overlay", help="write the video with the take's markers drawn on it")
    _add_take_video_camera(overlay, "the take whose markers are drawn", "the camera's video or folder of frames",
                           "the camera (calibrated and registered)")
    overlay.add_argument("--out", required=True, metavar="OVERLAY.mp4|.avi", help="the video to write")
    add_outputs(overlay, "out")
    overlay.set_defaults(handler=command_overlay)

    simulate = actions.add_parser("simulate", help="write a synthetic camera take to try the workflow")
    simulate.add_argument("--out", dest="out_folder", required=True, metavar="FOLDER",
                          help="a new or empty folder (its files are replaced only with --overwrite)")
    simulate.add_argument("--seed", type=int, default=0, help="seed of the simulated take and camera (default 0)")
    simulate.add_argument("--frames", type=int, default=400, help="mocap frames (default 400)")
    simulate.add_argument("--mocap-rate", type=float, default=100.0, metavar="HZ",
                          help="frame rate of the simulated take (default 100 Hz)")
    simulate.add_argument("--offset", type=float, metavar="S", help="camera clock offset (default random)")
    simulate.add_argument("--depth", action="store_true", help="also write depth frames")
    simulate.add_argument("--boards", type=int, default=15, help="board images for calibration (default 15)")
    simulate.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    simulate.set_defaults(handler=command_simulate)

    evaluate = evaluate_commands.add_parser("camera", help="camera calibration accuracy on synthetic cameras")
    evaluate.add_argument("--seeds", type=int, nargs="+", help="seeds (default: the held-out 101 102 103)")
    add_json_flag(evaluate)
    evaluate.set_defaults(handler=command_evaluate_camera)
