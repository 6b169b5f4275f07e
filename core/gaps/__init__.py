"""Gaps in marker trajectories: detection, fills (linear, spline, pattern, rigid body, model,
PCA marker intercorrelation), fill check."""

from handmocap.core.gaps.check import (
    FILL_METHODS,
    METHOD_CODES,
    MISSING,
    FillCheck,
    ModelContext,
    check_gap,
    fill_all,
    fill_gap,
    recommend,
)
from handmocap.core.gaps.detect import Gap, find_gaps
from handmocap.core.gaps.fills import (
    fill_linear,
    fill_model,
    fill_pattern,
    fill_rigid,
    fill_spline,
    minimum_acceleration_interpolation,
)
from handmocap.core.gaps.pca import fill_pca

__all__ = [
    "FILL_METHODS", "METHOD_CODES", "MISSING", "FillCheck", "Gap", "ModelContext", "check_gap",
    "fill_all", "fill_gap", "fill_linear", "fill_model", "fill_pattern", "fill_pca",
    "fill_rigid", "fill_spline", "find_gaps", "minimum_acceleration_interpolation",
    "recommend",
]
