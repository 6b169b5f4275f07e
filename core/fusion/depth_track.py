"""Tracking a hand through a sequence of depth frames (thesis Ch. 6): each frame starts from the previous frame's
pose and from its constant-velocity prediction (warm start), the articulated ICP adds the temporal terms
(velocity and acceleration of the chain's points against the two previous frames, eq. 6.9) to the single-frame
terms, and the hand is re-initialised by the single-frame fit (:class:`core.fusion.depth_fit.DepthFitter`:
segmentation, several starts) whenever the tracked fit is not trusted or the hand is not where the previous
frame left it. The hand's size (the model's scale) is estimated on the first trusted frames, then kept (their
median).

Also the depth-image readers and the ``FX,FY,CX,CY`` intrinsics the ``handmocap depth`` commands take.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from handmocap.core.camera.frames import image_file_size
from handmocap.core.camera.model import Camera
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.fusion.depth_fit import DepthFit, DepthFitSettings, DepthFitter
from handmocap.core.fusion.hand_segment import HandCandidate, find_hands
from handmocap.core.fusion.icp import FitExtras
from handmocap.core.model.kinematics import rotation_from_vector, vector_from_rotation

#: the hand's size is estimated on this many trusted frames, then kept (their median)
SCALE_FRAMES = 5
#: depth PNG files the track command reads from a folder
DEPTH_SUFFIXES = (".png",)


@dataclass(frozen=True)
class TrackSettings:
    """The single-frame fit (re-initialisation), the warm rounds, the temporal weights (per mm² of a chain
    point's velocity / acceleration, mean over the points) and how far the palm may move between frames (mm)."""

    fit: DepthFitSettings = field(default_factory=DepthFitSettings)
    rounds: int = 2
    velocity_weight: float = 0.02
    acceleration_weight: float = 0.01
    max_palm_move_mm: float = 150.0


@dataclass
class TrackedFrame:
    """One frame of a track: ``name``, ``fit``, ``mode``: "initialised" (first fit), "tracked" (warm start),
    "re-initialised" (the warm fit was not trusted or the hand moved away; the single-frame fit replaced it) or
    "lost" (no fit trusted)."""

    name: str
    fit: DepthFit
    mode: str

    def to_dict(self) -> dict:
        return {"frame": self.name, "mode": self.mode, **self.fit.to_dict()}


class DepthTracker:
    """Frame-by-frame tracking (see the module docstring); :meth:`step` takes one depth frame (mm)."""

    def __init__(self, camera: Camera, side: str = "right", settings: TrackSettings | None = None) -> None:
        self.settings = settings or TrackSettings()
        fit_settings = self.settings.fit
        tracking_icp = replace(fit_settings.icp, velocity_weight=self.settings.velocity_weight,
                               acceleration_weight=self.settings.acceleration_weight)
        self.fitter = DepthFitter(camera, side, fit_settings)
        self.warm = DepthFitter(camera, side, replace(fit_settings, icp=tracking_icp), self.fitter.base_model,
                                self.fitter.prior)
        self.camera = camera
        self.history: list[np.ndarray] = []     # chain points (21,3) of the last two trusted frames
        self.previous: DepthFit | None = None
        self.scales: list[float] = []
        self.warm_fit: DepthFit | None = None
        self.before: np.ndarray | None = None    # the pose of the frame before the previous one (both trusted)

    @property
    def scale(self) -> float | None:
        """The hand's size taken from the trusted frames so far (median), None before the first."""
        return float(np.median(self.scales)) if self.scales else None

    def step(self, depth: np.ndarray, cancelled: Callable[[], bool] | None = None) -> tuple[DepthFit, str]:
        """Fit one frame: ``(fit, mode)`` (see :class:`TrackedFrame`)."""
        mode = "tracked"
        fit = None
        if self.previous is not None and self.previous.trusted:
            candidate = self._candidate_near(depth, self.previous)
            if candidate is not None:
                fit = self._warm_fit(depth, candidate)
        self.warm_fit = fit
        if fit is None or not fit.trusted:
            mode = "initialised" if self.previous is None else "re-initialised"
            settled = self.scale if len(self.scales) >= SCALE_FRAMES else None
            fresh = self.fitter.fit(depth, cancelled, scale=settled)
            if fit is None or fresh.trusted or fresh.energy < fit.energy:
                fit = fresh
            if not fit.trusted:
                mode = "lost"
        self.before = self.previous.theta if self.previous is not None and self.previous.trusted and fit.trusted \
            else None
        if fit.trusted:
            if len(self.scales) < SCALE_FRAMES:
                self.scales.append(fit.scale)
            points = self.fitter.for_scale(fit.scale).chain.evaluate(fit.theta)[0]
            self.history = ([points] + self.history)[:2]
        else:
            self.history = []
        self.previous = fit
        return fit, mode

    def _candidate_near(self, depth: np.ndarray, previous: DepthFit) -> HandCandidate | None:
        """The hand candidate whose palm is nearest the previous palm, within ``max_palm_move_mm``."""
        candidates = find_hands(depth, self.camera, self.settings.fit.segment)
        best, best_distance = None, self.settings.max_palm_move_mm
        previous_palm = self.camera.back_project(previous.palm_uv[None], np.array([previous.palm_depth_mm]))[0]
        for candidate in candidates:
            palm = self.camera.back_project(candidate.palm_px[None], np.array([candidate.palm_depth_mm]))[0]
            distance = float(np.linalg.norm(palm - previous_palm))
            if distance < best_distance and not any("too large" in p or "continues" in p for p in candidate.problems):
                best, best_distance = candidate, distance
        return best

    def _warm_fit(self, depth: np.ndarray, candidate: HandCandidate) -> DepthFit:
        """The previous pose refined on ``candidate`` with the temporal terms."""
        assert self.previous is not None
        warm = self.warm.for_scale(self.previous.scale)
        history = None
        if self.history:
            history = (self.history[0], self.history[1] if len(self.history) > 1 else None)
        extras = FitExtras(wrist_line=candidate.arm_line_px, history=history)
        starts = [self.previous.theta]
        if self.before is not None:
            # constant velocity of the wrist (translation and rotation) from the two previous frames
            predicted = self.previous.theta.copy()
            predicted[0:3] += self.previous.theta[0:3] - self.before[0:3]
            turn = rotation_from_vector(self.previous.theta[3:6]) @ rotation_from_vector(self.before[3:6]).T
            predicted[3:6] = vector_from_rotation(turn @ rotation_from_vector(self.previous.theta[3:6]))
            starts.append(predicted)
        best = None
        for start in starts:
            theta = warm.refine(start, depth, candidate.mask, extras, rounds=self.settings.rounds,
                                candidate=candidate)
            judged = warm.judge(theta, depth, candidate, candidate.mask)
            if best is None or judged.energy < best.energy:
                best = judged
        assert best is not None
        return best


def track_depth_frames(frames: Sequence[np.ndarray], camera: Camera, names: Sequence[str] | None = None,
                       side: str = "right", settings: TrackSettings | None = None,
                       progress: Callable[[float], None] | None = None,
                       cancelled: Callable[[], bool] | None = None) -> list[TrackedFrame]:
    """Track the hand through ``frames`` (depth (H,W) mm each, in order): one :class:`TrackedFrame` per frame."""
    tracker = DepthTracker(camera, side, settings)
    names = list(names) if names is not None else [str(index) for index in range(len(frames))]
    result = []
    for index in range(len(frames)):
        if cancelled is not None and cancelled():
            raise CancelledError("depth tracking cancelled")
        started = time.perf_counter()
        fit, mode = tracker.step(frames[index], cancelled)
        fit.seconds = time.perf_counter() - started
        result.append(TrackedFrame(names[index], fit, mode))
        if progress is not None:
            progress((index + 1) / len(frames))
    return result


def parse_intrinsics(text: str, size: tuple[int, int], name: str = "depth camera") -> Camera:
    """A distortion-free camera of ``size`` (w, h) px from ``"FX,FY,CX,CY"`` (px)."""
    parts = [part.strip() for part in str(text).split(",")]
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) != 4 or not all(np.isfinite(values)):
        raise InputError(f"intrinsics must be four numbers FX,FY,CX,CY (px), not '{text}'")
    fx, fy, cx, cy = values
    if fx <= 0 or fy <= 0:
        raise InputError(f"focal lengths must be positive, got {fx:g} and {fy:g} px")
    width, height = size
    if not (0 <= cx <= width and 0 <= cy <= height):
        raise InputError(f"principal point ({cx:g}, {cy:g}) px lies outside the {width}×{height} px frame")
    matrix = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return Camera(matrix, np.zeros(5), size, registered=True, name=name)


