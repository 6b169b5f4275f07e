"""``handmocap depth fit`` and ``handmocap depth track``: the hand model fitted to depth frames without markers
(thesis Ch. 6): where the hand is, its pose, the residuals, whether the fit can be trusted and why not, and an
overlay of the fitted hand on the depth (issue 27)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from handmocap.app.cli.common import add_outputs, check_output, check_outputs, progress_printer
from handmocap.core.errors import InputError


def _camera(args: argparse.Namespace, size: tuple[int, int]):
    """The depth camera: ``--intrinsics FX,FY,CX,CY`` or a camera file (JSON/YAML/XML) of the same size."""
    from handmocap.core.fusion.depth_track import parse_intrinsics

    text = args.intrinsics
    if "," not in text and Path(text).suffix.lower() in (".json", ".yaml", ".yml", ".xml"):
        from handmocap.core.camera.files import load_camera

        camera = load_camera(text)
        if camera.size != size:
            raise InputError(f"{text} is for {camera.size[0]}×{camera.size[1]} px but the depth frames are "
                             f"{size[0]}×{size[1]}")
        if any(camera.distortion):
            raise InputError(f"{text} has lens distortion; give the depth camera's ideal intrinsics FX,FY,CX,CY")
        from handmocap.core.camera.model import Camera

        return Camera(camera.matrix, camera.distortion, size, registered=True, name=camera.name)
    return parse_intrinsics(text, size)


def _write_json(path: str, document: dict) -> None:
    from handmocap.core.io.durable import write_atomic

    write_atomic(path, (json.dumps(document, indent=1) + "\n").encode())


def _write_png(path: Path, image) -> None:
    import cv2

    from handmocap.core.io.durable import write_atomic

    ok, data = cv2.imencode(".png", image)
    if not ok:
        raise InputError(f"cannot encode the overlay {path}")
    write_atomic(path, data.tobytes())


def command_depth_fit(args: argparse.Namespace) -> int:
    """``handmocap depth fit``: one depth frame's fit as JSON (and an overlay PNG); exit 2 on bad input."""
    from handmocap.core.fusion.depth_fit import DepthFitter
    from handmocap.core.fusion.depth_overlay import draw_depth_fit
    from handmocap.core.fusion.depth_track import read_depth_image

    check_outputs(args)
    args.depth_unit_mm = _unit(args.depth_unit_mm)
    depth = read_depth_image(args.frame, args.depth_unit_mm)
    camera = _camera(args, (depth.shape[1], depth.shape[0]))
    fitter = DepthFitter(camera, args.hand)
    fit = fitter.fit(depth)
    document = {"frame": str(args.frame), "intrinsics": args.intrinsics, "depth_unit_mm": args.depth_unit_mm,
                **fit.to_dict()}
    _write_json(args.out, document)
    if args.overlay:
        _write_png(Path(args.overlay), draw_depth_fit(depth, fitter.renderer_for(fit), fit, Path(args.frame).name))
    verdict = "trusted" if fit.trusted else "NOT trusted: " + "; ".join(fit.reasons)
    if fit.candidate is None:
        print(f"{Path(args.frame).name}: no hand found ({verdict}) -> {args.out}")
    else:
        print(f"{Path(args.frame).name}: palm at ({fit.palm_uv[0]:.0f}, {fit.palm_uv[1]:.0f}) px, "
              f"{fit.palm_depth_mm:.0f} mm; depth residual {fit.depth_residual_mm:.2f} mm, model misses "
              f"{100 * fit.missed:.0f} % of the hand, {100 * fit.outside:.0f} % outside it; {verdict} "
              f"({fit.seconds:.1f} s) -> {args.out}" + (f", {args.overlay}" if args.overlay else ""))
    return 0


