"""The hand model: skeleton, skinned template mesh, marker layouts, kinematics."""

from __future__ import annotations

from functools import lru_cache

from handmocap.core.errors import InputError
from handmocap.core.io.resources import resource_path
from handmocap.core.model.hand_columns import HandColumns, detect_hands, hand_layout, name_side, track_layout
from handmocap.core.model.hand_model import HandModel, mean_vertex_error, skin_vertices
from handmocap.core.model.markers import (
    MarkerLayout,
    MarkerSet,
    MarkerSpec,
    add_layout_folder,
    best_layout_for,
    layout_names,
    load_layout,
    marker_columns,
    marker_jacobian,
    marker_positions,
    marker_positions_batch,
    remove_layout_folder,
    resolve_layout,
    save_layout,
)
from handmocap.core.model.skeleton import N_PARAMS, PARAM_NAMES, default_joint_limits

TEMPLATE_PATH = resource_path("template", "right_hand.npz")


@lru_cache(maxsize=4)
def load_template(side: str = "right") -> HandModel:
    """The shipped template hand (``resources/template/right_hand.npz``); the left hand mirrors it."""
    if side not in ("right", "left"):
        raise InputError(f"hand side must be 'right' or 'left', not '{side}'")
    if not TEMPLATE_PATH.exists():
        raise InputError(f"template missing: {TEMPLATE_PATH} (run 'handmocap template build')")
    model = HandModel.load(TEMPLATE_PATH)
    return model if side == "right" else model.mirrored()


__all__ = [
    "HandColumns", "HandModel", "MarkerLayout", "MarkerSet", "MarkerSpec", "N_PARAMS", "PARAM_NAMES", "TEMPLATE_PATH",
    "add_layout_folder", "best_layout_for", "detect_hands", "hand_layout",
    "default_joint_limits", "layout_names", "load_layout", "load_template", "marker_columns", "marker_jacobian",
    "marker_positions", "marker_positions_batch", "mean_vertex_error", "name_side", "remove_layout_folder",
    "resolve_layout", "save_layout",
    "skin_vertices", "track_layout",
]
