"""Live capture against the stand-in server on 127.0.0.1, with the real client libraries (qtm-rt, natnet):
streaming, recording into a session, capture control, and every bad input as one line with the recording
so far kept. Bounded: short takes at 100-200 Hz, a few seconds each."""

from __future__ import annotations

import errno
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from core.errors import InputError
from core.io import load_take
from core.labelling.online import OnlineLabeller
from core.labelling.scene import label_scene
from core.live import recorder
from core.live.capture import LiveCapture
from core.live.recorder import FrameJournal, read_journal
from core.live.server import StandInServer, make_replay
from core.live.sources import SourceError, parse_address
from core.live.supervision import Supervisor
from core.live.systems import make_source
from core.session.session import Session
from core.simulate.take import simulate_take


@pytest.fixture(scope="module")
def take():
    return simulate_take("glove-13", n_frames=400, seed=4, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                         unlabelled=True).take


class Sink:
    def __init__(self) -> None:
        self.frames, self.events, self.failures = [], [], []

    def frame(self, frame) -> None:
        self.frames.append(frame)

    def event(self, name: str) -> None:
        self.events.append(name)

    def failed(self, message: str) -> None:
        self.failures.append(message)


def wait_for(condition, seconds: float = 5.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


@pytest.mark.parametrize("protocol", ["qtm", "natnet"])
def test_real_clients_stream_the_points_unchanged(take, protocol):
    server = StandInServer(make_replay(take, 200, unlabelled=True), protocol, 0).start()
    try:
        source = make_source(protocol, f"127.0.0.1:{server.port}")
        sink = Sink()
        source.start(sink)
        assert wait_for(lambda: len(sink.frames) >= 60)
        source.stop()
    finally:
        server.stop()
    assert not sink.failures
    numbers = [frame.number for frame in sink.frames]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))        # none dropped on loopback
    for frame in sink.frames[:40]:
        expected = take.marker_positions[(frame.number - 1) % take.n_frames]
        expected = expected[np.isfinite(expected).all(axis=1)]
        assert frame.points.shape == expected.shape
        assert np.abs(np.sort(frame.points, axis=0) - np.sort(expected, axis=0)).max() < 1e-3   # float32 on the wire
    if protocol == "qtm":
        assert source.frame_rate == 200


def test_capture_records_labels_and_enters_the_session(take, tmp_path):
    server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0, loop_take=False).start()
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", "auto",
                          session=tmp_path / "session", name="trial 1", background_calibration=False)
    try:
        capture.start()
        assert wait_for(lambda: capture.frames_received >= take.n_frames, 10.0)
    finally:
        result = capture.stop(tmp_path / "trial.c3d")
        server.stop()
    figures = result.figures
    assert figures["frames_received"] == take.n_frames and figures["frames_dropped"] == 0
    assert figures["latency_ms_p99"] is not None and figures["labelled_share"] > 0.85
    recorded = load_take(tmp_path / "trial.c3d")
    assert recorded.n_frames == take.n_frames
    for frame in (0, 150, 399):     # the raw points as received, in the order received
        got = recorded.marker_positions[frame]
        expected = take.marker_positions[frame]
        assert np.allclose(np.sort(got[np.isfinite(got).all(axis=1)], axis=0),
                           np.sort(expected[np.isfinite(expected).all(axis=1)], axis=0), atol=1e-3)
    session = Session.open(tmp_path / "session")
    try:
        entry = session.take(result.take_id)
        assert entry.name == "trial_1" and entry.state == "labelled"
        opened = session.open_take(entry.id)
        assert opened.stack.undo_text().startswith("live labels")
        assert (opened.review.assignment >= 0).mean() == pytest.approx(figures["labelled_share"], abs=1e-4)
        opened.close(save=False)
    finally:
        session.close()
    # the live labels agree with the same take labelled offline in online mode
    offline = label_scene(recorded, hands="auto", layout="glove-13", online=True)
    live, other = result.labelling.assignment, offline.assignment
    either = (live >= 0) | (other >= 0)
    assert ((live == other) & either).sum() / either.sum() > 0.95


def test_online_labeller_matches_the_online_mode(take):
    offline = label_scene(take, hands="auto", layout="glove-13", online=True)
    labeller = OnlineLabeller("glove-13", "auto", background_calibration=False)
    labelled = 0
    for points in take.marker_positions:
        labelled += len(labeller.push(points))
    assert labelled == take.n_frames
    result = labeller.finish(take.frame_rate)
    assert result.marker_names == offline.marker_names
    assert np.array_equal(result.assignment, offline.assignment)


