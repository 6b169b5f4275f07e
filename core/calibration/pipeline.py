"""The whole scan calibration: scan + landmarks -> a subject-specific, ready-to-animate hand model.

Steps (journal "Hand model generation", DESIGN.md "Scan calibration"):

1. prepare the scan: subsample huge scans, convert metres, skin filter + outlier removal
   (:func:`core.calibration.cleaning.clean_scan`), estimate normals when the scan has none;
2. check the landmarks (enough of them, on the scan, not a mirror image of the template, no swapped
   pair) and align the template: Umeyama on the landmarks, then alternating similarity ICP and
   posture IK (:mod:`core.calibration.align`);
3. non-rigid fit with the paper's schedule (:mod:`core.calibration.nonrigid`); the template side of each
   landmark pair is the landmark's exact anatomical point on the template surface (a point inside a
   triangle, :func:`core.calibration.align.anatomical_landmarks`), not the mesh vertex it was rounded
   to: that rounding (up to 1.5 mm) shifts the relocated joints (max joint error on the evaluation
   subjects with exactly picked landmarks 2.4 mm with vertices, 1.8 mm with the exact points);
4. bring the fitted surface back to the rest pose (inverse linear blend skinning at the fitted
   posture), move the 16 joints and 5 tips with it through mean value coordinates computed on the
   undeformed template, rebuild the joint frames, keep the skin weights and landmarks (same mesh
   topology, so vertex-based and portable marker layouts both carry over);
5. report: landmark residuals, scan-to-model distances, distance map, warnings.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from handmocap.core.calibration.align import (
    Alignment,
    align_template,
    anatomical_landmarks,
    landmark_pairs,
    mirror_check,
)
from handmocap.core.calibration.cleaning import clean_scan
from handmocap.core.calibration.landmarks import MIN_LANDMARKS, load_landmarks, validate_landmarks
from handmocap.core.calibration.mean_value import mean_value_coordinates
from handmocap.core.calibration.nearest import nearest_neighbours
from handmocap.core.calibration.nonrigid import FitSchedule, estimate_normals, fit_nonrigid
from handmocap.core.calibration.report import (
    LARGE_RESIDUAL_MM,
    UNSUPPORTED_MM,
    CalibrationReport,
    distance_statistics,
    find_swapped_pairs,
    point_to_mesh_distances,
    unsupported_areas,
)
from handmocap.core.calibration.rigid import similarity_transform
from handmocap.core.calibration.scan import METRE_DIAGONAL_LIMIT, Scan, load_scan
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.model import HandModel, load_template
from handmocap.core.model.hand_model import MAX_INFLUENCES, mesh_vertex_normals
from handmocap.core.model.skeleton import N_JOINTS, Skeleton
from handmocap.core.model.template_mesh import LANDMARK_NAMES

MAX_SCAN_POINTS = 300_000       # larger scans are subsampled (randomly, seeded) before cleaning
REPORT_SAMPLE = 40_000          # scan points used for the scan-to-model statistics
LANDMARK_OFF_SCAN_MM = 15.0     # landmarks farther than this (median) from the scan are rejected
MIRROR_RATIO = 0.6              # mirrored fit this much better than the direct one -> wrong hand side
PALM_SIDE_COSINE = -0.3         # landmark normal disagreement that flags a landmark on the wrong side

Progress = Callable[[float], None]


@dataclass
class CalibrationResult:
    """Output of :func:`calibrate_scan`.

    ``model``: the calibrated :class:`HandModel` in its rest pose (mm); ``report``; ``alignment``
    (scale, ``theta (26,)`` of the fitted posture in the scan frame); ``fitted_vertices (V,3)``: the
    fitted surface in the scan frame; ``joints (16,3)``: the relocated joints posed in the scan frame;
    ``theta (26,)``: the pose of ``model`` on the scan (``skin_vertices(model, theta)`` ≈ the fitted surface);
    ``scan``: the cleaned scan the fit used; ``landmark_names``: the landmarks used.
    """

    model: HandModel
    report: CalibrationReport
    alignment: Alignment
    fitted_vertices: np.ndarray
    joints: np.ndarray
    scan: Scan
    landmark_names: list[str]
    theta: np.ndarray

    def save(self, model_path: str | Path, report_path: str | Path | None = None) -> None:
        """Write the model (``HandModel.save`` ``.npz``) and optionally the report (JSON), each through
        :mod:`core.io.durable`."""
        self.model.save(model_path)
        if report_path is not None:
            write_text_atomic(report_path, json.dumps(self.report.to_json(), indent=2))


def _stage(progress: Progress | None, start: float, end: float) -> Progress | None:
    """A progress callback mapping 0..1 of one stage onto ``start..end`` of the whole run."""
    if progress is None:
        return None
    return lambda fraction: progress(start + (end - start) * min(max(fraction, 0.0), 1.0))


def _check_cancel(cancelled: Callable[[], bool] | None) -> None:
    if cancelled is not None and cancelled():
        raise CancelledError("calibration cancelled; the scan and landmarks are unchanged")


def load_template_file(path: str | Path | None, side: str = "right") -> HandModel:
    """A template from a ``.npz`` HandModel or a ``.gltf``/``.glb`` skinned hand; the shipped one when None."""
    if path is None:
        return load_template(side)
    path = Path(path)
    if path.suffix.lower() in (".gltf", ".glb"):
        from handmocap.core.model.gltf import load_gltf_hand

        return load_gltf_hand(path)
    if path.suffix.lower() == ".npz":
        if not path.is_file():
            raise InputError(f"template file not found: {path}")
        return HandModel.load(path)
    raise InputError(f"{path.name}: unsupported template format (use .npz, .gltf or .glb)")


def prepare_scan(scan: Scan | str | Path, clean: bool = True, strictness: float = 0.5,
                 max_points: int = MAX_SCAN_POINTS, seed: int = 0) -> tuple[Scan, list[str]]:
    """Load (if a path), subsample huge scans, convert metres, clean; returns the scan and notes."""
    notes: list[str] = []
    if not isinstance(scan, Scan):
        scan = load_scan(scan)
    notes += scan.notes
    if len(scan) == 0:
        raise InputError("the scan has no points")
    diagonal = float(np.linalg.norm(np.ptp(scan.points, axis=0)))
    if 0.0 < diagonal < METRE_DIAGONAL_LIMIT:
        scan = Scan(scan.points * 1000.0, scan.normals, scan.colors, scan.faces, list(scan.notes))
        notes.append(f"coordinates look like metres (bounding box diagonal {diagonal:.3f}); converted to mm")
    if len(scan) > max_points:
        keep = np.zeros(len(scan), dtype=bool)
        keep[np.random.default_rng(seed).choice(len(scan), size=max_points, replace=False)] = True
        notes.append(f"the scan has {len(scan):,} points; using a random {max_points:,} of them")
        scan = scan.subset(keep)
    if clean:
        scan, cleaning = clean_scan(scan, strictness=strictness)
        if cleaning["colour_filter"]:
            notes.append(f"skin filter removed {cleaning['non_skin_removed']:,} points")
        notes.append(f"outlier filter removed {cleaning['outliers_removed']:,} points; "
                     f"{cleaning['kept_points']:,} kept")
    if len(scan) < 1000:
        raise InputError(f"only {len(scan)} scan points left after cleaning; a hand scan needs thousands "
                         "(is the skin filter too strict, or is this not a hand scan?)")
    return scan, notes


def check_landmarks(template: HandModel, landmarks: dict[str, np.ndarray | None], scan_points: np.ndarray | None,
                    tree: cKDTree | None = None) -> list[str]:
    """Raise :class:`InputError` for landmarks the fit cannot use (too few, off the scan, a mirror image of
    the template, swapped pairs); returns warnings (skipped landmarks)."""
    given = [name for name in LANDMARK_NAMES if landmarks.get(name) is not None]
    if len(given) < MIN_LANDMARKS:
        raise InputError(f"only {len(given)} landmarks given; at least {MIN_LANDMARKS} are needed "
                         "(spread over the fingertips and the wrist)")
    names, vertices, targets = landmark_pairs(template, landmarks)
    if scan_points is not None:
        tree = tree if tree is not None else cKDTree(scan_points)
        off = float(np.median(nearest_neighbours(tree, targets)[0]))
        if off > LANDMARK_OFF_SCAN_MM:
            raise InputError(f"the landmarks lie {off:.0f} mm from the scan (median): were they picked on another "
                             "scan, or in other units?")
    direct, mirrored = mirror_check(template, vertices, targets)
    if mirrored < MIRROR_RATIO * direct and direct > 10.0:
        other = "left" if template.side == "right" else "right"
        raise InputError(f"the landmarks describe a {other} hand but the template is a {template.side} hand "
                         f"(landmark RMS {direct:.0f} mm, mirrored {mirrored:.0f} mm): use the {other}-hand template")
    scale, rotation, translation = similarity_transform(template.vertices[vertices], targets)
    moved = scale * template.vertices[vertices] @ rotation.T + translation
    swaps = find_swapped_pairs(names, moved, targets, threshold_mm=0.1 * template.hand_length * scale)
    if swaps:
        a, b, before, after = swaps[0]
        raise InputError(f"landmarks {a} and {b} look swapped (residuals {before:.0f} mm, {after:.0f} mm when "
                         "exchanged): re-pick them")
    skipped = [name for name in LANDMARK_NAMES if landmarks.get(name) is None]
    return [f"{len(skipped)} landmarks skipped ({', '.join(skipped)}); the fit relies more on the scan there"] \
        if skipped else []


def unpose_vertices(model: HandModel, theta: np.ndarray, posed: np.ndarray) -> np.ndarray:
    """Rest-pose positions (V,3) whose linear blend skinning at ``theta`` gives ``posed (V,3)`` (exact
    inverse of the per-vertex blended transform)."""
    linear, translation = model.chain.skinning_matrices(theta)
    blended = np.zeros((len(posed), 3, 3))
    offset = np.zeros((len(posed), 3))
    for k in range(MAX_INFLUENCES):
        weights = model.skin_weights[:, k]
        joints = model.skin_joints[:, k]
        blended += weights[:, None, None] * linear[joints]
        offset += weights[:, None] * translation[joints]
    return np.linalg.solve(blended, (posed - offset)[:, :, None])[:, :, 0]


_MVC_CACHE: dict[int, tuple[HandModel, np.ndarray]] = {}


def joint_coordinates(template: HandModel) -> np.ndarray:
    """Mean value coordinates ``(21,V)`` of the 16 rest joints and 5 tips on the template (cached)."""
    cached = _MVC_CACHE.get(id(template))
    if cached is not None and cached[0] is template:
        return cached[1]
    points = np.vstack([template.skeleton.rest_positions, template.skeleton.tip_positions])
    coordinates = mean_value_coordinates(template.vertices, template.faces, points)
    _MVC_CACHE.clear()
    _MVC_CACHE[id(template)] = (template, coordinates)
    return coordinates


def rebuild_skeleton(old: Skeleton, joints: np.ndarray, tips: np.ndarray) -> Skeleton:
    """A skeleton with relocated ``joints (16,3)`` and ``tips (5,3)``: each digit frame keeps its palmar
    direction (orthogonalised) and turns its y axis along the new bone; the wrist frame is kept."""
    rotations = old.rest_rotations.copy()
    for joint in range(1, N_JOINTS):
        digit, segment = divmod(joint - 1, 3)
        child = joints[joint + 1] if segment < 2 else tips[digit]
        y_axis = child - joints[joint]
        y_axis /= np.linalg.norm(y_axis)
        z_axis = old.rest_rotations[joint][:, 2] - (old.rest_rotations[joint][:, 2] @ y_axis) * y_axis
        z_axis /= np.linalg.norm(z_axis)
        rotations[joint] = np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])
    return Skeleton(joints, rotations, tips, old.side)


def calibrated_model(template: HandModel, alignment: Alignment, fitted: np.ndarray, name: str
                     ) -> tuple[HandModel, np.ndarray]:
    """The rest-pose subject model from the fitted surface ``fitted (V,3)`` (scan frame, posed) and the
    pose ``theta (26,)`` that puts it on the fitted surface (the rest frame is re-centred on the relocated
    wrist joint, as the wrist translation parameters mean the wrist position)."""
    posed_model = alignment.model(template)
    posture = alignment.theta
    rest_vertices = unpose_vertices(posed_model, posture, fitted)
    relocated = joint_coordinates(template) @ rest_vertices
    wrist = relocated[0].copy()
    relocated -= wrist
    rest_vertices = rest_vertices - wrist
    skeleton = rebuild_skeleton(posed_model.skeleton, relocated[:N_JOINTS], relocated[N_JOINTS:])
    back = -skeleton.rest_rotations[7][:, 2]
    model = replace(template, skeleton=skeleton, vertices=rest_vertices, faces=template.faces.copy(),
                    skin_joints=template.skin_joints.copy(), skin_weights=template.skin_weights.copy(),
                    landmarks=dict(template.landmarks), back_direction=back / np.linalg.norm(back),
                    hand_length=float(np.linalg.norm(skeleton.tip_positions[2] - skeleton.rest_positions[0])),
                    name=name)
    theta = posture.copy()
    wrist_rotation, wrist_position = posed_model.chain.joint_transforms(posture)
    theta[0:3] = wrist_position[0] + wrist_rotation[0] @ wrist
    return model, theta


def build_report(template: HandModel, model: HandModel, fitted: np.ndarray, scan: Scan, tree: cKDTree,
                 names: list[str], landmark_vertices: np.ndarray, targets: np.ndarray, alignment: Alignment,
                 normals_oriented: bool, warnings: list[str], notes: list[str], seed: int = 0,
                 landmark_points: np.ndarray | None = None) -> CalibrationReport:
    """Residuals, distances, distance map and warnings of a finished fit (``landmark_points (L,3)``: the
    fitted template's landmark points when they are not exactly ``fitted[landmark_vertices]``)."""
    points = fitted[landmark_vertices] if landmark_points is None else landmark_points
    residuals = np.linalg.norm(points - targets, axis=1)
    rng = np.random.default_rng(seed)
    sample = scan.points if len(scan) <= REPORT_SAMPLE else scan.points[rng.choice(len(scan), REPORT_SAMPLE,
                                                                                   replace=False)]
    scan_distances = point_to_mesh_distances(sample, fitted, template.faces)
    vertex_distance, _ = nearest_neighbours(tree, fitted)
    share, areas = unsupported_areas(fitted, template.faces, vertex_distance, template.skin_joints,
                                     template.skin_weights)
    warnings = list(warnings)
    swaps = find_swapped_pairs(names, points, targets)
    for a, b, before, after in swaps:
        warnings.append(f"landmarks {a} and {b} look swapped ({before:.1f} mm, {after:.1f} mm when exchanged)")
    swapped = {name for pair in swaps for name in pair[:2]}
    for name, residual in zip(names, residuals, strict=True):
        if residual > LARGE_RESIDUAL_MM and name not in swapped:
            warnings.append(f"landmark {name} is {residual:.1f} mm from the fitted surface point: check the pick")
    if scan.normals is not None and normals_oriented:
        fitted_normals = mesh_vertex_normals(fitted, template.faces)[landmark_vertices]
        _, nearest = nearest_neighbours(tree, targets)
        agreement = np.einsum("na,na->n", fitted_normals, scan.normals[nearest])
        for name, cosine in zip(names, agreement, strict=True):
            if cosine < PALM_SIDE_COSINE:
                warnings.append(f"landmark {name} seems picked on the wrong side of the hand (palm instead of back)")
    for area, joint in areas:
        warnings.append(f"{area:.0f} mm² of the surface near {joint} has no scan support within "
                        f"{UNSUPPORTED_MM:.0f} mm (hole in the scan): the template shape fills it")
    return CalibrationReport(
        landmark_residuals={name: float(r) for name, r in zip(names, residuals, strict=True)},
        scan_to_model=distance_statistics(scan_distances), vertex_distance=vertex_distance,
        unsupported_share=share, warnings=warnings, notes=notes,
        alignment={"scale": alignment.scale, "landmark_rms_after_align_mm": alignment.landmark_rms_mm[-1]})


@dataclass
class CalibrationInput:
    """Everything the alignment and the fit need, checked (see :func:`prepare_calibration`)."""

    template: HandModel
    scan: Scan
    normals: np.ndarray
    normals_oriented: bool
    tree: cKDTree
    landmark_names: list[str]
    landmark_vertices: np.ndarray
    landmark_targets: np.ndarray
    notes: list[str]
    warnings: list[str]
    scan_name: str
    #: exact template landmark points (:func:`core.calibration.align.anatomical_landmarks`): triangle
    #: corners (L,3) and barycentric weights (L,3); None = the landmark vertices themselves
    landmark_corners: np.ndarray | None = None
    landmark_barycentric: np.ndarray | None = None

    def landmark_points(self, vertices: np.ndarray) -> np.ndarray:
        """The template landmark points (L,3) on a deformed copy ``vertices (V,3)`` of the template."""
        if self.landmark_corners is None or self.landmark_barycentric is None:
            return vertices[self.landmark_vertices]
        return np.einsum("lk,lka->la", self.landmark_barycentric, vertices[self.landmark_corners])


def prepare_calibration(scan: Scan | str | Path, landmarks: dict[str, np.ndarray | None] | str | Path,
                        template: HandModel | str | Path | None = None, clean: bool = True,
                        strictness: float = 0.5, max_points: int = MAX_SCAN_POINTS) -> CalibrationInput:
    """Load and clean the scan, read and check the landmarks (:class:`InputError` when unusable)."""
    if not isinstance(template, HandModel):
        template = load_template_file(template)
    landmarks = validate_landmarks(landmarks) if isinstance(landmarks, dict) else load_landmarks(landmarks)
    scan_name = Path(scan).stem if not isinstance(scan, Scan) else "scan"
    prepared, notes = prepare_scan(scan, clean=clean, strictness=strictness, max_points=max_points)
    landmarks = _landmarks_in_mm(landmarks, prepared, notes)
    normals_oriented = prepared.normals is not None
    normals = prepared.normals if prepared.normals is not None else estimate_normals(prepared.points)
    if not normals_oriented:
        notes.append("the scan has no normals; estimated from the point neighbourhoods (unoriented)")
    tree = cKDTree(prepared.points)
    warnings = check_landmarks(template, landmarks, prepared.points, tree)
    names, landmark_vertices, targets = landmark_pairs(template, landmarks)
    if normals_oriented and _normals_point_inwards(template, landmark_vertices, targets, normals, tree):
        normals = -normals
        notes.append("the scan's normals point into the hand (inverted face winding?); flipped")
    corners, barycentric = anatomical_landmarks(template, names)
    return CalibrationInput(template, prepared, normals, normals_oriented, tree, names, landmark_vertices, targets,
                            notes, warnings, scan_name, corners, barycentric)


def _normals_point_inwards(template: HandModel, landmark_vertices: np.ndarray, targets: np.ndarray,
                           normals: np.ndarray, tree: cKDTree) -> bool:
    """Whether the scan normals mostly disagree with the landmark-aligned template's outward normals."""
    scale, rotation, translation = similarity_transform(template.vertices[landmark_vertices], targets)
    sample = np.arange(0, len(template.vertices), max(1, len(template.vertices) // 2000))
    moved = scale * template.vertices[sample] @ rotation.T + translation
    distances, nearest = nearest_neighbours(tree, moved, upper_bound_mm=10.0)
    close = np.isfinite(distances)
    if close.sum() < 20:
        return False
    agreement = np.einsum("na,na->n", template.vertex_normals[sample[close]] @ rotation.T, normals[nearest[close]])
    return float(np.median(agreement)) < 0.0


def run_alignment(data: CalibrationInput, progress: Progress | None = None,
                  cancelled: Callable[[], bool] | None = None,
                  on_iteration: Callable[[np.ndarray], None] | None = None) -> Alignment:
    """Step 3 of the module docstring on prepared input."""
    return align_template(data.template, data.landmark_vertices, data.landmark_targets, data.scan.points,
                          data.normals, data.normals_oriented, tree=data.tree, progress=progress,
                          cancelled=cancelled, on_iteration=on_iteration)


def run_fit(data: CalibrationInput, alignment: Alignment, schedule: FitSchedule | None = None,
            progress: Progress | None = None, cancelled: Callable[[], bool] | None = None,
            on_iteration: Callable[[np.ndarray], None] | None = None) -> np.ndarray:
    """The non-rigid fit from an alignment; returns the fitted vertices (V,3) in the scan frame."""
    corners = data.landmark_vertices if data.landmark_corners is None else data.landmark_corners
    fit = fit_nonrigid(alignment.vertices, data.template.faces, corners, data.landmark_targets,
                       data.scan.points, data.normals, data.normals_oriented, schedule, progress=progress,
                       cancelled=cancelled, on_iteration=on_iteration, tree=data.tree,
                       landmark_weights=data.landmark_barycentric)
    return fit.vertices


def finish_calibration(data: CalibrationInput, alignment: Alignment, fitted: np.ndarray,
                       name: str | None = None) -> CalibrationResult:
    """Rest-pose model with relocated joints, and the report, from a finished fit."""
    model, theta = calibrated_model(data.template, alignment, fitted, name or f"calibrated {data.scan_name}")
    _, joints = model.chain.joint_transforms(theta)
    report = build_report(data.template, model, fitted, Scan(data.scan.points, data.normals), data.tree,
                          data.landmark_names, data.landmark_vertices, data.landmark_targets, alignment,
                          data.normals_oriented, data.warnings, data.notes,
                          landmark_points=data.landmark_points(fitted))
    return CalibrationResult(model, report, alignment, fitted, joints, data.scan, data.landmark_names, theta)


def calibrate_scan(scan: Scan | str | Path, landmarks: dict[str, np.ndarray | None] | str | Path,
                   template: HandModel | str | Path | None = None, progress: Progress | None = None,
                   cancelled: Callable[[], bool] | None = None,
                   on_iteration: Callable[[np.ndarray], None] | None = None, clean: bool = True,
                   strictness: float = 0.5, max_points: int = MAX_SCAN_POINTS,
                   schedule: FitSchedule | None = None, name: str | None = None) -> CalibrationResult:
    """Calibrate a hand model to a scan (see the module docstring).

    ``scan``: a :class:`Scan` or a PLY/OBJ path; ``landmarks``: name -> position (3,) mm or None, or a
    landmark JSON path; ``template``: a HandModel, a ``.npz``/``.gltf``/``.glb`` path, or None for the
    shipped right hand. ``on_iteration(vertices (V,3))`` receives the moving template (scan frame) during
    the alignment and the fit. Raises :class:`InputError` with one clear line for unusable input and
    :class:`CancelledError` when ``cancelled()`` turns true; inputs are never modified.
    """
    _check_cancel(cancelled)
    data = prepare_calibration(scan, landmarks, template, clean=clean, strictness=strictness, max_points=max_points)
    if progress is not None:
        progress(0.08)
    _check_cancel(cancelled)
    alignment = run_alignment(data, _stage(progress, 0.08, 0.25), cancelled, on_iteration)
    fitted = run_fit(data, alignment, schedule, _stage(progress, 0.25, 0.9), cancelled, on_iteration)
    _check_cancel(cancelled)
    result = finish_calibration(data, alignment, fitted, name)
    if progress is not None:
        progress(1.0)
    return result


def _landmarks_in_mm(landmarks: dict[str, np.ndarray | None], scan: Scan, notes: list[str]
                     ) -> dict[str, np.ndarray | None]:
    """Landmarks given in metres for a scan in mm are converted (with a note)."""
    given = np.array([value for value in landmarks.values() if value is not None])
    scan_diagonal = float(np.linalg.norm(np.ptp(scan.points, axis=0)))
    diagonal = float(np.linalg.norm(np.ptp(given, axis=0)))
    if 0.0 < diagonal < METRE_DIAGONAL_LIMIT < scan_diagonal:
        notes.append("landmark coordinates look like metres; converted to mm")
        return {name: None if value is None else value * 1000.0 for name, value in landmarks.items()}
    return landmarks
