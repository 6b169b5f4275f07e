"""Workflows shared by the command line and the GUI: auto-label a take into a review, re-solve the hands
after an edit, find, check, preview and fill the gaps of a review."""

from handmocap.core.workflows.filling import (
    GapGroup,
    ReviewGap,
    check_review_gap,
    fill_gaps,
    fill_review_gaps,
    find_review_gaps,
    gap_groups,
    preview_fill,
    short_open_gaps,
)
from handmocap.core.workflows.labelling import AutoLabelOutcome, auto_label, hand_tracks, labelling_report
from handmocap.core.workflows.resolve import ResolveJob, hand_models_for, resolve_hands, resolve_jobs, run_resolve_jobs

__all__ = [
    "AutoLabelOutcome", "GapGroup", "ResolveJob", "ReviewGap", "auto_label", "check_review_gap", "fill_gaps",
    "fill_review_gaps", "find_review_gaps", "gap_groups", "hand_models_for", "hand_tracks", "labelling_report",
    "preview_fill", "resolve_hands", "resolve_jobs", "run_resolve_jobs", "short_open_gaps",
]
