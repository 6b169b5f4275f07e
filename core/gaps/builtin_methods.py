"""The built-in gap-fill methods (:mod:`core.gaps.fills`, :mod:`core.gaps.pca`), registered in the order the
fill check tries them: linear, spline, pattern, rigid, model, pca (provenance codes 1..6)."""

from __future__ import annotations

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.gaps.context import DONOR_WINDOW, ModelContext, choose_donors
from handmocap.core.gaps.fills import (
    MODEL_FIT,
    SPLINE_CONTEXT,
    fill_linear,
    fill_model,
    fill_pattern,
    fill_rigid,
    fill_spline,
)
from handmocap.core.gaps.methods import FillMethod, register_fill_method
from handmocap.core.gaps.pca import PCA_WINDOW, fill_pca
from handmocap.core.model import N_PARAMS

#: frames of IK solved on each side of a gap for a model fill without precomputed joint angles
IK_PAD = 30


def _linear(positions: np.ndarray, marker: int, start: int, length: int, _context: ModelContext | None,
            _angles: np.ndarray | None) -> np.ndarray:
    return fill_linear(positions[:, marker], start, length)


def _spline(positions: np.ndarray, marker: int, start: int, length: int, _context: ModelContext | None,
            _angles: np.ndarray | None) -> np.ndarray:
    return fill_spline(positions[:, marker], start, length)


def _pattern(positions: np.ndarray, marker: int, start: int, length: int, _context: ModelContext | None,
             _angles: np.ndarray | None) -> np.ndarray:
    donor = choose_donors(positions, marker, start, length, 1, "pattern")[0]
    return fill_pattern(positions[:, marker], start, length, positions[:, donor])


def _rigid(positions: np.ndarray, marker: int, start: int, length: int, _context: ModelContext | None,
           _angles: np.ndarray | None) -> np.ndarray:
    donors = choose_donors(positions, marker, start, length, 3, "rigid body")
    return fill_rigid(positions[:, marker], start, length, positions[:, donors])


def _model(positions: np.ndarray, marker: int, start: int, length: int, context: ModelContext | None,
           joint_angles: np.ndarray | None) -> np.ndarray:
    """Model fill on ``context``; uses ``joint_angles (F, 26)`` when given, else solves IK over
    :data:`IK_PAD` frames on each side with the gap hidden."""
    if context is None:
        raise InputError("model fill needs a hand model and a marker layout")
    index = context.layout_index(marker)
    first, last = max(0, start - IK_PAD), min(len(positions), start + length + IK_PAD)
    window = context.layout_positions(positions[first:last])
    window[start - first:start - first + length, index] = np.nan
    if joint_angles is None:
        # IK runs forwards (each frame warm-started from the ones before) and the fill reads no angle
        # past MODEL_FIT frames after the gap, so the frames after those are not solved
        solved = min(len(window), start - first + length + MODEL_FIT)
        angles = np.full((len(window), N_PARAMS), np.nan)
        angles[:solved] = context.solve(window[:solved])
    else:
        angles = joint_angles[first:last]
    return fill_model(window, start - first, length, index, angles, context.model, context.markers)


def _pca(positions: np.ndarray, marker: int, start: int, length: int, _context: ModelContext | None,
         _angles: np.ndarray | None) -> np.ndarray:
    return fill_pca(positions, marker, start, length)


register_fill_method(FillMethod(
    name="linear", label="Linear", description="Straight line between the samples on each side",
    needs="1 measured frame on each side of the gap", code=1, colour=(112, 140, 240), fill=_linear, reach=1,
    menu_rank=2))
register_fill_method(FillMethod(
    name="spline", label="Spline", description="Cubic spline through the samples on each side",
    needs="2 measured frames on each side of the gap", code=2, colour=(72, 196, 232), fill=_spline,
    reach=SPLINE_CONTEXT, menu_rank=3))
register_fill_method(FillMethod(
    name="pattern", label="Pattern",
    description="Copies the motion of a donor marker observed through the gap, blended to the gap's ends",
    needs="another marker measured through the gap", code=3, colour=(178, 118, 240), fill=_pattern,
    reach=DONOR_WINDOW, menu_rank=4))
register_fill_method(FillMethod(
    name="rigid", label="Rigid body",
    description="Rigid body: three donor markers on the same segment carry the marker through the gap",
    needs="3 other markers of a rigid group measured through the gap", code=4, colour=(236, 112, 198), fill=_rigid,
    reach=DONOR_WINDOW, menu_rank=5))
register_fill_method(FillMethod(
    name="model", label="Model",
    description="Hand model: joint angles interpolated through the gap with minimum angular acceleration, "
                "markers placed by forward kinematics (the papers' method)",
    needs="a hand model and the take's marker layout; 2 measured frames on each side", code=5,
    colour=(84, 206, 120), fill=_model, reach=IK_PAD, menu_rank=0, needs_model=True))
register_fill_method(FillMethod(
    name="pca", label="PCA",
    description="Marker intercorrelations: the gap follows the other markers through the principal components "
                "of their coordinated motion around the gap (Gløersen & Federolf 2016)",
    needs=f"other markers measured through the gap and in the {PCA_WINDOW} frames on each side", code=6,
    colour=(196, 214, 72), fill=_pca, reach=PCA_WINDOW, menu_rank=1))
