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
    from handmocap.core.live.capture import LiveCapture
    from handmocap.core.live.server import StandInServer, make_replay
    from handmocap.core.live.systems import make_source
    from handmocap.core.simulate.scene import simulate_scene

    scene = simulate_scene("glove-13", n_frames=1500, seed=5, hands=hands, n_objects=objects, frame_rate=100.0)
    server = StandInServer(make_replay(scene.take, 100, unlabelled=True), "qtm", 0).start()
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", hands, scene.objects,
                          session=tmp_path / "session", name="live-demo")
    capture.start()
    return server, capture


def test_live_window_draws_at_its_own_pace(qtbot, tmp_path):
    from handmocap.app.gui.live_window import LiveWindow

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


def test_qtm_control_buttons_drive_the_server_and_the_recording_follows(qtbot, tmp_path, monkeypatch):
    """The window's QTM buttons against the stand-in QTM on 127.0.0.1 (a free port): the server sees each
    command, our recording starts with QTM's capture and ends with its stop (the take then enters the session),
    and QTM can still save its measurement afterwards. A refused command is one line."""
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QMessageBox

    from handmocap.app.gui.live_window import LiveWindow
    from handmocap.core.live.capture import LiveCapture
    from handmocap.core.live.server import StandInServer, make_replay
    from handmocap.core.live.systems import make_source
    from handmocap.core.session.session import Session
    from handmocap.core.simulate.take import simulate_take

    refusals: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda _parent, _title, text: refusals.append(text))
    take = simulate_take("glove-13", n_frames=1500, seed=7, noise_mm=0.3, frame_rate=100.0).take   # labelled
    server = StandInServer(make_replay(take, 100), "qtm", 0, password="pw").start()
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", "right",
                          session=tmp_path / "session", name="followed", follow_system=True)
    capture.start()
    window = LiveWindow(capture, tmp_path / "session", "followed", password="pw")
    qtbot.addWidget(window)
    window.show()
    buttons = window.control_buttons

    def click(command: str) -> None:
        qtbot.mouseClick(buttons[command], Qt.MouseButton.LeftButton)

    try:
        assert set(buttons) == {"takecontrol", "new", "start", "stop", "save"}
        qtbot.waitUntil(lambda: window.drawn > 0, timeout=10000)         # the points streamed, shown
        assert "waiting for Qualisys QTM to start a capture" in window.status.text()
        assert capture.frames_received == 0                              # ... not recorded
        click("start")                                                    # without control: refused in a line
        assert len(refusals) == 1 and "\n" not in refusals[0] and "take control" in refusals[0]
        assert not server.capturing
        click("takecontrol")
        assert server.master is not None and window.answers[-1] == "You are now master"
        click("new")
        click("start")
        assert server.capturing
        qtbot.waitUntil(lambda: capture.frames_received > 0, timeout=5000)
        qtbot.waitUntil(lambda: capture.labeller.started, timeout=30000)
        qtbot.wait(500)
        click("stop")
        assert not server.capturing
        qtbot.waitUntil(lambda: window.result is not None, timeout=30000)   # the take written on QTM's stop
        result = window.result
        # exactly the frames QTM sent between its start and stop events (one stream carries both)
        events = dict(server.events)
        assert result.figures["frames_received"] == events["capture stopped"] - events["capture started"] > 50
        assert result.figures["frames_dropped"] == 0
        assert result.out is not None and result.out.exists() and result.take_id
        assert result.figures["system_labelled_share"] > 0.5               # QTM's own labels came with them
        assert any("of the points itself" in line for line in result.summary)
        received = capture.frames_received
        window.save_name.setText("S01 trial 3")
        click("save")                                                     # QTM still answers after our stop
        assert server.saved == ["S01 trial 3"] and window.answers[-1] == "Measurement saved"
        qtbot.wait(300)
        assert capture.frames_received == received                        # nothing recorded after QTM's stop
        sent = [command.lower() for command in server.commands]
        for expected in ("takecontrol pw", "new", "start", "stop", "save s01 trial 3"):
            assert any(command.startswith(expected) for command in sent), (expected, sent)
        session = Session.open(tmp_path / "session")
        try:
            assert session.take(result.take_id).state == "labelled"
        finally:
            session.close()
    finally:
        window.close()
        server.stop()


def main(out: str) -> int:
    import tempfile

    from PySide6.QtWidgets import QApplication

    from handmocap.app.gui.live_window import LiveWindow

    app = QApplication.instance() or QApplication(sys.argv)
    with tempfile.TemporaryDirectory() as tmp:
        server, capture = _start(Path(tmp))
        window = LiveWindow(capture, Path(tmp) / "session", "live-demo")
        window.show()
        end = time.monotonic() + 6.0
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.01)
        window.view.render_now()
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
