"""Finding the hand in a depth frame without colour: a hand-sized object, not simply the nearest one.

The frame is split into surfaces at depth jumps; in every surface the palm candidates are the local maxima of
the distance to the surface's outline, measured in millimetres (a palm is 25–60 mm from its centre to its
edge; a torso or a chair seat much more, a finger much less). Around each candidate the pixels within a hand's
reach in 3D (the palm centre to the tip of the middle finger is ≈ 130 mm) form the candidate hand, which is
scored on what makes a hand:

- **distance band**: the candidate lies within the camera's working range (``near_mm``..``far_mm``);
- **size**: its physical area (cm², from the pixel footprint at its depth) against a hand's, and the share of
  the reach disc it fills (a hand fills a third of it, a wall or a torso all of it);
- **shape**: thin protrusions of finger width around the palm (open fingers), and how the object leaves the
  reach sphere: through one arm-wide exit (a hand at the end of its arm) or none (the arm out of view), not two
  or more (the middle of an arm, a torso), and how much of its outline the surface continues across (a
  forearm's cut, not the long cut of a torso or a seat);
- **occlusion**: a hand in front of the scene has farther surfaces (or nothing) around it; a piece of a body
  seen between nearer things has nearer surfaces along its outline;
- **border**: a hand that touches the image border is partly out of view;
- **nearness**: a small bonus for being nearer than the rest of the scene (hands are held in front), which
  decides only between otherwise equal candidates.

Everything is computed on the ideal (undistorted) depth image in mm; no colour is needed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.errors import InputError


@dataclass(frozen=True)
class SegmentSettings:
    """Sizes (mm) of a hand and of the search."""

    #: working range of the depth camera (mm): pixels outside are ignored
    near_mm: float = 150.0
    far_mm: float = 2000.0
    #: neighbouring pixels further apart than max(jump_mm, jump_share · depth) belong to different surfaces
    jump_mm: float = 15.0
    jump_share: float = 0.025
    #: palm half-width range (mm): the distance from the palm centre to the outline
    palm_radius_mm: tuple[float, float] = (22.0, 62.0)
    #: typical palm half-width (mm) of the score
    palm_radius_typical_mm: float = 42.0
    #: 3D radius (mm) around the palm centre that holds the hand (palm centre to middle fingertip ≈ 130 mm)
    reach_mm: float = 150.0
    #: physical area (cm²) of a hand seen from any side, with a short piece of forearm: a fist seen end-on to an open
    #: hand seen flat
    area_cm2: tuple[float, float] = (35.0, 320.0)
    #: finger width (mm): protrusions thinner than this around the palm are fingers
    finger_width_mm: float = 26.0
    #: an exit of the reach sphere wider than this (mm) is an arm (or a larger body part)
    arm_width_mm: float = 38.0
    #: the surface may continue beyond the hand's reach along at most this much of its outline (mm): a forearm's
    #: cut, seen obliquely; a torso or a seat continues along far more
    open_outline_mm: float = 140.0
    #: at most this share of its outline may lie behind a nearer surface, one at least ``occluder_mm`` nearer (a
    #: finger bent towards the camera is a nearer surface of the hand itself, a few centimetres only)
    max_hidden: float = 0.15
    occluder_mm: float = 60.0
    #: surfaces smaller than this (cm²) are noise
    min_surface_cm2: float = 15.0
    #: candidates examined per frame (the best by palm radius first)
    max_candidates: int = 24


@dataclass
class HandCandidate:
    """One candidate hand: ``mask (H,W) bool`` (its pixels), ``palm_px (2,)`` (u, v) and ``palm_depth_mm`` of
    the palm centre, ``palm_radius_mm``, ``area_cm2``, ``fill`` share of the reach disc, ``fingers`` thin
    protrusions, ``finger_px (F,2)`` their far ends and ``finger_mm (F,3)`` those ends in the camera frame,
    ``exits`` arm-wide exits of the reach sphere, ``open_mm`` the length of its outline where the surface
    continues beyond the reach (the forearm's cut, or a larger surface's), ``hidden`` the share of its outline
    behind which a nearer surface lies, ``arm_direction_px (2,)`` unit image
    direction from the palm to the widest arm exit or None, ``arm_line_px`` the forearm's image axis (point (2,),
    direction (2,) towards the elbow) or None, ``touches_border``, ``nearness`` (0..1: share of the scene
    behind it), ``score`` (higher is more hand-like) and ``problems`` (why it may not be a hand)."""

    mask: np.ndarray
    palm_px: np.ndarray
    palm_depth_mm: float
    palm_radius_mm: float
    area_cm2: float
    fill: float
    fingers: int
    finger_px: np.ndarray
    finger_mm: np.ndarray
    exits: int
    open_mm: float
    hidden: float
    arm_direction_px: np.ndarray | None
    arm_line_px: tuple[np.ndarray, np.ndarray] | None
    touches_border: bool
    nearness: float
    score: float
    problems: list[str] = field(default_factory=list)

    def box(self) -> tuple[int, int, int, int]:
        """(left, top, right, bottom) px of the mask."""
        rows, columns = np.nonzero(self.mask)
        return int(columns.min()), int(rows.min()), int(columns.max()), int(rows.max())

    def summary(self) -> dict:
        """Plain numbers for a report."""
        return {"palm_px": [round(float(v), 1) for v in self.palm_px], "palm_depth_mm": round(self.palm_depth_mm, 1),
                "palm_radius_mm": round(self.palm_radius_mm, 1), "area_cm2": round(self.area_cm2, 1),
                "fill": round(self.fill, 3), "fingers": self.fingers, "exits": self.exits,
                "open_outline_mm": round(self.open_mm, 1), "hidden_outline": round(self.hidden, 3),
                "touches_border": self.touches_border, "nearness": round(self.nearness, 3),
                "score": round(self.score, 3), "box": list(self.box()), "problems": list(self.problems)}


def surfaces(depth: np.ndarray, settings: SegmentSettings) -> tuple[np.ndarray, int]:
    """Connected surfaces of ``depth (H,W)`` mm: ``(labels (H,W) int32, 0 = none, count)``; neighbours further
    apart in depth than the jump threshold are not connected."""
    valid = (depth > settings.near_mm) & (depth < settings.far_mm)
    values = np.where(valid, depth, 0.0).astype(np.float32)
    threshold = np.maximum(settings.jump_mm, settings.jump_share * values)
    apart = np.zeros(depth.shape, dtype=bool)
    horizontal = np.abs(np.diff(values, axis=1)) > np.minimum(threshold[:, 1:], threshold[:, :-1])
    vertical = np.abs(np.diff(values, axis=0)) > np.minimum(threshold[1:, :], threshold[:-1, :])
    # the nearer pixel of a jump keeps its surface, the farther one is cut (the foreground keeps its outline)
    apart[:, 1:] |= horizontal & (values[:, 1:] > values[:, :-1])
    apart[:, :-1] |= horizontal & (values[:, :-1] > values[:, 1:])
    apart[1:, :] |= vertical & (values[1:, :] > values[:-1, :])
    apart[:-1, :] |= vertical & (values[:-1, :] > values[1:, :])
    count, labels = cv2.connectedComponents((valid & ~apart).astype(np.uint8), connectivity=4)
    return labels.astype(np.int32), int(count)


def _pixel_size(depth: np.ndarray, focal: float) -> np.ndarray:
    """Side (mm) of a pixel's footprint at its depth."""
    return depth / focal


