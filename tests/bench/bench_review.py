"""Review benchmark: how long the operator waits for the review operations on a long take (10 000 frames,
48 labels, 52 points) in a session: applying a labelling (journalled), lanes / statistics / problem
list, an edit over the whole take, undo and redo, saving the snapshot, reopening with a journal to
replay, labelled C3D export and import.

Run: python tests/bench/bench_review.py [frames]
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handmocap.core.io import save_take
from handmocap.core.review import (
    ApplyLabelling,
    AssignLabel,
    SwapLabels,
    export_labelled_c3d,
    review_from_labelled_c3d,
)
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session


def timed(figures: dict, name: str, operation):
    """Run ``operation``, store its wall time in ms under ``name``, return its result."""
    start = time.perf_counter()
    result = operation()
    figures[name] = round(1000.0 * (time.perf_counter() - start), 1)
    return result


def main() -> None:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    take, labelling, _ = synthetic_labelling(frames=frames, labels=48, ghosts=4, seed=0, spacing_mm=30)
    folder = Path(tempfile.mkdtemp())
    save_take(take, folder / "raw.c3d")
    session = Session.create(folder / "session")
    entry = session.add_take(folder / "raw.c3d")
    opened = session.open_take(entry.id)
    figures: dict = {"frames": frames, "labels": 48, "points": take.n_markers}
    timed(figures, "apply_labelling_ms", lambda: opened.push(ApplyLabelling(labelling)))
    review = opened.review
    timed(figures, "lanes_ms", review.lane_states)
    timed(figures, "stats_ms", review.marker_stats)
    timed(figures, "problems_ms", review.problems)
    column = int(review.assignment[100, 3])
    timed(figures, "assign_whole_take_ms", lambda: opened.push(AssignLabel(100, column, "M5", scope="take")))
    timed(figures, "undo_ms", opened.undo)
    timed(figures, "redo_ms", opened.redo)
    timed(figures, "save_ms", opened.save)
    figures["snapshot_mb"] = round(opened.snapshot_path.stat().st_size / 1e6, 2)
    for step in range(20):
        opened.push(SwapLabels("M1", "M2", 10 * step, 10 * step + 10))
    opened.close(save=False)
    reopened = timed(figures, "reopen_with_20_journal_entries_ms", lambda: Session.open(folder / "session")
                     .open_take(entry.id))
    assert np.array_equal(reopened.review.assignment, review.assignment)
    timed(figures, "export_c3d_ms", lambda: export_labelled_c3d(review, folder / "labelled.c3d"))
    timed(figures, "import_c3d_ms", lambda: review_from_labelled_c3d(folder / "labelled.c3d"))
    for key, value in figures.items():
        print(f"  {key:<36} {value}")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
