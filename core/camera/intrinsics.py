"""Intrinsic calibration from images of a ChArUco board (``cv2.aruco``) or a chessboard: corner
detection with sub-pixel refinement, ``cv2.calibrateCamera``, the reprojection error of every view,
rejection of bad views and a coverage hint (the image cells where no corner has been seen yet).

The sub-pixel search window follows the board's size in each image: its half-width is a share of the smallest
square side seen there (a chessboard: :data:`SUBPIX_SHARE`, large enough to hold the corner's edges and small
enough to keep the neighbouring corners out; a ChArUco board: the white gap between a corner and its markers).
:func:`window_sensitivity` reports how far the focal length moves with that window 25 % smaller and larger.
The images may be files, folders of images or videos (:func:`board_views`); a board that is not found is
explained (:func:`board_hint`: found as another size or kind, and the options that fit).

Board frame (mm): X along the ``squares[0]`` columns, Y along the rows, Z = 0 on the board; the first
inner corner is at (square, square), as OpenCV's ChArUco boards place it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import cv2
import numpy as np

from handmocap.core.camera.frames import image_file_size
from handmocap.core.camera.model import Camera
from handmocap.core.errors import InputError

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
_CHESSBOARD_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
#: a chessboard's sub-pixel half-window as a share of the smallest square side in the image (px). On synthetic
#: views (squares of 14–33 px) 0.3–0.6 give the focal length within 0.06 %, 0.1 within 0.1 %, 0.8 up to 3 % off;
#: on OpenCV's real sample photographs (squares of 22–45 px, some blur) 0.3 gives the lowest reprojection error
#: (0.180 px over the 12 views; 0.4: 0.277 px, two views at 0.45 px; OpenCV's tutorial 11 px: 0.422 px, one view
#: at 1.22 px where its window reaches the next corner)
SUBPIX_SHARE = 0.3
#: a ChArUco board's: this share of the white gap between a square's corner and its marker
CHARUCO_GAP_SHARE = 0.8
#: half-window limits (px)
SUBPIX_LIMITS = (2, 15)
#: the windows of the focal length's sensitivity, as factors of the chosen one
SENSITIVITY_FACTORS = (0.75, 1.25)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg")
#: video frames searched for the board (evenly spread over the video)
VIDEO_VIEWS = 40


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
    ``image_points (K,2)`` px, ``object_points (K,3)`` mm; ``coarse (K,2)`` px the corners before the sub-pixel
    refinement and ``window_px`` its half-window."""

    ids: np.ndarray
    image_points: np.ndarray
    object_points: np.ndarray
    coarse: np.ndarray | None = None
    window_px: int = 5


