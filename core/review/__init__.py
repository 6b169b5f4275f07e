"""The review model of one take: labels, provenance, fills, confidence and solves, edited by undoable commands.

* :mod:`core.review.take` — :class:`ReviewTake` with its marker statistics, timeline lanes and problem list;
* :mod:`core.review.commands` — undoable, JSON-serialisable edits and the :class:`UndoStack` (history);
* :mod:`core.review.events` — the typed :class:`ReviewChanged` events the undo stack announces to views;
* :mod:`core.review.export` — labelled C3D, joint-angle CSV and BVH exports of a review, and the way back.
"""

from handmocap.core.model.provenance import MEASURED, MISSING
from handmocap.core.review.commands import (
    SCOPES,
    AcceptFills,
    AddEvent,
    ApplyLabelling,
    AssignLabel,
    Command,
    CompoundCommand,
    DefineHand,
    GapFill,
    LabellingArrays,
    MarkGhost,
    RejectFills,
    RemoveEvent,
    SetSolve,
    SwapLabels,
    TrimTake,
    UndoStack,
    Unlabel,
    command_from_json,
    resolve_track,
)
from handmocap.core.review.events import Change, FrameSpan, ReviewChanged
from handmocap.core.review.export import (
    export_bvh,
    export_joint_angles_csv,
    export_labelled_c3d,
    review_from_labelled_c3d,
)
from handmocap.core.review.take import (
    LANE_EDITED,
    LANE_FILLED,
    LANE_GAP,
    LANE_LOW_CONFIDENCE,
    LANE_NAMES,
    LANE_NONE,
    LANE_OBSERVED,
    PROBLEM_KINDS,
    HandTrack,
    MarkerStats,
    Problem,
    ReviewSettings,
    ReviewTake,
    detected_hands,
)

__all__ = [
    "LANE_EDITED", "LANE_FILLED", "LANE_GAP", "LANE_LOW_CONFIDENCE", "LANE_NAMES", "LANE_NONE",
    "LANE_OBSERVED", "MEASURED", "MISSING", "PROBLEM_KINDS", "SCOPES",
    "AcceptFills", "AddEvent", "ApplyLabelling", "AssignLabel", "Change", "Command", "CompoundCommand", "DefineHand",
    "FrameSpan",
    "GapFill", "HandTrack", "LabellingArrays", "MarkGhost", "MarkerStats", "Problem", "RejectFills", "RemoveEvent",
    "ReviewChanged", "ReviewSettings", "ReviewTake", "SetSolve", "SwapLabels", "TrimTake", "UndoStack", "Unlabel",
    "command_from_json", "detected_hands", "export_bvh", "export_joint_angles_csv", "export_labelled_c3d",
    "resolve_track", "review_from_labelled_c3d",
]
