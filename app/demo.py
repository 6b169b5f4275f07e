"""The demo session: a simulated take and, when the shared data folder is present, the real DFKI
glove recording (``../shared/data/real``; or ``$HANDMOCAP_SHARED/data/real``)."""

from __future__ import annotations

import os
from pathlib import Path

from core.io import Take, load_take
from core.simulate import simulate_take

REAL_RECORDING = "dfki_glove_right_hand_frames_0001_3000.tsv"


def shared_folder() -> Path | None:
    """``../shared`` next to the project (or ``$HANDMOCAP_SHARED``) when it exists."""
    candidates = [os.environ.get("HANDMOCAP_SHARED"), Path(__file__).resolve().parents[2] / "shared"]
    for candidate in candidates:
        if candidate and Path(candidate, "data").is_dir():
            return Path(candidate)
    return None


def demo_takes() -> list[tuple[str, Take]]:
    """(title, take) pairs of the demo session."""
    simulated = simulate_take(layout="dense", n_frames=900, seed=1, noise_mm=0.3, occlusion=True).take
    takes = [("Simulated grasps (dense layout)", simulated)]
    shared = shared_folder()
    if shared is not None and (shared / "data" / "real" / REAL_RECORDING).exists():
        takes.insert(0, ("DFKI glove recording (real, glove-13)", load_take(shared / "data" / "real" / REAL_RECORDING)))
    return takes