def _grey(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image


def smallest_square_px(points: np.ndarray, ids: np.ndarray, spec: BoardSpec) -> float:
    """The smallest distance (px) between corners ``points (K,2)`` that are neighbours on the board (one square
    side apart), from their ``ids (K,)``; inf when no two neighbours are seen."""
    columns = spec.inner_corners[0]
    place = {int(corner): index for index, corner in enumerate(ids)}
    sides = []
    for corner, index in place.items():
        for neighbour in ((corner + 1) if (corner + 1) % columns else None, corner + columns):
            if neighbour is not None and neighbour in place:
                sides.append(float(np.linalg.norm(points[index] - points[place[neighbour]])))
    return min(sides) if sides else float("inf")


def subpixel_window(points: np.ndarray, ids: np.ndarray, spec: BoardSpec) -> int:
    """The half-window (px) of the sub-pixel corner search in an image whose corners are ``points (K,2)``: a share
    of the smallest square side there (see the module docstring), within :data:`SUBPIX_LIMITS`."""
    side = smallest_square_px(points, ids, spec)
    if not np.isfinite(side):
        return 3 if spec.kind == "charuco" else 5
    if spec.kind == "charuco":
        gap = (spec.square_mm - spec.marker_mm) / (2.0 * spec.square_mm)
        half = CHARUCO_GAP_SHARE * gap * side
    else:
        half = SUBPIX_SHARE * side
    return int(np.clip(round(half), *SUBPIX_LIMITS))


def refine_corners(grey: np.ndarray, coarse: np.ndarray, window: int) -> np.ndarray:
    """``cv2.cornerSubPix`` of ``coarse (K,2)`` px with the half-window ``window`` px: (K,2) px."""
    corners = cv2.cornerSubPix(grey, np.asarray(coarse, np.float32).reshape(-1, 1, 2), (window, window), (-1, -1),
                               _SUBPIX_CRITERIA)
    return corners.reshape(-1, 2).astype(float)


def find_corners(grey: np.ndarray, spec: BoardSpec) -> tuple[np.ndarray, np.ndarray] | None:
    """The board's coarse corners ``(ids (K,), points (K,2) px)`` in a grey image, before any sub-pixel
    refinement; None when fewer than :data:`MIN_CORNERS` are found (or, for ChArUco, they are collinear)."""
    if spec.kind == "charuco":
        board = spec.charuco_board()
        corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(grey)
        if ids is None or len(ids) < MIN_CORNERS or board.checkCharucoCornersCollinear(ids):
            return None
        return ids.ravel(), np.asarray(corners, float).reshape(-1, 2)
    found, corners = cv2.findChessboardCorners(grey, spec.inner_corners, flags=_CHESSBOARD_FLAGS)
    if not found:
        return None
    return np.arange(len(corners)), np.asarray(corners, float).reshape(-1, 2)


def detect_board(image: np.ndarray, spec: BoardSpec, window: int | None = None) -> Detection | None:
    """The board's corners in ``image`` (BGR or grey), refined to sub-pixel with the half-window ``window`` px
    (default: from the square's size in the image, :func:`subpixel_window`); None when fewer than
    :data:`MIN_CORNERS` are found (or, for ChArUco, they are collinear)."""
    grey = _grey(image)
    found = find_corners(grey, spec)
    if found is None:
        return None
    ids, coarse = found
    half = subpixel_window(coarse, ids, spec) if window is None else int(window)
    return Detection(ids, refine_corners(grey, coarse, half), spec.object_points()[ids], coarse, half)


@dataclass
class BoardView:
    """One image to look for the board in: its ``name`` (a file, or a video and frame) and how to read it."""

    name: str
    read: Callable[[], np.ndarray]


def _read_image(path: Path) -> np.ndarray:
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as error:
        raise InputError(f"cannot read {path} ({error.strerror or error})") from None
    image = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"{path.name}: OpenCV cannot decode this image")
    return image


@dataclass
class BoardViews:
    """The views to calibrate from: ``views``, their common ``size`` (w, h) px, and the ``skipped`` ones (name,
    size) of another size."""

    views: list[BoardView]
    size: tuple[int, int]
    skipped: list[tuple[str, tuple[int, int]]]