def _disc(radius_px: float) -> np.ndarray:
    size = 2 * max(1, int(round(radius_px))) + 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))


def find_hands(depth: np.ndarray, camera: Camera, settings: SegmentSettings | None = None) -> list[HandCandidate]:
    """Hand candidates in ``depth (H,W)`` mm (0 = none, ideal pinhole image of ``camera``), most hand-like
    first (see the module docstring); empty when nothing of a palm's size is seen."""
    settings = settings or SegmentSettings()
    depth = np.asarray(depth, dtype=np.float32)
    if depth.ndim != 2 or depth.shape != (camera.height, camera.width):
        raise InputError(f"the depth frame is {depth.shape[-1]}×{depth.shape[0]} px but the camera is "
                         f"{camera.width}×{camera.height}")
    focal = float(np.mean(camera.focal))
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    labels, count = surfaces(depth, settings)
    valid_depths = depth[(depth > settings.near_mm) & (depth < settings.far_mm)]
    if len(valid_depths) == 0:
        return []
    scene_depths = np.sort(valid_depths)
    pixel_mm = _pixel_size(depth, focal)
    height, width = depth.shape
    rows_all, columns_all = np.indices(depth.shape)
    raw: list[tuple[float, int, int, int]] = []
    stats = [(label, int((labels == label).sum())) for label in range(1, count)]
    for label, size in stats:
        if size < 30:
            continue
        surface = labels == label
        area_cm2 = float((pixel_mm[surface] ** 2).sum()) / 100.0
        if area_cm2 < settings.min_surface_cm2:
            continue
        distance_px = cv2.distanceTransform(surface.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        distance_mm = distance_px * pixel_mm
        low, high = settings.palm_radius_mm
        local_size = max(3, int(round(low * focal / max(float(np.median(depth[surface])), 1.0))))
        peaks = (distance_mm >= low) & (distance_mm <= high) & surface & (
            distance_px >= cv2.dilate(distance_px, _disc(local_size)) - 1e-3)
        for row, column in zip(*np.nonzero(peaks), strict=True):
            raw.append((float(distance_mm[row, column]), label, int(row), int(column)))
    # keep well-separated peaks, nearest to the typical palm size first
    raw.sort(key=lambda item: abs(item[0] - settings.palm_radius_typical_mm))
    chosen: list[tuple[float, int, int, int]] = []
    for item in raw:
        _, label, row, column = item
        separation = 25.0 * focal / max(float(depth[row, column]), 1.0)
        if all(other[1] != label or np.hypot(other[2] - row, other[3] - column) > separation for other in chosen):
            chosen.append(item)
        if len(chosen) >= settings.max_candidates:
            break
    candidates = []
    for radius_mm, label, row, column in chosen:
        surface = labels == label
        candidates.append(_candidate(depth, surface, row, column, radius_mm, settings, focal, (fx, fy), (cx, cy),
                                     pixel_mm, rows_all, columns_all, scene_depths, (width, height)))
    candidates.sort(key=lambda candidate: -candidate.score)
    return candidates


@dataclass
class _Window:
    """The pixels around one palm candidate: ``inside`` (the candidate), its ``surface``, ``depth``, camera-frame
    ``points`` (h,w,3), ``distance`` to the palm centre (mm), image ``rows``/``columns``, pixel size ``pixel_mm``."""

    inside: np.ndarray
    surface: np.ndarray
    depth: np.ndarray
    points: np.ndarray
    distance: np.ndarray
    rows: np.ndarray
    columns: np.ndarray
    pixel_mm: np.ndarray


def _candidate(depth: np.ndarray, surface: np.ndarray, row: int, column: int, radius_mm: float,
               settings: SegmentSettings, focal: float, focals: tuple[float, float], principal: tuple[float, float],
               pixel_mm: np.ndarray, rows_all: np.ndarray, columns_all: np.ndarray, scene_depths: np.ndarray,
               size: tuple[int, int]) -> HandCandidate:
    """Measure the candidate hand around the palm peak (row, column) of ``surface``."""
    (fx, fy), (cx, cy) = focals, principal
    width, height = size
    window = max(3, int(round(radius_mm * 0.5 * focal / max(float(depth[row, column]), 1.0))))
    patch = depth[max(row - window, 0):row + window + 1, max(column - window, 0):column + window + 1]
    patch_surface = surface[max(row - window, 0):row + window + 1, max(column - window, 0):column + window + 1]
    palm_depth = float(np.median(patch[patch_surface])) if patch_surface.any() else float(depth[row, column])
    centre = np.array([(column - cx) / fx * palm_depth, (row - cy) / fy * palm_depth, palm_depth])
    reach_px = int(np.ceil(settings.reach_mm * focal / max(palm_depth - settings.reach_mm, 50.0)))
    top, bottom = max(row - reach_px, 0), min(row + reach_px + 1, height)
    left, right = max(column - reach_px, 0), min(column + reach_px + 1, width)
    sub_depth = depth[top:bottom, left:right].astype(float)
    sub_rows, sub_columns = rows_all[top:bottom, left:right], columns_all[top:bottom, left:right]
    points = np.stack([(sub_columns - cx) / fx * sub_depth, (sub_rows - cy) / fy * sub_depth, sub_depth], axis=-1)
    distance = np.linalg.norm(points - centre, axis=-1)
    inside = surface[top:bottom, left:right] & (distance <= settings.reach_mm)
    mask = np.zeros(depth.shape, dtype=bool)
    mask[top:bottom, left:right] = inside
    # the part connected to the palm only
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if count > 2 and labels[row, column] > 0:
        mask = labels == labels[row, column]
        inside = mask[top:bottom, left:right]
    area = _Window(inside, surface[top:bottom, left:right], sub_depth, points, distance, sub_rows, sub_columns,
                   pixel_mm[top:bottom, left:right])
    area_cm2 = float((area.pixel_mm[inside] ** 2).sum()) / 100.0
    fill = area_cm2 / (np.pi * (settings.reach_mm / 10.0) ** 2)
    palm = np.array([float(column), float(row)])
    exits, exit_pixels, arm_direction, arm_line = _exits(area, palm, settings, float(pixel_mm[row, column]))
    finger_ends, finger_points = _fingers(area, exit_pixels, radius_mm, palm_depth / focal, settings)
    hidden = _hidden_share(area, settings)
    # where the surface continues beyond the hand's reach: the mask's outline next to the same surface outside it
    outside_surface = area.surface & ~inside
    open_outline = inside & cv2.dilate(outside_surface.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    open_mm = float(area.pixel_mm[open_outline].sum())
    border = 2
    touches_border = bool(mask[:border].any() or mask[-border:].any() or mask[:, :border].any()
                          or mask[:, -border:].any())
    nearness = 1.0 - float(np.searchsorted(scene_depths, palm_depth)) / len(scene_depths)
    score, problems = _score(radius_mm, area_cm2, fill, len(finger_ends), exits, open_mm, hidden, touches_border,
                             nearness, settings)
    return HandCandidate(mask, palm, palm_depth, radius_mm, area_cm2, fill, len(finger_ends), finger_ends,
                         finger_points, exits, open_mm, hidden, arm_direction, arm_line, touches_border, nearness,
                         score, problems)


def _exits(area: _Window, palm: np.ndarray, settings: SegmentSettings, pixel_at_palm: float
           ) -> tuple[int, np.ndarray, np.ndarray | None, tuple[np.ndarray, np.ndarray] | None]:
    """Where the object crosses the outer shell of the reach sphere at least an arm wide: ``(count, their pixels,
    the unit image direction from the palm to the widest, the forearm's image axis)``."""
    shell = area.inside & (area.distance > settings.reach_mm - 20.0)
    shell_count, shell_labels = cv2.connectedComponents(shell.astype(np.uint8), connectivity=8)
    exits, arm_direction, arm_line, widest = 0, None, None, 0.0
    exit_pixels = np.zeros(area.inside.shape, dtype=bool)
    for index in range(1, shell_count):
        part = shell_labels == index
        part_points = area.points[part]
        spread = float(np.ptp(part_points[:, :2], axis=0).max()) if len(part_points) > 1 else 0.0
        if spread < settings.arm_width_mm:
            continue
        exits += 1
        exit_pixels |= part
        if spread > widest:
            widest = spread
            exit_point = np.array([area.columns[part].mean(), area.rows[part].mean()])
            direction = exit_point - palm
            arm_direction = direction / max(float(np.linalg.norm(direction)), 1e-9)
            arm_line = _arm_axis(area.inside, area.columns, area.rows, palm, exit_point,
                                 settings.arm_width_mm / pixel_at_palm)
    return exits, exit_pixels, arm_direction, arm_line


def _fingers(area: _Window, exit_pixels: np.ndarray, radius_mm: float, pixel_at_palm: float,
             settings: SegmentSettings) -> tuple[np.ndarray, np.ndarray]:
    """Thin protrusions left when the object is opened by a disc of finger width (not the arm's cut end):
    their far ends ``(px (F,2), camera-frame mm (F,3))``."""
    inside = area.inside
    opened = cv2.morphologyEx(inside.astype(np.uint8), cv2.MORPH_OPEN,
                              _disc(0.5 * settings.finger_width_mm / pixel_at_palm)).astype(bool)
    thin = inside & ~opened
    near_exit = cv2.dilate(exit_pixels.astype(np.uint8), _disc(6.0 / pixel_at_palm)).astype(bool)
    thin_count, thin_labels = cv2.connectedComponents(thin.astype(np.uint8), connectivity=8)
    ends, points = [], []
    for index in range(1, thin_count):
        part = thin_labels == index
        if (part & near_exit).any():
            continue
        part_distance = area.distance[part]
        length = float(part_distance.max() - part_distance.min())
        thickness = float((area.pixel_mm[part] ** 2).sum()) / max(length, 1.0)
        if length >= 20.0 and length >= 1.8 * thickness and float(part_distance.max()) > radius_mm + 15.0:
            far = part_distance >= np.percentile(part_distance, 80)
            ends.append([float(area.columns[part][far].mean()), float(area.rows[part][far].mean())])
            points.append(area.points[part][far].mean(axis=0))
    return np.array(ends).reshape(-1, 2), np.array(points).reshape(-1, 3)


def _hidden_share(area: _Window, settings: SegmentSettings) -> float:
    """The share of the object's outline behind which a nearer surface lies: a piece of something occluded, or
    a hand partly hidden (a hand in front of the scene has farther surfaces or nothing around it)."""
    inside = area.inside
    outline = inside & ~cv2.erode(inside.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    around = np.where((area.depth > 0) & ~area.surface, area.depth, 1e6).astype(np.float32)   # other surfaces
    nearest_around = -cv2.dilate(-around, np.ones((11, 11), np.uint8))   # across a depth shadow too
    occluded = outline & (nearest_around < area.depth - settings.occluder_mm)
    return float(occluded.sum()) / max(int(outline.sum()), 1)


def _arm_axis(inside: np.ndarray, columns: np.ndarray, rows: np.ndarray, palm: np.ndarray, exit_point: np.ndarray,
              arm_width_px: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The forearm's image axis ``(point (2,), direction (2,))`` px: a line through the centres of slices across
    the object between half-way to the exit and the exit, in a corridor of three arm widths around the palm →
    exit line; None when fewer than three slices hold pixels."""
    reach = float(np.linalg.norm(exit_point - palm))
    if reach < 1.0:
        return None
    axis = (exit_point - palm) / reach
    offsets = np.stack([columns - palm[0], rows - palm[1]], axis=-1)
    along = offsets @ axis
    across = offsets @ np.array([-axis[1], axis[0]])
    corridor = inside & (np.abs(across) < 1.5 * arm_width_px)
    centres = []
    for position in np.linspace(0.5 * reach, reach, 6):
        band = corridor & (np.abs(along - position) < max(1.0, 0.05 * reach))
        if band.sum() >= 3:
            centres.append([float(columns[band].mean()), float(rows[band].mean())])
    if len(centres) < 3:
        return None
    points = np.array(centres)
    mean = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - mean).T))
    direction = vectors[:, 1] if vectors[:, 1] @ axis >= 0 else -vectors[:, 1]
    return mean, direction


def _score(radius_mm: float, area_cm2: float, fill: float, fingers: int, exits: int, open_mm: float, hidden: float,
           touches_border: bool, nearness: float, settings: SegmentSettings) -> tuple[float, list[str]]:
    """Hand-likeness (higher is better) and the reasons it may not be a hand."""
    problems = []
    score = -((radius_mm - settings.palm_radius_typical_mm) / 12.0) ** 2
    low, high = settings.area_cm2
    if area_cm2 < low:
        problems.append(f"too small for a hand ({area_cm2:.0f} cm², a hand ≥ {low:.0f})")
        score -= 2.0 * np.log(low / max(area_cm2, 1.0)) * 4
    elif area_cm2 > high:
        problems.append(f"too large for a hand ({area_cm2:.0f} cm², a hand ≤ {high:.0f})")
        score -= 2.0 * np.log(area_cm2 / high) * 4
    if fill > 0.62:
        problems.append(f"fills {100 * fill:.0f} % of a hand's reach (a flat or large surface)")
        score -= 20.0 * (fill - 0.62)
    score += 1.5 * min(fingers, 5)
    if exits >= 2:
        problems.append(f"continues on {exits} sides (part of an arm or a body, not a hand at its end)")
        score -= 3.0 * (exits - 1)
    if open_mm > settings.open_outline_mm:
        problems.append(f"its surface continues beyond a hand's reach along {open_mm:.0f} mm of its outline "
                        f"(a forearm's cut is ≤ {settings.open_outline_mm:.0f} mm: part of a larger surface)")
        score -= 2.0 * (open_mm - settings.open_outline_mm) / 100.0
    if hidden > settings.max_hidden:
        problems.append(f"{100 * hidden:.0f} % of its outline lies behind a nearer surface (partly hidden, or a "
                        "piece of something occluded)")
        score -= 6.0 * (hidden - settings.max_hidden)
    if touches_border:
        problems.append("touches the image border (partly out of view)")
        score -= 1.5
    score += 1.0 * nearness
    return float(score), problems
