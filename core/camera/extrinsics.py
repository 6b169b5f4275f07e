"""Extrinsic calibration: where the camera is in the mocap space (rotation, translation mm).

(a) From markers seen by both systems. Retro-reflective markers are bright blobs in the colour image
(:func:`detect_blobs`; with a depth image each blob also gets a 3D point in the camera frame). Blobs are
matched to the labelled 3D markers without knowing which is which: pose hypotheses come from P3P on
triples of blobs against every ordered triple of markers and are scored by the blobs they explain;
the best is refined over all frames by ``solvePnPRansac`` + Levenberg–Marquardt (colour only), or by a
RANSAC over 3D correspondences and a rigid least-squares (Kabsch) fit when there is depth (Zhao et al.
2012, §4). (b) From a ChArUco board whose outline carries markers measured by the mocap system.
Reports the reprojection error (px) and the 3D residual (mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, permutations

import cv2
import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.errors import InputError
from handmocap.core.ik import kabsch

#: a blob is a component brighter than the midpoint of ``level`` (the image's 99th percentile: scene content,
#: markers cover far less than 1 % of it) and the peak; its centre weighs the pixels within
#: :data:`BLOB_PAD` px by their brightness above the blob's local background (the median of a ring around it)
BLOB_CORE = 0.5
BLOB_PAD = 2
#: peak − level (grey levels) below which the image holds no bright markers
MIN_CONTRAST = 40.0
MIN_BLOB_AREA = 2
MAX_BLOB_SHARE = 0.01
#: match gate (px) for the hypothesis search: a marker within it explains a blob
SEARCH_GATE_PX = 8.0
#: blob triples tried per frame and frames tried
TRIPLES_PER_FRAME = 6
#: the search stops at a hypothesis that explains this share of a frame's blobs (or markers, if fewer)
EARLY_STOP = 0.8
SEARCH_FRAMES = 3
#: refinement passes; each gates matches at this multiple of the previous pass's median error
REFINE_PASSES = 4
GATE_FACTOR = 4.0
MIN_GATE_PX = 1.0
MIN_GATE_MM = 3.0
MIN_MATCHES = 6


@dataclass
class Blobs:
    """Bright blobs of one image: ``centres (K,2)`` px (intensity-weighted), ``areas (K,)`` px, ``points
    (K,3)`` camera-frame mm of the marker centres (NaN without depth)."""

    centres: np.ndarray
    areas: np.ndarray
    points: np.ndarray


def detect_blobs(camera: Camera, colour: np.ndarray, depth_mm: np.ndarray | None = None,
                 marker_radius: float = 3.0) -> Blobs:
    """Bright round blobs (retro-reflective markers) of a BGR image; with a depth image ``(H,W)`` mm
    (0 = none), the marker centre behind each blob: the median depth of the blob's core plus 0.7 ×
    ``marker_radius`` (the median of a sphere cap's depth over its disc), along the blob's ray."""
    # white markers are bright in every channel; skin is not bright in blue: use the darkest channel
    grey = (colour.min(axis=2) if colour.ndim == 3 else colour).astype(np.float32)
    level, peak = float(np.percentile(grey, 99.0)), float(grey.max())
    empty = Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 3)))
    if peak - level < MIN_CONTRAST:
        return empty
    core = (grey > level + BLOB_CORE * (peak - level)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(core, connectivity=8)
    kernel = np.ones((2 * BLOB_PAD + 1, 2 * BLOB_PAD + 1), np.uint8)
    centres, areas, points = [], [], []
    max_area = MAX_BLOB_SHARE * grey.size
    height, width = grey.shape
    for label in range(1, count):
        x, y, w, h, area = stats[label]
        if not MIN_BLOB_AREA <= area <= max_area or max(w, h) > 2.5 * min(w, h) or area < 0.4 * w * h:
            continue
        top, left = max(y - 2 * BLOB_PAD, 0), max(x - 2 * BLOB_PAD, 0)
        bottom, right = min(y + h + 2 * BLOB_PAD, height), min(x + w + 2 * BLOB_PAD, width)
        region = labels[top:bottom, left:right] == label
        grown = cv2.dilate(region.astype(np.uint8), kernel).astype(bool)
        patch = grey[top:bottom, left:right]
        ring = patch[~grown]
        base = float(np.median(ring)) if len(ring) else level
        weight = np.clip(patch - base, 0.0, None) * grown
        rows, columns = np.mgrid[top:bottom, left:right]
        total = weight.sum()
        centre = np.array([(weight * columns).sum() / total, (weight * rows).sum() / total])
        point = np.full(3, np.nan)
        if depth_mm is not None:
            samples = depth_mm[top:bottom, left:right][region]
            samples = samples[samples > 0]
            if len(samples):
                point = camera.rays(centre)[0] * (np.median(samples) + 0.7 * marker_radius)
        centres.append(centre)
        areas.append(area)
        points.append(point)
    if not centres:
        return empty
    return Blobs(np.array(centres), np.array(areas, dtype=float), np.array(points))


@dataclass
class MarkerFrame:
    """One camera frame paired with the mocap frame at the same time: its ``blobs`` and the labelled
    ``markers (M,3)`` mocap mm (NaN = not seen by the mocap)."""

    blobs: Blobs
    markers: np.ndarray


@dataclass
class Registration:
    """``camera`` registered; ``reprojection_px`` RMS of the matched blobs; ``residual_mm`` RMS 3D distance
    of the matched markers to their blob points (NaN without depth); ``matches``: matched pairs;
    ``matched_share``: share of the blobs explained; ``method`` pnp|rigid|board."""

    camera: Camera
    reprojection_px: float
    residual_mm: float
    matches: int
    matched_share: float
    method: str

    def report(self) -> dict:
        return {"method": self.method, "reprojection_px": round(self.reprojection_px, 4),
                "residual_mm": None if not np.isfinite(self.residual_mm) else round(self.residual_mm, 4),
                "matches": self.matches, "matched_share": round(self.matched_share, 4)}


def register_from_markers(camera: Camera, frames: list[MarkerFrame], use_depth: bool | None = None,
                          initial: Camera | None = None, triples: int = TRIPLES_PER_FRAME) -> Registration:
    """Register ``camera`` (intrinsics) to the mocap space from ``frames``; with depth (``use_depth`` None:
    when most blobs have a 3D point) the final fit is rigid 3D (Kabsch), else PnP. ``initial``: a camera
    whose pose starts the refinement instead of the hypothesis search (of ``triples`` blob triples a frame)."""
    if not frames or sum(len(f.blobs.centres) for f in frames) < MIN_MATCHES:
        raise InputError(f"registration needs at least {MIN_MATCHES} marker blobs; found "
                         f"{sum(len(f.blobs.centres) for f in frames)} in {len(frames)} frames")
    if use_depth is None:
        points = np.concatenate([f.blobs.points for f in frames])
        use_depth = bool(np.isfinite(points).all(axis=1).mean() > 0.5)
    pose = (initial.rotation, initial.translation) if initial is not None and initial.registered \
        else _search_pose(camera, frames, triples)
    gate_px = SEARCH_GATE_PX
    gate_mm = None
    for _ in range(REFINE_PASSES):
        current = camera.with_pose(*pose)
        pairs = _match(current, frames, gate_px)
        if len(pairs[0]) < MIN_MATCHES:
            raise InputError(f"only {len(pairs[0])} blobs match the markers; the camera could not be "
                             "registered (are the markers bright in the image and the frames in step?)")
        if use_depth:
            pose, errors_mm = _rigid_fit(current, pairs, gate_mm)
            gate_mm = max(GATE_FACTOR * float(np.median(errors_mm)), MIN_GATE_MM)
        else:
            pose = _pnp_fit(current, pairs, gate_px)
        residuals = np.linalg.norm(camera.with_pose(*pose).project(pairs[0]) - pairs[1], axis=1)
        gate_px = max(GATE_FACTOR * float(np.median(residuals)), MIN_GATE_PX)
    registered = camera.with_pose(*pose)
    markers, pixels, points = _match(registered, frames, gate_px)
    errors = np.linalg.norm(registered.project(markers) - pixels, axis=1)
    residual = float(np.sqrt(np.nanmean(np.sum((registered.to_camera(markers) - points) ** 2, axis=1)))) \
        if np.isfinite(points).all(axis=1).any() else float("nan")
    blob_count = sum(len(f.blobs.centres) for f in frames)
    return Registration(registered, float(np.sqrt(np.mean(errors ** 2))), residual, len(markers),
                        len(markers) / blob_count, "rigid" if use_depth else "pnp")


def _match(camera: Camera, frames: list[MarkerFrame], gate_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mutual nearest blob ↔ projected marker pairs within ``gate_px`` over all frames: ``(markers (P,3)
    mocap mm, pixels (P,2), blob points (P,3) camera mm)``."""
    markers, pixels, points = [], [], []
    for frame in frames:
        seen = np.isfinite(frame.markers).all(axis=1)
        if not seen.any() or not len(frame.blobs.centres):
            continue
        projected = camera.project(frame.markers[seen])
        distance = np.linalg.norm(projected[:, None, :] - frame.blobs.centres[None, :, :], axis=2)
        distance = np.where(np.isfinite(distance), distance, np.inf)
        nearest_blob = distance.argmin(axis=1)
        nearest_marker = distance.argmin(axis=0)
        for marker, blob in enumerate(nearest_blob):
            if nearest_marker[blob] == marker and distance[marker, blob] <= gate_px:
                markers.append(frame.markers[seen][marker])
                pixels.append(frame.blobs.centres[blob])
                points.append(frame.blobs.points[blob])
    if not markers:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3))
    return np.array(markers), np.array(pixels), np.array(points)


