"""Sessions and take review: the review data model, undoable edits, the edit journal, the session folder.

* :mod:`core.session.review` — :class:`ReviewTake` (labels, provenance, fills, confidence, solves of a
  take) with its marker statistics, timeline lanes and problem list;
* :mod:`core.session.commands` — undoable, JSON-serialisable edits and the :class:`UndoStack`;
* :mod:`core.session.journal` — the fsync'ed edit journal replayed on open;
* :mod:`core.session.session` — :class:`Session` (a folder with a manifest) and :class:`OpenTake`;
* :mod:`core.session.export` — labelled C3D, joint-angle CSV and BVH exports of a review.
"""

from core.session.commands import (
    SCOPES,
    AcceptFills,
    ApplyLabelling,
    AssignLabel,
    Command,
    CompoundCommand,
    DefineHand,
    FrameSpan,
    GapFill,
    LabellingArrays,
    MarkGhost,
    RejectFills,
    SetSolve,
    SwapLabels,
    UndoStack,
    Unlabel,
    command_from_json,
    resolve_track,
)
from core.session.export import (
    export_bvh,
    export_joint_angles_csv,
    export_labelled_c3d,
    review_from_labelled_c3d,
)
from core.session.journal import Journal
from core.session.review import (
    FILL_CODES,
    LANE_EDITED,
    LANE_FILLED,
    LANE_GAP,
    LANE_LOW_CONFIDENCE,
    LANE_NAMES,
    LANE_NONE,
    LANE_OBSERVED,
    MEASURED,
    MISSING,
    PROBLEM_KINDS,
    PROVENANCE_NAMES,
    HandTrack,
    MarkerStats,
    Problem,
    ReviewSettings,
    ReviewTake,
)
from core.session.session import TAKE_STATES, OpenTake, Session, SubjectEntry, TakeEntry

__all__ = [
    "FILL_CODES", "LANE_EDITED", "LANE_FILLED", "LANE_GAP", "LANE_LOW_CONFIDENCE", "LANE_NAMES", "LANE_NONE",
    "LANE_OBSERVED", "MEASURED", "MISSING", "PROBLEM_KINDS", "PROVENANCE_NAMES", "SCOPES", "TAKE_STATES",
    "AcceptFills", "ApplyLabelling", "AssignLabel", "Command", "CompoundCommand", "DefineHand", "FrameSpan", "GapFill",
    "HandTrack", "Journal", "LabellingArrays", "MarkGhost", "MarkerStats", "OpenTake", "Problem", "RejectFills",
    "ReviewSettings", "ReviewTake", "Session", "SetSolve", "SubjectEntry", "SwapLabels", "TakeEntry", "UndoStack",
    "Unlabel", "command_from_json", "export_bvh", "export_joint_angles_csv", "export_labelled_c3d",
    "resolve_track", "review_from_labelled_c3d",
]
