"""Intrinsic calibration from images of a ChArUco board (``cv2.aruco``) or a chessboard: corner
detection with sub-pixel refinement, ``cv2.calibrateCamera``, the reprojection error of every view,
rejection of bad views and a coverage hint (the image cells where no corner has been seen yet).

Board frame (mm): X along the ``squares[0]`` columns, Y along the rows, Z = 0 on the board; the first
inner corner is at (square, square), as OpenCV's ChArUco boards place it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from core.camera.frames import image_file_size
from core.camera.model import Camera
from core.errors import InputError

BOARD_KINDS = ("charuco", "chessboard")
#: corners a view needs to count (fewer do not constrain a homography well)
MIN_CORNERS = 8
#: views needed for a calibration
MIN_VIEWS = 4
#: a view is rejected when its RMS error exceeds both the median + 3 robust σ of all views and twice
#: the median (so a set of uniformly good views loses nothing to a tiny spread)
REJECT_SIGMAS = 3.0
COVERAGE_GRID = (4, 3)
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: ``kind`` charuco|chessboard, ``squares`` (columns, rows), square and ArUco
    marker sides in mm, the ArUco ``dictionary`` name (``cv2.aruco.DICT_*``)."""

    kind: str = "charuco"
    squares: tuple[int, int] = (7, 5)
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.kind not in BOARD_KINDS:
            raise InputError(f"board must be one of {', '.join(BOARD_KINDS)}, not '{self.kind}'")
        columns, rows = self.squares
        if not (3 <= columns <= 40 and 3 <= rows <= 40):
            raise InputError(f"a board needs 3..40 squares a side, got {columns}x{rows}")
        if not 0 < self.square_mm <= 1000:
            raise InputError(f"square side must be within 0..1000 mm, got {self.square_mm}")
        if self.kind == "charuco":
            if not 0 < self.marker_mm < self.square_mm:
                raise InputError(f"ArUco marker side ({self.marker_mm} mm) must be below the square side "
                                 f"({self.square_mm} mm)")
            if not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
                raise InputError(f"unknown ArUco dictionary '{self.dictionary}'")
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
            if dictionary.bytesList.shape[0] < columns * rows // 2:
                raise InputError(f"dictionary {self.dictionary} has too few markers for a {columns}x{rows} board")

    @property
    def inner_corners(self) -> tuple[int, int]:
        """(columns, rows) of inner corners."""
        return self.squares[0] - 1, self.squares[1] - 1

    def object_points(self) -> np.ndarray:
        """All inner corners ``(C,3)`` mm in the board frame, row by row (the corner ids of ChArUco)."""
        columns, rows = self.inner_corners
        grid = np.mgrid[1:rows + 1, 1:columns + 1].reshape(2, -1).T[:, ::-1]
        return np.column_stack([grid * self.square_mm, np.zeros(len(grid))])

    def charuco_board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.squares, self.square_mm, self.marker_mm, dictionary)


def board_image(spec: BoardSpec, pixels_per_square: int) -> tuple[np.ndarray, int]:
    """A printable image of the board (grey uint8) with a white margin: ``(image, margin px)``; board point
    (X, Y) mm is at pixel ((X / square) · pixels_per_square + margin − 0.5, ...)."""
    margin = pixels_per_square // 2
    columns, rows = spec.squares
    size = (columns * pixels_per_square + 2 * margin, rows * pixels_per_square + 2 * margin)
    if spec.kind == "charuco":
        return spec.charuco_board().generateImage(size, marginSize=margin, borderBits=1), margin
    cells = (np.indices((rows, columns)).sum(axis=0) % 2 == 0).astype(np.uint8)
    squares = np.kron(1 - cells, np.ones((pixels_per_square, pixels_per_square), np.uint8)) * 255
    return cv2.copyMakeBorder(squares, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255), margin


@dataclass
class Detection:
    """Board corners found in one image: ``ids (K,)`` into :meth:`BoardSpec.object_points`,
    ``image_points (K,2)`` px, ``object_points (K,3)`` mm."""

    ids: np.ndarray
    image_points: np.ndarray
    object_points: np.ndarray


