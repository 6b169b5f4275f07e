"""Where the shared evaluation data lives: ``$HANDMOCAP_SHARED`` or the ``shared`` folder next to the project,
holding ``data/`` (the real DFKI glove recording, vendor C3D files, glTF hands, real depth frames).

The data is never copied into the project; evaluations, the demo session and the tests read it from here
and skip (or say so) when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

PROJECT_SHARED = Path(__file__).resolve().parents[3] / "shared"


def shared_folder() -> Path:
    """``$HANDMOCAP_SHARED`` when set, else ``../shared`` next to the project (it may not exist)."""
    configured = os.environ.get("HANDMOCAP_SHARED")
    return Path(configured) if configured else PROJECT_SHARED


SHARED_DATA = shared_folder() / "data"
REAL_RECORDING = SHARED_DATA / "real" / "dfki_glove_right_hand_frames_0001_3000.tsv"
VENDOR_C3D = SHARED_DATA / "c3d"
GLTF_TEMPLATES = SHARED_DATA / "templates"
RGBD_FRAMES = SHARED_DATA / "rgbd"
