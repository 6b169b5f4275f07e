"""``handmocap fuse`` and ``handmocap evaluate fusion``: markers + RGB-D fusion tracking (issue 15, Zhao et al.
2012)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from handmocap.app.cli.common import (
    add_json_flag,
    add_outputs,
    add_rate_argument,
    check_outputs,
    print_figures,
    progress_printer,
)
from handmocap.core.errors import InputError

COLOUR_NAMES = ("colour", "color", "rgb")


def _recording(folder: Path, depth_unit: float, rate: float, background: str | None, hue: list[int] | None):
    """The RGB-D recording of ``folder``: depth PNGs in ``depth/`` (or in the folder itself), colour frames in
    ``colour/`` (PNG/JPG) or a ``video.*`` file when present."""
    import cv2
    import numpy as np

    from handmocap.core.camera.frames import open_frames
    from handmocap.core.fusion import RGBDFrames

    if not folder.is_dir():
        raise InputError(f"RGB-D folder {folder} does not exist or is not a folder")
    depth_folder = folder / "depth" if (folder / "depth").is_dir() else folder
    depth = open_frames(depth_folder, depth_unit_mm=depth_unit, frame_rate=rate)
    colour = None
    for name in COLOUR_NAMES:
        if (folder / name).is_dir():
            colour = open_frames(folder / name, frame_rate=rate)
    videos = sorted(folder.glob("video.*"))
    if colour is None and videos:
        colour = open_frames(videos[0], frame_rate=rate)
    if colour is not None and (len(colour) != len(depth) or colour.size != depth.size):
        raise InputError(f"{folder}: {len(colour)} colour frames of {colour.size[0]}×{colour.size[1]} px but "
                         f"{len(depth)} depth frames of {depth.size[0]}×{depth.size[1]} px; they must match")
    plate = None
    if background:
        plate = cv2.imdecode(np.fromfile(background, dtype=np.uint8), cv2.IMREAD_COLOR)
        if plate is None:
            raise InputError(f"{background}: OpenCV cannot decode this image")
        if colour is not None and (plate.shape[1], plate.shape[0]) != colour.size:
            raise InputError(f"{background} is {plate.shape[1]}×{plate.shape[0]} px but the colour frames are "
                             f"{colour.size[0]}×{colour.size[1]}")
    return RGBDFrames(depth, colour, plate, (hue[0], hue[1]) if hue else None)   # (--wristband-hue: 2 values)


def command_fuse(args: argparse.Namespace) -> int:
    """``handmocap fuse``: write a take solved with its markers and an RGB-D recording; exit 2 on bad input."""
    from handmocap.core.camera.files import load_camera
    from handmocap.core.fusion import FusionSettings, fuse_take
    from handmocap.core.fusion.pso import SwarmSettings
    from handmocap.core.io import load_take
    from handmocap.core.model import best_layout_for

    check_outputs(args)
    take = load_take(args.take, frame_rate=args.rate)
    camera = load_camera(args.camera)
    frames = _recording(Path(args.rgbd), args.depth_unit, args.rgbd_rate, args.background, args.wristband_hue)
    if frames.depth.size != camera.size:
        raise InputError(f"the depth frames are {frames.depth.size[0]}×{frames.depth.size[1]} px but the camera is "
                         f"{camera.size[0]}×{camera.size[1]}")
    layout = args.layout or best_layout_for(take.marker_names)
    if layout is None:
        raise InputError("no shipped layout matches the take's marker names; give one with --layout")
    if args.particles < 2 or args.generations < 1:
        raise InputError("--particles must be at least 2 and --generations at least 1")
    settings = FusionSettings(optimiser=args.optimiser, swarm=SwarmSettings(args.particles, args.generations))
    print(f"fusing {Path(args.take).name} ({take.n_frames} frames, layout {layout}) with {len(frames.depth)} RGB-D "
          f"frames ({'colour + depth' if frames.colour is not None else 'depth only'}), optimiser {args.optimiser}",
          file=sys.stderr)
    result = fuse_take(take, camera, frames, settings, progress_printer("fusing", len(frames.depth), "RGB-D frames"),
                       layout=layout)
    result.save(args.out)
    print(f"fused {len(result.rgbd_frames)} RGB-D frames ({1.0 / result.seconds_per_rgbd_frame:.2f} frames/s, "
          f"{args.optimiser}), {take.n_frames} mocap frames -> {args.out}")
    return 0


def command_evaluate_fusion(args: argparse.Namespace) -> int:
    """``handmocap evaluate fusion``: print fusion against markers-only IK on synthetic RGB-D takes."""
    from handmocap.core.evaluation.fusion import HELD_OUT_SEEDS, evaluate_fusion
    from handmocap.core.fusion import FusionSettings

    seeds = tuple(args.seeds) if args.seeds else HELD_OUT_SEEDS
    print_figures(evaluate_fusion(seeds, FusionSettings(), swarm=not args.no_pso), args.json)
    return 0


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``fuse`` and ``evaluate fusion`` to the ``handmocap`` parser."""
    fuse = commands.add_parser("fuse", help="solve a take with markers and an RGB-D camera (Zhao et al. 2012)")
    fuse.add_argument("take", help="labelled take (C3D, TSV, TRC, CSV)")
    add_rate_argument(fuse)
    fuse.add_argument("--camera", required=True, metavar="CAMERA.json", help="the registered RGB-D camera")
    fuse.add_argument("--rgbd", required=True, metavar="FOLDER",
                      help="depth PNGs in FOLDER/depth (or FOLDER), colour in FOLDER/colour or FOLDER/video.*")
    fuse.add_argument("--depth-unit", type=float, default=1.0, metavar="MM", help="mm per depth unit (default 1)")
    fuse.add_argument("--rgbd-rate", type=float, default=30.0, metavar="HZ", help="camera frame rate (default 30)")
    fuse.add_argument("--background", metavar="IMAGE", help="colour image of the empty scene (default: the median "
                      "of the colour frames)")
    fuse.add_argument("--wristband-hue", type=int, nargs=2, metavar=("LOW", "HIGH"),
                      help="hue range (OpenCV 0..180) of a coloured wristband that cuts the arm")
    fuse.add_argument("--layout", help="marker layout (default: the shipped layout matching the take)")
    fuse.add_argument("--optimiser", choices=["icp", "pso"], default="icp",
                      help="icp: swarm-seeded articulated ICP (fast, default); pso: the paper's swarm")
    fuse.add_argument("--particles", type=int, default=48, help="swarm particles (pso, default 48)")
    fuse.add_argument("--generations", type=int, default=200, help="swarm generations (pso, default 200)")
    fuse.add_argument("--out", required=True, metavar="RESULT.npz", help="the fused solve to write")
    add_outputs(fuse, "out")
    fuse.set_defaults(handler=command_fuse)

    evaluate = evaluate_commands.add_parser("fusion", help="fusion vs markers-only IK on synthetic RGB-D takes")
    evaluate.add_argument("--seeds", type=int, nargs="+", help="seeds (default: the held-out 201 202 203)")
    evaluate.add_argument("--no-pso", action="store_true", help="skip the (slow) run of the paper's swarm")
    add_json_flag(evaluate)
    evaluate.set_defaults(handler=command_evaluate_fusion)