def test_qtm_capture_control_and_a_second_master(take):
    server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0, password="pw").start()
    first, second = (make_source("qtm", f"127.0.0.1:{server.port}") for _ in range(2))
    sink, other = Sink(), Sink()
    try:
        first.start(sink)
        second.start(other)
        with pytest.raises(SourceError, match="password"):
            first.control("takecontrol", "wrong")
        assert first.control("takecontrol", "pw") == "You are now master"
        with pytest.raises(SourceError, match="already taken"):
            second.control("takecontrol", "pw")
        assert first.control("new") == "Creating new connection"
        assert first.control("start") == "Starting measurement"
        assert wait_for(lambda: "capture started" in other.events)
        assert first.control("stop") == "Stopping measurement"
        assert first.control("save", "S01 trial 2") == "Measurement saved"
        assert server.saved == ["S01 trial 2"]
        assert wait_for(lambda: "capture stopped" in sink.events)
    finally:
        first.stop()
        second.stop()
        server.stop()


def test_recording_follows_qtm_start_and_stop(take, tmp_path):
    server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0).start()
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", "right",
                          session=tmp_path / "s", follow_system=True)
    try:
        capture.start()
        time.sleep(0.3)
        assert capture.frames_received == 0
        capture.control("takecontrol")
        capture.control("start")
        time.sleep(1.0)
        capture.control("stop")
        assert wait_for(capture._stopping.is_set)
    finally:
        result = capture.stop(tmp_path / "followed.c3d")
        server.stop()
    assert 60 <= result.figures["frames_received"] <= 140


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_bad_inputs_are_one_line(take, tmp_path):
    port = free_port()
    with pytest.raises(SourceError, match="nothing answers"):
        make_source("qtm", f"127.0.0.1:{port}").start(Sink(), timeout=2)
    with pytest.raises(SourceError, match="no NatNet server answers"):
        make_source("natnet", f"127.0.0.1:{port}").start(Sink(), timeout=1)
    with pytest.raises(InputError, match="port"):
        parse_address("127.0.0.1:99999", 1)
    with pytest.raises(InputError, match="unknown live source"):
        make_source("vicon", "127.0.0.1")
    old = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0, qtm_max_version=(1, 20)).start()
    try:
        with pytest.raises(SourceError, match="does not speak RT protocol version 1.25"):
            make_source("qtm", f"127.0.0.1:{old.port}").start(Sink())
    finally:
        old.stop()
    single = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0, single_client=True).start()
    first = make_source("qtm", f"127.0.0.1:{single.port}")
    try:
        first.start(Sink())
        with pytest.raises(SourceError, match="Another client"):
            make_source("qtm", f"127.0.0.1:{single.port}").start(Sink())
    finally:
        first.stop()
        single.stop()


@pytest.mark.parametrize("protocol", ["qtm", "natnet"])
def test_garbage_and_a_server_gone_keep_the_recording(take, tmp_path, protocol):
    server = StandInServer(make_replay(take, 100, unlabelled=True), protocol, 0, garbage_after=120).start()
    capture = LiveCapture(make_source(protocol, f"127.0.0.1:{server.port}"), "glove-13", "right",
                          session=tmp_path / "s", reconnect=False)
    try:
        capture.start()
        assert wait_for(lambda: capture.messages, 6.0)
    finally:
        server.stop()
        result = capture.stop(tmp_path / "partial.c3d")
    assert len(result.messages) == 1 and "\n" not in result.messages[0]
    assert ("cannot read" in result.messages[0] or "RT packet" in result.messages[0]
            or "overrun" in result.messages[0])
    assert 100 <= result.figures["frames_received"] <= 125
    assert load_take(tmp_path / "partial.c3d").n_frames == result.figures["frames_received"]


def test_reconnects_after_the_server_went_away(take, tmp_path):
    server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0).start()
    port = server.port
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{port}"), "glove-13", "right", session=tmp_path / "s")
    try:
        capture.start()
        assert wait_for(lambda: capture.frames_received > 50)
        server.stop()
        assert wait_for(lambda: any("closed the connection" in m for m in capture.messages))
        before = capture.frames_received
        server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", port).start()
        assert wait_for(lambda: capture.frames_received > before + 50, 8.0)
        assert any(message.startswith("reconnected") for message in capture.messages)
    finally:
        result = capture.stop(tmp_path / "resumed.c3d")
        server.stop()
    assert load_take(tmp_path / "resumed.c3d").n_frames == result.figures["frames_received"]


