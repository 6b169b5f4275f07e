"""Gaps in marker trajectories: detection, fills (linear, spline, pattern, rigid body, model,
PCA marker intercorrelation), the registry of fill methods, fill check."""

from handmocap.core.gaps import builtin_methods  # noqa: F401  (registers the built-in fill methods)
from handmocap.core.gaps.check import (
    MISSING,
    FillCheck,
    check_gap,
    fill_all,
    fill_gap,
    recommend,
)
from handmocap.core.gaps.context import ModelContext
from handmocap.core.gaps.detect import Gap, find_gaps
from handmocap.core.gaps.fills import (
    fill_linear,
    fill_model,
    fill_pattern,
    fill_rigid,
    fill_spline,
    minimum_acceleration_interpolation,
)
from handmocap.core.gaps.methods import (
    AUTO,
    FillMethod,
    check_fill_choice,
    fill_choices,
    fill_codes,
    fill_method,
    fill_method_names,
    fill_methods,
    menu_fill_methods,
    provenance_names,
    register_fill_method,
    unregister_fill_method,
)
from handmocap.core.gaps.pca import fill_pca

__all__ = [
    "AUTO", "MISSING", "FillCheck", "FillMethod", "Gap", "ModelContext", "check_fill_choice", "check_gap",
    "fill_all", "fill_choices", "fill_codes", "fill_gap", "fill_linear", "fill_method", "fill_method_names",
    "fill_methods", "fill_model", "fill_pattern", "fill_pca", "fill_rigid", "fill_spline", "find_gaps",
    "menu_fill_methods", "minimum_acceleration_interpolation", "provenance_names", "recommend",
    "register_fill_method", "unregister_fill_method",
]
