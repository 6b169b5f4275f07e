"""Fit where a layout's markers sit on the hand from a labelled take (marker-offset calibration).

Alternates (a) IK of sampled frames with the current placement and (b) re-placing every marker at the
median, over those frames, of its measured position carried back into the rest pose through the
solved transform of the joint that carries it (the marker-offset half of Zhao et al. 2012 eq. 2; bone
lengths are not changed here). The result is written in the portable ``between/along/side`` form, so
it carries over to other hand models.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik import IKSettings, solve_positions
from handmocap.core.ik.solver import match_layout
from handmocap.core.model import HandModel, MarkerLayout, MarkerSpec, resolve_layout
from handmocap.core.model.markers import frame_joint_of, joint_rest_point
from handmocap.core.model.skeleton import DIGITS, JOINT_NAMES

MIN_OFFSET_MM, MAX_OFFSET_MM = 2.0, 20.0


def _portable_spec(model: HandModel, spec: MarkerSpec, rest_position: np.ndarray) -> MarkerSpec:
    """A ``between/along/side`` spec whose ray from the bone axis reaches ``rest_position (3,)``."""
    first, second = spec.joints
    start, end = joint_rest_point(model, first), joint_rest_point(model, second)
    axis = end - start
    along = float(np.clip((rest_position - start) @ axis / (axis @ axis), -0.6, 1.2))
    origin = start + along * axis
    frame = model.skeleton.rest_rotations[frame_joint_of(first)]
    local = frame.T @ (rest_position - origin)
    if model.side == "left":
        local[0] = -local[0]
    local /= max(np.linalg.norm(local), 1e-9)
    x, y, z = (round(float(v), 3) for v in local)
    return MarkerSpec(name=spec.name, between=spec.between, along=round(along, 3), side=(x, y, z),
                      offset_mm=spec.offset_mm)


def fit_marker_placement(positions: np.ndarray, marker_names: list[str], model: HandModel,
                         layout: MarkerLayout, iterations: int = 3, max_frames: int = 300,
                         progress: Callable[[float], None] | None = None,
                         cancelled: Callable[[], bool] | None = None) -> tuple[MarkerLayout, list[float]]:
    """Refit ``layout`` (surface-ray markers only) to a labelled take ``positions (F,N,3)`` mm.

    Returns the placement with the lowest mean IK residual and that residual (mm) for the input and
    after each iteration (the surface snapping makes the sequence not always decreasing).
    """
    if any(spec.vertex is not None for spec in layout.markers):
        raise InputError("marker placement fitting needs a layout in the between/along/side form")
    columns = match_layout(marker_names, layout)
    frames = np.linspace(0, len(positions) - 1, min(max_frames, len(positions))).astype(int)
    targets = np.full((len(frames), len(columns), 3), np.nan)
    targets[:, columns >= 0] = positions[frames][:, columns[columns >= 0]]
    residuals: list[float] = []
    best_layout, best_residual = layout, np.inf
    for iteration in range(iterations + 1):
        markers = resolve_layout(model, layout)
        result = solve_positions(targets, model, markers, settings=IKSettings(method="layered"))
        residuals.append(result.mean_residual_mm)
        if result.mean_residual_mm < best_residual:
            best_layout, best_residual = layout, result.mean_residual_mm
        if iteration == iterations:
            break
        if cancelled is not None and cancelled():
            raise CancelledError("marker placement fit cancelled; the layout is unchanged")
        specs = []
        for index, spec in enumerate(layout.markers):
            carrier = _carrier_joint(spec)
            rest = rest_positions_of_targets(model, result.joint_angles, targets[:, index], carrier)
            if len(rest) < 5:
                specs.append(spec)
                continue
            specs.append(_portable_spec(model, spec, np.median(rest, axis=0)))
        layout = MarkerLayout(layout.name, tuple(specs), layout.description)
        layout = _with_fitted_offsets(model, layout, targets, result.joint_angles)
        if progress is not None:
            progress((iteration + 1) / iterations)
    return best_layout, residuals


def _carrier_joint(spec: MarkerSpec) -> int:
    """The joint whose segment the marker sits on (the first joint of ``between``; tips: distal)."""
    joint = spec.joints[0]
    if joint.endswith("_tip"):
        return 3 + 3 * DIGITS.index(joint[:-4])
    return JOINT_NAMES.index(joint)


def rest_positions_of_targets(model: HandModel, thetas: np.ndarray, targets: np.ndarray,
                               joint: int) -> np.ndarray:
    """Measured positions (F,3) carried into the rest pose rigidly with ``joint``; finite rows only."""
    rest_rotation = model.skeleton.rest_rotations[joint]
    rest_position = model.skeleton.rest_positions[joint]
    carried = []
    for theta, target in zip(thetas, targets, strict=True):
        if not (np.isfinite(theta).all() and np.isfinite(target).all()):
            continue
        rotations, positions = model.chain.joint_transforms(theta)
        local = rotations[joint].T @ (target - positions[joint])
        carried.append(rest_rotation @ local + rest_position)
    return np.asarray(carried).reshape(-1, 3)


def _with_fitted_offsets(model: HandModel, layout: MarkerLayout, targets: np.ndarray,
                         thetas: np.ndarray) -> MarkerLayout:
    """Set each marker's offset to the median height of its carried-back measurements above the skin."""
    markers = resolve_layout(model, layout)
    specs = []
    for index, spec in enumerate(layout.markers):
        rest = rest_positions_of_targets(model, thetas, targets[:, index], _carrier_joint(spec))
        if len(rest) < 5:
            specs.append(spec)
            continue
        vertex = markers.vertex[index]
        height = np.median((rest - model.vertices[vertex]) @ model.vertex_normals[vertex])
        offset = float(np.clip(height, MIN_OFFSET_MM, MAX_OFFSET_MM))
        specs.append(MarkerSpec(spec.name, spec.between, spec.along, spec.side, None, round(offset, 2)))
    return MarkerLayout(layout.name, tuple(specs), layout.description)