def test_a_full_disk_stops_the_recording_and_keeps_what_was_written(take, tmp_path, monkeypatch):
    real_write = os.write
    budget = {"bytes": 60_000}

    def write(descriptor, data):
        budget["bytes"] -= len(data)
        if budget["bytes"] < 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(descriptor, data)

    server = StandInServer(make_replay(take, 100, unlabelled=True), "natnet", 0).start()
    capture = LiveCapture(make_source("natnet", f"127.0.0.1:{server.port}"), "glove-13", "right",
                          session=tmp_path / "s")
    monkeypatch.setattr(recorder.os, "write", write)
    try:
        capture.start()
        assert wait_for(lambda: capture.recording_error, 6.0)
    finally:
        result = capture.stop()
        server.stop()
    assert capture.recording_error.startswith("the disk is full: the recording stopped after")
    journal = read_journal(tmp_path / "s" / "live" / "live.hmlj")
    assert 50 < len(journal.points) == result.figures["frames_received"] - 1
    assert journal.take().n_frames == len(journal.points)


def test_journal_survives_a_killed_process(tmp_path):
    script = f"""
import os, numpy as np
from pathlib import Path
from core.live.recorder import FrameJournal
journal = FrameJournal(Path({str(tmp_path)!r}), Path({str(tmp_path / 'live' / 'k.hmlj')!r}), {{"frame_rate": 100}})
for index in range(250):
    journal.add_frame(index + 1, index / 100, 0.0, np.full((5, 3), float(index)))
    journal.add_labels(index, np.arange(5))
os.kill(os.getpid(), 9)
"""
    process = subprocess.run([sys.executable, "-c", script], timeout=60)
    assert process.returncode == -9
    journal = read_journal(tmp_path / "live" / "k.hmlj")
    assert len(journal.points) == 250 and len(journal.labels) == 250
    assert np.all(journal.points[249] == 249.0)
    with open(tmp_path / "live" / "k.hmlj", "ab") as handle:      # a torn last record is dropped
        handle.write(b"FRM1\x00\x01")
    assert len(read_journal(tmp_path / "live" / "k.hmlj").points) == 250
    with pytest.raises(InputError, match="exists already"):
        FrameJournal(tmp_path, tmp_path / "live" / "k.hmlj", {})


def test_a_stream_with_no_hand_says_so(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.uniform(-1000, 1000, (300, 6, 3))                # scattered points, no hand
    labeller = OnlineLabeller("glove-13", "auto")
    for frame in points:
        assert labeller.push(frame) == []
    assert "initialises a hand" in labeller.startup_error
    with pytest.raises(InputError, match="hand"):
        labeller.finish(100.0)


def test_supervision_alarms_and_summary():
    supervisor = Supervisor([("right", "right", slice(0, 3))], ["index_tip", "ring_tip", "hand_top"], 100.0,
                            unseen_seconds=1.0)
    alarms = []
    for frame in range(300):
        assignment = np.array([0, 1 if frame < 100 else -1, 2]) if frame < 200 else np.array([-1, -1, 2])
        alarms += supervisor.update(assignment, np.full(3, 0.5), np.full(3, 5.0))
    assert any("ring tip (right) not seen for 1 s" in alarm for alarm in alarms)
    assert any("right hand is lost" in alarm for alarm in alarms)
    status = supervisor.status()[0]
    assert status.light == "red" and "ring_tip" in status.missing
    summary = supervisor.summary()
    assert "ring tip missing 67 % of the take: retake?" in summary


def test_cli_record_json_last_line(take, tmp_path):
    from core.io import save_take

    save_take(take, tmp_path / "raw.c3d")
    port = free_port()
    serve = subprocess.Popen([sys.executable, "-m", "app.cli.main", "live", "serve", str(tmp_path / "raw.c3d"),
                              "--protocol", "natnet", "--port", str(port), "--unlabelled", "--seconds", "30"],
                             stderr=subprocess.PIPE, text=True)
    try:
        serve.stderr.readline()
        record = subprocess.run([sys.executable, "-m", "app.cli.main", "live", "record", "--natnet",
                                 f"127.0.0.1:{port}", "--layout", "glove-13", "--hands", "auto", "--seconds", "3",
                                 "--out", str(tmp_path / "rec.c3d"), "--json", "--quiet"],
                                capture_output=True, text=True, timeout=60)
    finally:
        serve.terminate()
        serve.wait(10)
    assert record.returncode == 0, record.stderr
    figures = json.loads(record.stdout.strip().splitlines()[-1])
    for key in ("frames_received", "frames_dropped", "latency_ms_p50", "latency_ms_p99", "labelled_share"):
        assert key in figures
    assert figures["frames_received"] > 200 and figures["frames_dropped"] == 0
    assert Path(figures["session"]).joinpath("session.json").exists()
    failed = subprocess.run([sys.executable, "-m", "app.cli.main", "live", "record", "--qtm",
                             f"127.0.0.1:{free_port()}", "--seconds", "1", "--out", str(tmp_path / "x.c3d")],
                            capture_output=True, text=True, timeout=60)
    assert failed.returncode == 2 and len(failed.stderr.strip().splitlines()) == 1
    assert "Traceback" not in failed.stderr