def _pnp_fit(camera: Camera, pairs: tuple[np.ndarray, np.ndarray, np.ndarray], gate_px: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """``solvePnPRansac`` from the current pose over the matched pairs, then LM on its inliers."""
    markers, pixels, _ = pairs
    distortion = camera.distortion if len(camera.distortion) else None
    rvec, tvec = camera.rotation_vector.reshape(3, 1).copy(), camera.translation.reshape(3, 1).copy()
    ok, rvec, tvec, inliers = cv2.solvePnPRansac(markers, pixels, camera.matrix, distortion, rvec, tvec,
                                                 useExtrinsicGuess=True, iterationsCount=200,
                                                 reprojectionError=gate_px, confidence=0.999)
    if not ok or inliers is None or len(inliers) < MIN_MATCHES:
        raise InputError("no consistent camera pose: the blobs do not match the markers")
    inliers = inliers.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(markers[inliers], pixels[inliers], camera.matrix, distortion, rvec, tvec)
    return cv2.Rodrigues(rvec)[0], tvec.ravel()


def _rigid_fit(camera: Camera, pairs: tuple[np.ndarray, np.ndarray, np.ndarray], gate_mm: float | None
               ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """RANSAC over the 3D pairs (markers mocap ↔ blob points camera), then Kabsch on the inliers;
    the inlier tolerance is ``gate_mm`` or, in the first pass, derived from the current pose's errors."""
    markers, _, points = pairs
    valid = np.isfinite(points).all(axis=1)
    markers, points = markers[valid], points[valid]
    if len(markers) < MIN_MATCHES:
        raise InputError(f"only {len(markers)} matched blobs have depth; need {MIN_MATCHES} for a rigid fit")
    current = np.linalg.norm(camera.to_camera(markers) - points, axis=1)
    tolerance = gate_mm or max(GATE_FACTOR * float(np.median(current)), MIN_GATE_MM)
    rng = np.random.default_rng(0)
    best = current < tolerance
    for _ in range(200):
        sample = rng.choice(len(markers), 3, replace=False)
        rotation, translation = kabsch(markers[sample], points[sample])
        inliers = np.linalg.norm(markers @ rotation.T + translation - points, axis=1) < tolerance
        if inliers.sum() > best.sum():
            best = inliers
    if best.sum() < MIN_MATCHES:
        raise InputError("no consistent rigid fit between the markers and the blobs' depth points")
    rotation, translation = kabsch(markers[best], points[best])
    return (rotation, translation), np.linalg.norm(markers[best] @ rotation.T + translation - points[best], axis=1)


def _search_pose(camera: Camera, frames: list[MarkerFrame], triples: int) -> tuple[np.ndarray, np.ndarray]:
    """The pose hypothesis explaining the most blobs: P3P on spread-out blob triples of the frames with
    the most blobs against every ordered triple of their markers, scored in a batch on the frame itself;
    the frame's best few are scored again on all frames."""
    order = np.argsort([-len(f.blobs.centres) for f in frames])[:SEARCH_FRAMES]
    best_score, best_pose = -1.0, None
    for index in order:
        frame = frames[index]
        markers = frame.markers[np.isfinite(frame.markers).all(axis=1)]
        if len(markers) < 3 or len(frame.blobs.centres) < 3:
            continue
        normalised = camera.undistort_pixels(frame.blobs.centres)
        for triple in _blob_triples(frame.blobs.centres, triples):
            poses = list(_p3p_hypotheses(camera, markers, frame.blobs.centres[list(triple)]))
            if not poses:
                continue
            scores = _batch_explained(poses, markers, normalised, SEARCH_GATE_PX / camera.focal[0])
            for candidate in np.argsort(scores)[::-1][:3]:
                score = _explained(camera.with_pose(*poses[candidate]), frames)
                if score > best_score:
                    best_score, best_pose = score, poses[candidate]
            if scores.max() >= EARLY_STOP * min(len(frame.blobs.centres), len(markers)):
                assert best_pose is not None  # the candidates just scored (scores >= 0) beat the initial -1
                return best_pose   # most of the frame explained: this triple was right
    if best_pose is None:
        raise InputError("no camera pose found: need frames with at least 3 marker blobs and 3 markers")
    return best_pose


def _batch_explained(poses: list, markers: np.ndarray, normalised: np.ndarray, gate: float) -> np.ndarray:
    """For every pose, the blobs (normalised coordinates ``(K,2)``) within ``gate`` of a projected marker."""
    rotations = np.array([rotation for rotation, _ in poses])
    translations = np.array([translation for _, translation in poses])
    points = np.einsum("hij,mj->hmi", rotations, markers) + translations[:, None, :]
    projected = points[..., :2] / points[..., 2:3]
    distance = np.linalg.norm(projected[:, :, None, :] - normalised[None, None, :, :], axis=3)
    nearest = distance.min(axis=1)
    return (nearest <= gate).sum(axis=1) - 0.01 * np.where(nearest <= gate, nearest / gate, 0.0).sum(axis=1)


def _blob_triples(centres: np.ndarray, count: int) -> list[tuple[int, int, int]]:
    """Up to ``count`` blob triples spanning the largest triangles."""
    triples = list(combinations(range(len(centres)), 3))
    areas = [abs(np.cross(centres[b] - centres[a], centres[c] - centres[a])) for a, b, c in triples]
    return [triples[i] for i in np.argsort(areas)[::-1][:count]]


def _p3p_hypotheses(camera: Camera, markers: np.ndarray, pixels: np.ndarray):
    """Camera poses ``(rotation, translation)`` putting some ordered marker triple on the three blob
    ``pixels`` and all markers in front of the camera."""
    distortion = camera.distortion if len(camera.distortion) else None
    image = np.ascontiguousarray(pixels, dtype=np.float64)
    for triple in permutations(range(len(markers)), 3):
        objects = np.ascontiguousarray(markers[list(triple)])
        try:
            count, rvecs, tvecs = cv2.solveP3P(objects, image, camera.matrix, distortion, flags=cv2.SOLVEPNP_AP3P)
        except cv2.error:
            continue
        for rvec, tvec in zip(rvecs[:count], tvecs[:count], strict=True):
            rotation = cv2.Rodrigues(rvec)[0]
            if ((markers @ rotation.T)[:, 2] + tvec[2, 0] > 0).all():
                yield rotation, tvec.ravel()


def _explained(camera: Camera, frames: list[MarkerFrame]) -> float:
    """Blobs explained by a marker within :data:`SEARCH_GATE_PX`, minus a small penalty per pixel of
    distance (to break ties toward the more precise pose)."""
    score = 0.0
    for frame in frames[:SEARCH_FRAMES * 4]:
        if not len(frame.blobs.centres):
            continue
        projected = camera.project(frame.markers)
        distance = np.linalg.norm(projected[:, None, :] - frame.blobs.centres[None, :, :], axis=2)
        nearest = np.nanmin(np.where(np.isfinite(distance), distance, np.inf), axis=0)
        near = nearest <= SEARCH_GATE_PX
        score += near.sum() - 0.01 * nearest[near].sum()
    return score


def register_from_board(camera: Camera, detections: list, board_markers: np.ndarray,
                        mocap_markers: np.ndarray) -> Registration:
    """Register ``camera`` from views of a ChArUco board carrying markers: ``detections`` (per view, from
    :func:`core.camera.intrinsics.detect_board`, None = not found), ``board_markers (B,3)`` the markers'
    centres in the board frame (mm), ``mocap_markers (N,B,3)`` their mocap positions per view. Each view's
    board pose in the mocap comes from a Kabsch fit of its markers (residual = their RMS misfit, mm); the
    corners of all views, moved into the mocap frame, give one PnP."""
    objects, images, misfits = [], [], []
    for detection, markers in zip(detections, mocap_markers, strict=True):
        seen = np.isfinite(markers).all(axis=1)
        if detection is None or seen.sum() < 3:
            continue
        rotation, translation = kabsch(board_markers[seen], markers[seen])
        misfits.append(markers[seen] - (board_markers[seen] @ rotation.T + translation))
        objects.append(detection.object_points @ rotation.T + translation)
        images.append(detection.image_points)
    if not objects:
        raise InputError("no view shows the board with at least 3 of its markers measured")
    objects_all, images_all = np.concatenate(objects), np.concatenate(images)
    distortion = camera.distortion if len(camera.distortion) else None
    ok, rvec, tvec = cv2.solvePnP(objects_all, images_all, camera.matrix, distortion, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise InputError("no camera pose fits the board corners")
    rvec, tvec = cv2.solvePnPRefineLM(objects_all, images_all, camera.matrix, distortion, rvec, tvec)
    registered = camera.with_pose(cv2.Rodrigues(rvec)[0], tvec.ravel())
    errors = np.linalg.norm(registered.project(objects_all) - images_all, axis=1)
    residual = float(np.sqrt(np.mean(np.sum(np.concatenate(misfits) ** 2, axis=1))))
    return Registration(registered, float(np.sqrt(np.mean(errors ** 2))), residual, len(objects_all), 1.0, "board")