def detect_board(image: np.ndarray, spec: BoardSpec) -> Detection | None:
    """The board's corners in ``image`` (BGR or grey), refined to sub-pixel; None when fewer than
    :data:`MIN_CORNERS` are found (or, for ChArUco, they are collinear)."""
    grey: np.ndarray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    if spec.kind == "charuco":
        board = spec.charuco_board()
        corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(grey)
        if ids is None or len(ids) < MIN_CORNERS or board.checkCharucoCornersCollinear(ids):
            return None
        ids = ids.ravel()
    else:
        found, corners = cv2.findChessboardCorners(grey, spec.inner_corners,
                                                   flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            return None
        ids = np.arange(len(corners))
    window = (3, 3) if spec.kind == "charuco" else (5, 5)  # ChArUco: stay clear of the ArUco markers' edges
    corners = cv2.cornerSubPix(grey, np.asarray(corners, np.float32).reshape(-1, 1, 2), window, (-1, -1),
                               _SUBPIX_CRITERIA)
    return Detection(ids, corners.reshape(-1, 2).astype(float), spec.object_points()[ids])


def detect_board_in_files(paths: list[Path], spec: BoardSpec, before: Callable[[int], None] | None = None
                          ) -> tuple[list[Detection | None], tuple[int, int]]:
    """The board in each image file (None where not found) and the images' common size (w, h) px; every
    image must have the first one's size. ``before(k)`` is called before image k is read (a worker's
    progress and cancellation)."""
    if not paths:
        raise InputError("no board images to calibrate from")
    detections: list[Detection | None] = []
    size = image_file_size(paths[0])
    for index, path in enumerate(paths):
        if before is not None:
            before(index)
        image_size = image_file_size(path)
        if image_size != size:
            raise InputError(f"{path.name} is {image_size[0]}×{image_size[1]} px but the first image is "
                             f"{size[0]}×{size[1]}")
        image = cv2.imdecode(np.fromfile(path, dtype=np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            raise InputError(f"{path.name}: OpenCV cannot decode this image")
        detections.append(detect_board(image, spec))
    return detections, size


@dataclass
class IntrinsicCalibration:
    """``camera`` (not registered), ``reprojection_px``: RMS over the used views, ``view_errors (N,)`` px
    RMS per view (NaN where the board was not found), ``used (N,)`` bool, ``threshold_px`` of the
    rejection, ``empty_cells``: (column, row) cells of a :data:`COVERAGE_GRID` with no corner."""

    camera: Camera
    reprojection_px: float
    view_errors: np.ndarray
    used: np.ndarray
    threshold_px: float
    empty_cells: list[tuple[int, int]]

    def report(self) -> dict:
        """Plain numbers for the camera file and the CLI."""
        return {"reprojection_px": round(self.reprojection_px, 4), "views": int(len(self.used)),
                "views_used": int(self.used.sum()), "rejection_threshold_px": round(self.threshold_px, 4),
                "view_errors_px": [None if not np.isfinite(e) else round(float(e), 4) for e in self.view_errors],
                "coverage_hint": coverage_text(self.empty_cells)}


def calibrate_intrinsics(detections: list[Detection | None], image_size: tuple[int, int],
                         name: str = "camera") -> IntrinsicCalibration:
    """Calibrate from per-image ``detections`` (None = board not found) of ``image_size`` (w, h) px:
    ``calibrateCamera`` (k1 k2 p1 p2 k3), then views whose error is an outlier (:data:`REJECT_SIGMAS`) are
    dropped and the calibration repeated until none is."""
    found = np.array([d is not None for d in detections], dtype=bool)
    if found.sum() < MIN_VIEWS:
        raise InputError(f"the board was found in {found.sum()} of {len(detections)} images; "
                         f"calibration needs at least {MIN_VIEWS}")
    used = found.copy()
    while True:
        camera, errors = _calibrate(_used(detections, used), image_size, name)
        view_errors = np.full(len(detections), np.nan)
        view_errors[used] = errors
        median = float(np.median(errors))
        spread = 1.4826 * float(np.median(np.abs(errors - median)))
        threshold = max(median + REJECT_SIGMAS * spread, 2.0 * median)
        bad = used & (view_errors > threshold)
        if not bad.any() or used.sum() - bad.sum() < MIN_VIEWS:
            break
        used &= ~bad
    rms = float(np.sqrt(np.sum(errors ** 2 * _counts(detections, used)) / _counts(detections, used).sum()))
    points = np.concatenate([d.image_points for d in _used(detections, used)])
    return IntrinsicCalibration(camera, rms, view_errors, used, threshold, empty_cells(points, image_size))


def _used(detections: list[Detection | None], used: np.ndarray) -> list[Detection]:
    """The ``detections`` where ``used (N,)`` bool is set (only ever where the board was found)."""
    return [d for d, u in zip(detections, used, strict=True) if u and d is not None]


def _counts(detections: list[Detection | None], used: np.ndarray) -> np.ndarray:
    return np.array([len(d.ids) for d in _used(detections, used)], dtype=float)


def _calibrate(detections: list[Detection], image_size: tuple[int, int], name: str) -> tuple[Camera, np.ndarray]:
    """One ``calibrateCamera``: the camera and the RMS error (px) of every view."""
    objects = [d.object_points.astype(np.float32) for d in detections]
    images = [d.image_points.astype(np.float32) for d in detections]
    try:
        _, matrix, distortion, rvecs, tvecs = cv2.calibrateCamera(objects, images, image_size, None, None)
    except cv2.error as error:
        raise InputError(f"calibration failed: {str(error).strip().splitlines()[-1][:200]}") from None
    errors = np.empty(len(detections))
    for index, (detection, rvec, tvec) in enumerate(zip(detections, rvecs, tvecs, strict=True)):
        projected, _ = cv2.projectPoints(detection.object_points, rvec, tvec, matrix, distortion)
        errors[index] = np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - detection.image_points) ** 2, axis=1)))
    return Camera(matrix, distortion.ravel(), image_size, name=name), errors


def empty_cells(points: np.ndarray, image_size: tuple[int, int],
                grid: tuple[int, int] = COVERAGE_GRID) -> list[tuple[int, int]]:
    """(column, row) cells of a ``grid`` over the image that hold none of ``points (N,2)`` px."""
    columns = np.clip((points[:, 0] * grid[0] // image_size[0]).astype(int), 0, grid[0] - 1)
    rows = np.clip((points[:, 1] * grid[1] // image_size[1]).astype(int), 0, grid[1] - 1)
    seen = set(zip(columns.tolist(), rows.tolist(), strict=True))
    return [(c, r) for r in range(grid[1]) for c in range(grid[0]) if (c, r) not in seen]


def coverage_text(cells: list[tuple[int, int]], grid: tuple[int, int] = COVERAGE_GRID) -> str:
    """A one-line hint naming where the board has not been seen yet."""
    if not cells:
        return "corners cover every part of the image"
    vertical = {0: "top", grid[1] - 1: "bottom"}
    horizontal = {0: "left", grid[0] - 1: "right"}
    names = [f"{vertical.get(r, 'middle')}-{horizontal.get(c, 'centre')}" for c, r in cells]
    return "no corners yet in the " + ", ".join(dict.fromkeys(names)) + " of the image: show the board there"