def read_depth_image(path: str | Path, unit_mm: float) -> np.ndarray:
    """A 16-bit one-channel PNG depth frame in mm (value × ``unit_mm``; 0 = no depth), checked: a regular file,
    a sane size from its header before decoding, 16 bits, one channel, some depth."""
    path = Path(path)
    if not (np.isfinite(unit_mm) and 0 < unit_mm <= 100):
        raise InputError(f"the depth unit must be within 0..100 mm, got {unit_mm:g}")
    if path.is_dir():
        raise InputError(f"{path} is a folder; 'depth fit' takes one 16-bit PNG frame ('depth track' a folder)")
    if not path.is_file():
        raise InputError(f"{path} does not exist or is not a file")
    if path.suffix.lower() not in DEPTH_SUFFIXES:
        raise InputError(f"{path.name}: a depth frame must be a 16-bit PNG")
    image_file_size(path)
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as error:
        raise InputError(f"cannot read {path} ({error.strerror or error})") from None
    try:
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        image = None
    if image is None:
        raise InputError(f"{path.name}: OpenCV cannot decode this image")
    if image.dtype != np.uint16 or image.ndim != 2:
        channels = 1 if image.ndim == 2 else image.shape[2]
        raise InputError(f"{path.name}: a depth frame must be a 16-bit one-channel PNG, got {image.dtype} with "
                         f"{channels} channel{'s' if channels > 1 else ''}")
    if not image.any():
        raise InputError(f"{path.name}: the frame holds no depth (every pixel is 0)")
    return image.astype(np.float32) * np.float32(unit_mm)


def depth_frame_paths(folder: str | Path) -> list[Path]:
    """The 16-bit PNG frames of ``folder`` in natural name order (``2.png`` before ``10.png``)."""
    import re

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder} does not exist or is not a folder of depth frames")
    paths = [path for path in folder.iterdir() if path.suffix.lower() in DEPTH_SUFFIXES and path.is_file()]
    if not paths:
        raise InputError(f"{folder}: no PNG depth frames")

    def key(path: Path) -> list:
        return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]
    return sorted(paths, key=key)
