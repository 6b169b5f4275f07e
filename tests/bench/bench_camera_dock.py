"""Camera dock speed while scrubbing (issue 14: a new decoded 640×480 frame with its overlay in ≤ 30 ms).

A simulated 4 s take (100 Hz) with its 30 Hz 640×480 camera video, written as Motion-JPEG AVI (every frame a
key frame) and as MPEG-4 MP4 (seeks decode from the previous key frame), is opened in the main window from a
session; the timeline is moved (a) forward one mocap frame at a time, (b) backward one at a time, (c) to random
frames. Timed per new camera frame, once the other views have drawn the frame change (not timed): ``dock``, the
dock's draw (camera frame lookup, decode or cache, projection, colours, skeleton) and its canvas painted
(QImage + QPainter overlay) into an image; ``repaint``, the canvas repainted on screen, which includes the
window's composition with the OpenGL 3D view (software GL under Xvfb: the same cost for any widget's repaint).
The window is 1500×1100 with the dock as in resources/screenshots/camera_dock.png.

Run (needs a display or QT_QPA_PLATFORM=offscreen): python tests/bench/bench_camera_dock.py [--json]
"""

import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen" if not os.environ.get("DISPLAY") else "xcb")

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.main_window import MainWindow
from handmocap.core.camera.writers import write_video
from handmocap.core.io import save_take
from handmocap.core.session import Session
from handmocap.core.session.cameras import add_camera
from handmocap.core.simulate.camera import random_camera, simulate_camera_take

MOCAP_FRAMES = int(os.environ.get("BENCH_MOCAP_FRAMES", "400"))
RANDOM_JUMPS = 60


def make_session(folder: Path, suffix: str) -> Path:
    simulated = simulate_camera_take(seed=7, n_frames=MOCAP_FRAMES, mocap_rate=100.0, offset_s=0.12,
                                     camera=random_camera(7, distance=450.0))
    save_take(simulated.simulated.take, folder / "take.c3d")
    video = folder / f"video{suffix}"
    write_video(video, (simulated.render(k, with_depth=False)[0] for k in range(len(simulated.camera_times))),
                simulated.frame_rate, simulated.camera.size)
    session = Session.create(folder / "session")
    entry = session.add_take(folder / "take.c3d", layout="dense")
    add_camera(session, entry.id, simulated.camera, video)
    session.close()
    return folder / "session"


def scrub(app: QApplication, window: MainWindow, frames: list[int]) -> dict:
    """Per new camera frame over ``frames``: ``dock`` ms (the draw and the canvas painted into an image) and
    ``repaint`` ms (a synchronous repaint of the canvas on screen, with the window's composition)."""
    controller, canvas = window.cameras, window.cameras.view.canvas
    target = QImage(canvas.size(), QImage.Format.Format_ARGB32_Premultiplied)
    dock, repaint = [], []
    for frame in frames:
        before = controller._shown_key
        window.app.set_frame(frame)
        app.processEvents()                  # the 3D view, timeline, tracks draw the frame (not timed)
        start = time.perf_counter()
        controller.draw_now()
        canvas.render(target)
        middle = time.perf_counter()
        canvas.repaint()
        end = time.perf_counter()
        if before is None or controller._shown_key[2] != before[2]:
            dock.append(1000.0 * (middle - start))
            repaint.append(1000.0 * (end - middle))
        app.processEvents()
    return {"dock": summary(dock), "repaint": summary(repaint)}


def summary(times: list[float]) -> dict:
    return {"frames": len(times), "median_ms": round(float(np.median(times)), 2),
            "p95_ms": round(float(np.percentile(times, 95)), 2), "max_ms": round(float(np.max(times)), 2)}


def main() -> dict:
    app = QApplication.instance() or QApplication([])
    results = {}
    for suffix in (".avi", ".mp4"):
        with tempfile.TemporaryDirectory() as name:
            folder = make_session(Path(name), suffix)
            window = MainWindow()
            window.show()
            window.sessions.open_session(folder)
            window.sessions.open_take(window.sessions.session.takes[0].id)
            while window.loader.is_busy() or window.document is None:
                app.processEvents()
            for _ in range(20):
                app.processEvents()
            window.resize(1500, 1100)           # the layout of resources/screenshots/camera_dock.png
            for _ in range(20):
                app.processEvents()
            window.resizeDocks([window.timeline_dock, window.tracks_dock], [110, 160], Qt.Orientation.Vertical)
            window.resizeDocks([window.markers_dock, window.camera_dock], [150, 760], Qt.Orientation.Vertical)
            for _ in range(20):
                app.processEvents()
            canvas = window.cameras.view.canvas
            window.cameras._draw_timer.timeout.disconnect()     # the dock draws when timed, not on its own
            rng = np.random.default_rng(0)
            results[suffix[1:]] = {
                "canvas_px": [canvas.width(), canvas.height()],
                "forward": scrub(app, window, list(range(0, MOCAP_FRAMES))),
                "backward": scrub(app, window, list(range(MOCAP_FRAMES - 1, -1, -1))),
                "random": scrub(app, window, [int(f) for f in rng.integers(0, MOCAP_FRAMES, RANDOM_JUMPS)]),
            }
            window.close()
            window.deleteLater()
            app.processEvents()
    results["load_average"] = [round(value, 1) for value in os.getloadavg()]
    return results


if __name__ == "__main__":
    figures = main()
    print(json.dumps(figures, indent=1) if "--json" in sys.argv else figures)
