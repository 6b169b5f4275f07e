"""Camera calibration accuracy on synthetic cameras with known truth (``handmocap evaluate camera``).

Held-out seeds :data:`HELD_OUT_SEEDS` (development used seeds 1–8). Per seed: intrinsics from 20
ChArUco views (and a chessboard set), extrinsics from 8 views of the calibration object (colour-only PnP
and RGB-D Kabsch) and from a ChArUco board carrying 4 mocap markers, and the clock offset of a 4 s take
(100 Hz mocap, 30 Hz camera) from its marker blobs. Figures are the worst over the seeds.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.camera.extrinsics import MarkerFrame, detect_blobs, register_from_board, register_from_markers
from handmocap.core.camera.intrinsics import BoardSpec, calibrate_intrinsics, detect_board
from handmocap.core.camera.model import Camera, CameraClock, rotation_angle_deg
from handmocap.core.camera.sync import sync_markers
from handmocap.core.simulate.camera import (
    MARKER_RADIUS,
    OBJECT_MARKER_RADIUS,
    board_views,
    calibration_object_views,
    random_camera,
    simulate_camera_take,
)

HELD_OUT_SEEDS = (101, 102, 103)
CHARUCO = BoardSpec("charuco", (7, 5), 30.0, 22.0)
CHESSBOARD = BoardSpec("chessboard", (9, 7), 25.0)
MOCAP_NOISE_MM = 0.2


def _pose_errors(estimated: Camera, truth: Camera) -> tuple[float, float]:
    return (float(np.linalg.norm(estimated.centre - truth.centre)),
            rotation_angle_deg(estimated.rotation, truth.rotation))


def _intrinsic_errors(camera: Camera, truth: Camera) -> tuple[float, float]:
    focal = 100 * float(np.max(np.abs(np.array(camera.focal) / np.array(truth.focal) - 1)))
    principal = float(np.linalg.norm(np.array(camera.principal_point) - truth.principal_point))
    return focal, principal


def evaluate_seed(seed: int, take_frames: int = 400) -> dict:
    """The figures of one synthetic camera (see the module docstring)."""
    truth = random_camera(seed)
    rng = np.random.default_rng([seed, 19])
    views = board_views(truth, CHARUCO, 20, seed)
    intrinsics = calibrate_intrinsics([detect_board(image, CHARUCO) for image in views.images], truth.size)
    chess = board_views(truth, CHESSBOARD, 15, seed + 1000)
    chess_intrinsics = calibrate_intrinsics([detect_board(image, CHESSBOARD) for image in chess.images], truth.size)
    camera = intrinsics.camera
    focal, principal = _intrinsic_errors(camera, truth)
    chess_focal, chess_principal = _intrinsic_errors(chess_intrinsics.camera, truth)

    object_views = calibration_object_views(truth, 8, seed, MOCAP_NOISE_MM)
    frames = [MarkerFrame(detect_blobs(camera, colour, depth, OBJECT_MARKER_RADIUS), markers)
              for colour, depth, markers in zip(object_views.colour, object_views.depth, object_views.markers,
                                                strict=True)]
    colour_only = register_from_markers(camera, frames, use_depth=False)
    with_depth = register_from_markers(camera, frames, use_depth=True)

    board = board_views(truth, CHARUCO, 6, seed + 2000)
    width, height = CHARUCO.squares[0] * CHARUCO.square_mm, CHARUCO.squares[1] * CHARUCO.square_mm
    on_board = np.array([[-15, -15, 7.0], [width + 15, -15, 7.0], [-15, height + 15, 7.0],
                         [width / 2, height + 15, 7.0]])
    mocap = np.array([truth.to_mocap(on_board @ r.T + t) for r, t in zip(board.rotations, board.translations,
                                                                          strict=True)])
    mocap += rng.normal(0, MOCAP_NOISE_MM, mocap.shape)
    from_board = register_from_board(camera, [detect_board(image, CHARUCO) for image in board.images], on_board, mocap)

    take = simulate_camera_take(seed, take_frames, camera=truth)
    blobs = [detect_blobs(camera, take.render(k, with_depth=False)[0], None, MARKER_RADIUS)
             for k in range(len(take.camera_times))]
    guess = colour_only.camera.with_clock(CameraClock())
    sync = sync_markers(guess, blobs, take.camera_times, take.simulated.truth["marker_positions"],
                        take.simulated.take.frame_rate)
    offset_error = abs(sync.offset_s - take.camera.clock.offset_s) * take.simulated.take.frame_rate

    figures = {
        "focal_error_pct": focal, "principal_error_px": principal, "reprojection_px": intrinsics.reprojection_px,
        "chessboard_focal_error_pct": chess_focal, "chessboard_principal_error_px": chess_principal,
        "chessboard_reprojection_px": chess_intrinsics.reprojection_px,
    }
    for name, registration in (("", colour_only), ("depth_", with_depth), ("board_", from_board)):
        millimetres, degrees = _pose_errors(registration.camera, truth)
        figures[f"extrinsic_{name}mm"] = millimetres
        figures[f"extrinsic_{name}deg"] = degrees
        figures[f"extrinsic_{name}reprojection_px"] = registration.reprojection_px
    figures["offset_error_frames"] = offset_error
    figures["sync_quality"] = sync.quality
    return figures


def evaluate_camera(seeds: tuple[int, ...] = HELD_OUT_SEEDS) -> dict:
    """Worst figures over ``seeds`` (rounded), with the seeds used."""
    results = [evaluate_seed(seed) for seed in seeds]
    worst = {key: max(r[key] for r in results) for key in results[0] if key != "sync_quality"}
    worst["sync_quality"] = min(r["sync_quality"] for r in results)
    return {**{key: round(float(value), 4) for key, value in worst.items()}, "seeds": list(seeds)}
