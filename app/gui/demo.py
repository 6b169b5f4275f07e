"""The demo session: a session folder with a raw (unlabelled) simulated take to auto-label and review, a
labelled simulated take, a labelled simulated take filmed by a calibrated, registered 30 Hz RGB-D camera (a 3.1 s
640×480 video and its 16-bit depth frames in mm, whose first frame is at mocap time :data:`CAMERA_OFFSET_S`; Solve ▸
Fuse with RGB-D works on it), and, when the shared data
folder is present, the real DFKI glove recording (``../shared/data/real``; or
``$HANDMOCAP_SHARED/data/real``).

The folder is ``$HANDMOCAP_DEMO_SESSION`` or ``~/.cache/handmocap/demo-session``; it is made once and
reopened afterwards (with the operator's edits), and remade when it is damaged.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import numpy as np

from handmocap.core.camera.files import load_camera, save_camera
from handmocap.core.camera.writers import write_depth_frames, write_video
from handmocap.core.errors import HandMocapError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.io import save_take
from handmocap.core.session import Session
from handmocap.core.session.cameras import add_camera
from handmocap.core.simulate import simulate_take
from handmocap.core.simulate.camera import random_camera, simulate_camera_take

RAW_TAKE = "simulated raw take (dense, unlabelled).c3d"
LABELLED_TAKE = "simulated grasps (dense, labelled).trc"
CAMERA_TAKE = "simulated take with a camera (dense, labelled).c3d"
CAMERA_VIDEO = "camera video (30 Hz).avi"
CAMERA_DEPTH = "camera depth (30 Hz)"
CAMERA_FILE = "camera.json"
CAMERA_FRAMES = 320        # mocap frames at 100 Hz: a 3.2 s take, a 3.1 s video of 93 camera frames
CAMERA_OFFSET_S = 0.12     # the camera clock's known offset (s)
CAMERA_DISTANCE_MM = 450.0  # from the workspace centre: the hand fills a good part of the image


def demo_folder() -> Path:
    """Where the demo session lives."""
    configured = os.environ.get("HANDMOCAP_DEMO_SESSION")
    return Path(configured) if configured else Path.home() / ".cache" / "handmocap" / "demo-session"


def prepare_demo_session(folder: Path | None = None) -> Path:
    """The demo session folder, made (takes written and added) when it does not hold a usable session."""
    folder = folder or demo_folder()
    if (folder / "session.json").exists():
        try:
            session = Session.open(folder)
            if session.takes:
                session.close()
                return folder
        except HandMocapError:
            pass
        shutil.move(folder, folder.with_name(f"{folder.name}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"))
    session = Session.create(folder, name="Demo session")
    files = folder / "files"
    files.mkdir(exist_ok=True)
    if REAL_RECORDING.exists():
        session.add_take(REAL_RECORDING, subject="DFKI subject", layout="glove-13", name="DFKI glove recording (real)")
    labelled = simulate_take(layout="dense", n_frames=900, seed=1, noise_mm=0.3, occlusion=True).take
    save_take(labelled, files / LABELLED_TAKE)
    session.add_take(files / LABELLED_TAKE, subject="simulated subject", layout="dense", take=labelled)
    raw = simulate_take(layout="dense", n_frames=900, seed=3, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                        unlabelled=True).take
    save_take(raw, files / RAW_TAKE)
    session.add_take(files / RAW_TAKE, subject="simulated subject", layout="dense", take=raw)
    _add_camera_take(session, files)
    session.close()
    return folder


def _add_camera_take(session: Session, files: Path) -> None:
    """A labelled simulated take, its RGB-D camera's video and depth frames (rendered once: the depth costs about
    0.9 s more than the video alone) and the camera file (the simulation's truth: intrinsics, pose and clock),
    added to ``session`` with its camera."""
    filmed = simulate_camera_take(seed=7, n_frames=CAMERA_FRAMES, mocap_rate=100.0, offset_s=CAMERA_OFFSET_S,
                                  camera=random_camera(7, distance=CAMERA_DISTANCE_MM))
    take = filmed.simulated.take
    save_take(take, files / CAMERA_TAKE)
    entry = session.add_take(files / CAMERA_TAKE, subject="simulated subject", layout="dense", take=take,
                             name="simulated take with a camera")
    camera = filmed.camera
    depths = []

    def colours():
        for index in range(len(filmed.camera_times)):
            colour, depth = filmed.render(index)
            assert depth is not None, "rendered with depth"      # (render's default)
            depths.append(np.round(depth).astype(np.uint16))
            yield colour

    write_video(files / CAMERA_VIDEO, colours(), filmed.frame_rate, camera.size)
    (files / CAMERA_DEPTH).mkdir(exist_ok=True)
    write_depth_frames(files / CAMERA_DEPTH, depths, 1.0)
    save_camera(camera, files / CAMERA_FILE)
    add_camera(session, entry.id, load_camera(files / CAMERA_FILE), files / CAMERA_VIDEO, files / CAMERA_DEPTH, 1.0)