def board_views(inputs: list[str | Path], video_views: int = VIDEO_VIEWS, mixed_sizes: str = "skip") -> BoardViews:
    """The board views of ``inputs``: image files, folders (their images in natural name order) and videos
    (``video_views`` frames evenly spread). One camera has one image size: views of another size than most are
    set aside (``mixed_sizes="skip"``; a folder may hold a stray photograph) or refused (``"refuse"``)."""
    from handmocap.core.camera.frames import open_frames

    views: list[BoardView] = []
    sizes: list[tuple[int, int]] = []
    for given in inputs:
        path = Path(given)
        if path.is_dir():
            images = sorted((p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
                            key=_natural_key)
            if not images:
                raise InputError(f"{path}: no {'/'.join(s[1:].upper() for s in IMAGE_SUFFIXES[:3])} images in the "
                                 "folder")
            for image in images:
                sizes.append(image_file_size(image))
                views.append(BoardView(image.name, partial(_read_image, image)))
        elif path.suffix.lower() in VIDEO_SUFFIXES:
            video = open_frames(path)
            chosen = np.unique(np.linspace(0, video.count - 1, min(max(video_views, 1), video.count)).astype(int))
            for index in chosen:
                sizes.append(video.size)
                views.append(BoardView(f"{path.name} frame {index + 1}", partial(video.frame, int(index))))
        elif path.is_file():
            sizes.append(image_file_size(path))
            views.append(BoardView(path.name, partial(_read_image, path)))
        else:
            raise InputError(f"{path} does not exist (give board images, folders of them or videos)")
    if not views:
        raise InputError("no board images to calibrate from")
    if mixed_sizes == "refuse":
        size = sizes[0]
    else:
        kinds, counts = np.unique(np.array(sizes), axis=0, return_counts=True)
        most = kinds[counts == counts.max()]
        size = next(candidate for candidate in sizes if any((candidate == tuple(k)) for k in most))
    kept, skipped = [], []
    for view, other in zip(views, sizes, strict=True):
        if other == size:
            kept.append(view)
        elif mixed_sizes == "refuse":
            raise InputError(f"{view.name} is {other[0]}×{other[1]} px but the first image is {size[0]}×{size[1]}")
        else:
            skipped.append((view.name, other))
    return BoardViews(kept, (int(size[0]), int(size[1])), skipped)


def _natural_key(path: Path) -> list:
    import re

    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def detect_board_in_views(views: list[BoardView], spec: BoardSpec, before: Callable[[int], None] | None = None
                          ) -> list[Detection | None]:
    """The board in each view (None where not found). ``before(k)`` is called before view k is read (a worker's
    progress and cancellation)."""
    detections: list[Detection | None] = []
    for index, view in enumerate(views):
        if before is not None:
            before(index)
        detections.append(detect_board(view.read(), spec))
    return detections


def detect_board_in_files(paths: list[Path], spec: BoardSpec, before: Callable[[int], None] | None = None
                          ) -> tuple[list[Detection | None], tuple[int, int]]:
    """The board in each image file (None where not found) and the images' common size (w, h) px; every
    image must have the first one's size. ``before(k)`` is called before image k is read (a worker's
    progress and cancellation)."""
    if not paths:
        raise InputError("no board images to calibrate from")
    found = board_views(list(paths), mixed_sizes="refuse")
    return detect_board_in_views(found.views, spec, before), found.size


def board_hint(views: list[BoardView], spec: BoardSpec, tries: int = 4) -> str | None:
    """Why the board is not found, when another size or kind is: the other readings of the given numbers (inner
    corners for squares, the other kind of board, rows and columns exchanged) tried on up to ``tries`` views
    spread over the set; the line names the options that fit, e.g. "found as a chessboard of 9×6 inner corners
    in 4 of 4 images tried: use --board chessboard --squares 10x7 (or --inner-corners 9x6)"; None when none
    fits."""
    picks = np.unique(np.linspace(0, len(views) - 1, min(tries, len(views))).astype(int))
    greys = [_grey(views[index].read()) for index in picks]
    columns, rows = spec.squares
    readings: list[BoardSpec] = []
    for kind in (spec.kind, "chessboard" if spec.kind == "charuco" else "charuco"):
        for squares in ((columns + 1, rows + 1), (columns, rows), (rows + 1, columns + 1), (rows, columns),
                        (columns - 1, rows - 1)):
            if kind == spec.kind and squares == spec.squares:
                continue
            try:
                readings.append(BoardSpec(kind, squares, spec.square_mm, spec.marker_mm, spec.dictionary))
            except InputError:
                continue
    for reading in readings:
        found = sum(find_corners(grey, reading) is not None for grey in greys)
        if found:
            inner = reading.inner_corners
            kind = "" if reading.kind == spec.kind else f"--board {reading.kind} "
            board = "a chessboard" if reading.kind == "chessboard" else "a ChArUco board"
            return (f"found as {board} of {inner[0]}×{inner[1]} inner corners ({reading.squares[0]}×"
                    f"{reading.squares[1]} squares) in {found} of {len(greys)} images tried: use {kind}--squares "
                    f"{reading.squares[0]}x{reading.squares[1]} (or {kind}--inner-corners {inner[0]}x{inner[1]})")
    return None


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
    previous = np.full(len(detections), np.nan)
    while True:
        camera, errors = _calibrate(_used(detections, used), image_size, name)
        view_errors = previous.copy()       # a view left out keeps the error it was left out for
        view_errors[used] = errors
        median = float(np.median(errors))
        spread = 1.4826 * float(np.median(np.abs(errors - median)))
        threshold = max(median + REJECT_SIGMAS * spread, 2.0 * median)
        bad = used & (view_errors > threshold)
        if not bad.any() or used.sum() - bad.sum() < MIN_VIEWS:
            break
        used &= ~bad
        previous = view_errors
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


def calibrate_views(views: list[BoardView], image_size: tuple[int, int], spec: BoardSpec, name: str = "camera",
                    before: Callable[[int], None] | None = None) -> tuple[IntrinsicCalibration, dict]:
    """Detect the board in every view and calibrate: ``(calibration, sensitivity)`` (:func:`window_sensitivity`).
    When the board is found in too few views the one-line error says which size or kind was found instead
    (:func:`board_hint`)."""
    detections = detect_board_in_views(views, spec, before)
    found = sum(detection is not None for detection in detections)
    if found < MIN_VIEWS:
        columns, rows = spec.squares
        inner = spec.inner_corners
        what = (f"a {spec.kind} of {columns}×{rows} squares ({inner[0]}×{inner[1]} inner corners)")
        hint = board_hint(views, spec)
        raise InputError(f"the board ({what}) was found in {found} of {len(views)} images; "
                         + (hint if hint else f"calibration needs at least {MIN_VIEWS}: check --board and --squares"
                                              " (squares across x down; --inner-corners for inner corners)"))
    calibration = calibrate_intrinsics(detections, image_size, name)
    return calibration, window_sensitivity(views, detections, calibration.used, image_size)


def window_sensitivity(views: list[BoardView], detections: list[Detection | None], used: np.ndarray,
                       image_size: tuple[int, int], factors: tuple[float, ...] = SENSITIVITY_FACTORS) -> dict:
    """How far the focal length moves when every image's sub-pixel half-window is scaled by ``factors``: the
    corners refined again from the same coarse corners, the same ``used (N,)`` views calibrated once (no
    rejection). ``{"window_px": [min, median, max] of the windows used, "focal_change_percent": {factor: %}}``
    (the mean of fx and fy against the calibration with the chosen windows)."""
    chosen = {index: detection for index, detection in enumerate(detections)
              if used[index] and detection is not None and detection.coarse is not None}
    if len(chosen) < MIN_VIEWS:
        return {}
    windows = np.array([detection.window_px for detection in chosen.values()])
    base, _ = _calibrate(list(chosen.values()), image_size, "base")
    focal = float(np.mean(base.focal))
    greys = {index: _grey(views[index].read()) for index in chosen}
    changes = {}
    for factor in factors:
        refined = []
        for index, detection in chosen.items():
            assert detection.coarse is not None
            half = int(np.clip(round(detection.window_px * factor), 1, 3 * SUBPIX_LIMITS[1]))
            refined.append(Detection(detection.ids, refine_corners(greys[index], detection.coarse, half),
                                     detection.object_points, detection.coarse, half))
        camera, _ = _calibrate(refined, image_size, "sensitivity")
        changes[f"{factor:g}x"] = round(100.0 * (float(np.mean(camera.focal)) - focal) / focal, 4)
    return {"window_px": [int(windows.min()), float(np.median(windows)), int(windows.max())],
            "focal_change_percent": changes}