def command_depth_track(args: argparse.Namespace) -> int:
    """``handmocap depth track``: every frame of a folder, tracked, as JSON (and overlays); exit 2 on bad input."""
    from handmocap.core.fusion.depth_overlay import draw_depth_fit
    from handmocap.core.fusion.depth_track import DepthTracker, depth_frame_paths, read_depth_image

    check_outputs(args)
    args.depth_unit_mm = _unit(args.depth_unit_mm)
    paths = depth_frame_paths(args.folder)
    overlays = Path(args.overlays) if args.overlays else None
    if overlays is not None:
        if overlays.exists() and not overlays.is_dir():
            raise InputError(f"{overlays} exists and is not a folder")
        overlays.mkdir(parents=True, exist_ok=True)
        for path in paths:
            check_output(overlays / f"{path.stem}_overlay.png", args.overwrite)
    first = read_depth_image(paths[0], args.depth_unit_mm)
    camera = _camera(args, (first.shape[1], first.shape[0]))
    tracker = DepthTracker(camera, args.hand)
    frames = []
    counts = {"initialised": 0, "tracked": 0, "re-initialised": 0, "lost": 0}
    with progress_printer("tracking", len(paths), "frames") as progress:
        for index, path in enumerate(paths):
            depth = first if index == 0 else read_depth_image(path, args.depth_unit_mm)
            if depth.shape != first.shape:
                raise InputError(f"{path.name} is {depth.shape[1]}×{depth.shape[0]} px but {paths[0].name} is "
                                 f"{first.shape[1]}×{first.shape[0]}")
            fit, mode = tracker.step(depth)
            counts[mode] += 1
            frames.append({"frame": path.name, "mode": mode, **fit.to_dict()})
            if overlays is not None:
                renderer = tracker.fitter.renderer_for(fit)
                _write_png(overlays / f"{path.stem}_overlay.png", draw_depth_fit(depth, renderer, fit,
                                                                                 f"{path.name} ({mode})"))
            progress((index + 1) / len(paths))
    trusted = sum(1 for frame in frames if frame["trusted"])
    _write_json(args.out, {"folder": str(args.folder), "intrinsics": args.intrinsics,
                           "depth_unit_mm": args.depth_unit_mm, "hand": args.hand, "frames": frames,
                           "summary": {"frames": len(frames), "trusted": trusted, **counts}})
    print(f"tracked {len(frames)} frames of {args.folder}: {trusted} trusted ({counts['tracked']} tracked from the "
          f"previous frame, {counts['initialised'] + counts['re-initialised']} (re-)initialised, {counts['lost']} "
          f"lost) -> {args.out}" + (f", overlays in {overlays}" if overlays else ""))
    return 0


def _unit(text: str) -> float:
    """The ``--depth-unit-mm`` value: a number of mm within 0..100 (one line otherwise)."""
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"the depth unit must be a number of mm, not '{text}'") from None
    if not 0 < value <= 100:
        raise InputError(f"the depth unit must be within 0..100 mm, got {text}")
    return value


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``depth fit`` and ``depth track`` to the ``handmocap`` parser."""
    depth = commands.add_parser("depth", help="fit the hand model to depth frames without markers (thesis Ch. 6)")
    actions = depth.add_subparsers(dest="depth_command", metavar="ACTION", required=True)

    def common(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--intrinsics", required=True, metavar="FX,FY,CX,CY",
                            help="the depth camera's focal lengths and principal point (px), or its camera file")
        parser.add_argument("--depth-unit-mm", required=True, metavar="U",
                            help="mm per depth value (e.g. 0.125 for an SR305, 1 for a Kinect)")
        parser.add_argument("--hand", choices=["right", "left"], default="right", help="the hand (default right)")

    fit = actions.add_parser("fit", help="find and fit the hand in one 16-bit PNG depth frame")
    fit.add_argument("frame", metavar="FRAME.png", help="16-bit one-channel PNG depth frame (0 = no depth)")
    common(fit)
    fit.add_argument("--out", required=True, metavar="RESULT.json",
                     help="pose, residuals, palm_uv, trusted and why not")
    fit.add_argument("--overlay", metavar="OVERLAY.png", help="also draw the fitted hand on the depth")
    add_outputs(fit, "out", "overlay")
    fit.set_defaults(handler=command_depth_fit)

    track = actions.add_parser("track", help="track the hand through a folder of depth frames (name order)")
    track.add_argument("folder", metavar="FOLDER", help="folder of 16-bit PNG depth frames")
    common(track)
    track.add_argument("--out", required=True, metavar="TRACK.json", help="every frame's fit and how it was found")
    track.add_argument("--overlays", metavar="FOLDER", help="write FRAME_overlay.png per frame into this folder")
    add_outputs(track, "out")
    track.set_defaults(handler=command_depth_track)
