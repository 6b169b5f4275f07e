"""Live capture against the stand-in server on 127.0.0.1, with the real client libraries (qtm-rt, natnet):
streaming, recording into a session, capture control, and every bad input as one line with the recording
so far kept. Bounded: short takes at 100-200 Hz, a few seconds each."""

from __future__ import annotations

import errno
import json
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io import load_take
from handmocap.core.io.system_labels import system_labels_summary
from handmocap.core.labelling.online import OnlineLabeller
from handmocap.core.labelling.scene import label_scene
from handmocap.core.live import recorder
from handmocap.core.live.capture import LiveCapture
from handmocap.core.live.recorder import FrameJournal, read_journal, read_system_labels
from handmocap.core.live.server import StandInServer, make_replay
from handmocap.core.live.sources import SourceError, parse_address
from handmocap.core.live.supervision import Supervisor
from handmocap.core.live.systems import make_source
from handmocap.core.session.session import Session
from handmocap.core.simulate.take import simulate_take

HANDMOCAP = [sys.executable, "-m", "handmocap.app.cli.main"]


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


def record_replay(replay, protocol: str, folder: Path, name: str, frames: int, out: str):
    """Stream ``replay`` once from a stand-in server, record it with ``auto`` hands into the session
    ``folder/session`` as take ``name`` until ``frames`` frames arrived, written to ``folder/out``; the
    capture's result."""
    server = StandInServer(replay, protocol, 0, loop_take=False).start()
    capture = LiveCapture(make_source(protocol, f"127.0.0.1:{server.port}"), "glove-13", "auto",
                          session=folder / "session", name=name, background_calibration=False)
    try:
        capture.start()
        assert wait_for(lambda: capture.frames_received >= frames, 10.0)
    finally:
        result = capture.stop(folder / out)
        server.stop()
    return result


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
    result = record_replay(make_replay(take, 100, unlabelled=True), "qtm", tmp_path, "trial 1", take.n_frames,
                           "trial.c3d")
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


@pytest.fixture(scope="module")
def labelled_take():
    """A take whose markers carry their layout names: the stand-in sends them as the system's labels."""
    return simulate_take("glove-13", n_frames=300, seed=6, noise_mm=0.3, ghost_rate=0.05, occlusion=True).take


@pytest.mark.parametrize("protocol", ["qtm", "natnet"])
def test_the_systems_labels_are_kept_with_the_take(labelled_take, tmp_path, protocol):
    take = labelled_take
    replay = make_replay(take, 100)
    assert replay.labels and len(replay.labels) < take.n_markers        # labelled markers and ghosts
    result = record_replay(replay, protocol, tmp_path, "sys", take.n_frames, "sys.c3d")
    labelled = sum(int(np.isfinite(frame).all(axis=1).sum()) for frame in replay.labelled)
    others = sum(len(frame) for frame in replay.unlabelled)
    figures = result.figures
    assert figures["frames_received"] == take.n_frames
    assert figures["system_labelled_share"] == pytest.approx(labelled / (labelled + others), abs=1e-4)
    assert figures["system_labels"] == len(replay.labels)
    assert figures["system_agreement"] > 0.95            # the live labels name the points as the system did
    line = [line for line in result.summary if "of the points itself" in line]
    assert len(line) == 1 and "live/sys.system-labels.npz" in line[0] and "\n" not in line[0]
    # per point: the label the system gave each recorded point names the take's marker at those coordinates
    recorded = load_take(tmp_path / "sys.c3d")
    system = read_system_labels(result.system_file)
    assert sorted(system.names) == sorted(replay.labels)
    assert system.codes.shape == (recorded.n_frames, recorded.n_markers)
    checked = 0
    for frame in range(0, take.n_frames, 7):
        for point, label in enumerate(system.labels_of(frame)):
            got = recorded.marker_positions[frame, point]
            if label:
                expected = take.marker_positions[frame, take.marker_names.index(label)]
                assert np.abs(got - expected).max() < 1e-3
                checked += 1
            else:
                assert np.isfinite(got).all()                 # an unlabelled point the system sent
    assert checked > 400                                      # 43 frames of 13 markers, some occluded
    # the raw points are unchanged: every frame holds the take's points
    for frame in (0, 150, 299):
        got = recorded.marker_positions[frame]
        expected = take.marker_positions[frame]
        assert np.allclose(np.sort(got[np.isfinite(got).all(axis=1)], axis=0),
                           np.sort(expected[np.isfinite(expected).all(axis=1)], axis=0), atol=1e-3)
    # the take's metadata says the system's labels exist and where they are
    group = recorded.parameters["SYSTEM_LABELS"]
    assert sorted(group["NAMES"]) == sorted(replay.labels)
    assert float(group["SHARE"]) == pytest.approx(figures["system_labelled_share"], abs=1e-4)
    assert Path(str(group["FILE"])) == result.system_file.absolute()
    session = Session.open(tmp_path / "session")
    try:
        assert session.take(result.take_id).results["system_labels"] == "live/sys.system-labels.npz"
    finally:
        session.close()
    # the journal holds them too (a recording recovered after a crash keeps them)
    journal = read_journal(tmp_path / "session" / "live" / "sys.hmlj")
    assert np.array_equal(journal.system().codes, system.codes) and journal.system_names == system.names
    assert sorted(journal.take().parameters["SYSTEM_LABELS"]["NAMES"]) == sorted(replay.labels)
    # handmocap info says so
    info = system_labels_summary(recorded.parameters["SYSTEM_LABELS"])
    assert info == {"source": info["source"], "labels": len(replay.labels),
                    "labelled_share": pytest.approx(figures["system_labelled_share"], abs=1e-4),
                    "file": str(result.system_file.absolute())}
    assert system_labels_summary({"SHARE": "x", "COUNT": [1]}) is None and system_labels_summary(None) is None


def test_a_stream_without_the_systems_labels_says_nothing_of_them(take, tmp_path):
    result = record_replay(make_replay(take, 100, unlabelled=True), "qtm", tmp_path, "plain", 200, "plain.c3d")
    assert result.system is None and result.figures["system_labelled_share"] is None
    assert "SYSTEM_LABELS" not in load_take(tmp_path / "plain.c3d").parameters
    assert not (tmp_path / "session" / "live" / "plain.system-labels.npz").exists()


def test_journal_keeps_the_systems_labels(tmp_path):
    journal = FrameJournal(tmp_path, tmp_path / "live" / "j.hmlj", {"frame_rate": 100, "source_label": "QTM"})
    journal.add_frame(1, 0.0, 0.0, np.zeros((3, 3)), np.array([0, -1, 1]), ["a", "b"])
    journal.add_frame(2, 0.01, 0.0, np.ones((2, 3)))                        # a frame without labels
    journal.add_frame(3, 0.02, 0.0, np.ones((4, 3)), np.array([2, 0, -1, -1]), ["a", "b", "ring tip"])
    journal.close()
    read = read_journal(tmp_path / "live" / "j.hmlj")
    assert read.system_names == ["a", "b", "ring tip"] and len(read.points) == 3
    system = read.system()
    assert system.labels_of(0) == ["a", "", "b"] and system.labels_of(1) == ["", ""]
    assert system.labels_of(2) == ["ring tip", "a", "", ""]
    assert system.labelled_share == pytest.approx(4 / 9)
    assert list(system.seen_share()) == pytest.approx([2 / 3, 1 / 3, 1 / 3])
    with open(tmp_path / "live" / "j.hmlj", "ab") as handle:     # a label index never introduced: the end
        handle.write(struct.pack("<4sqqddI", b"FRM1", 3, 4, 0.03, 0.0, 0))
        handle.write(struct.pack("<4sqIi", b"SYS1", 3, 1, 7))
    damaged = read_journal(tmp_path / "live" / "j.hmlj")
    assert len(damaged.points) == 4 and len(damaged.system_labels) == 2
    with pytest.raises(InputError, match="not a file of a capture system's labels"):
        read_system_labels(tmp_path / "live" / "j.hmlj")


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


def test_recording_follows_a_qtm_capture_already_running(take, tmp_path):
    server = StandInServer(make_replay(take, 100, unlabelled=True), "qtm", 0).start()
    server.capturing = True                     # QTM captures before we connect: GetState says so
    capture = LiveCapture(make_source("qtm", f"127.0.0.1:{server.port}"), "glove-13", "right",
                          session=tmp_path / "s", follow_system=True)
    try:
        capture.start()
        assert wait_for(lambda: capture.frames_received > 20)
        assert capture.system_capturing is True
    finally:
        capture.stop()
        server.stop()
    assert "getstate" in [command.lower() for command in server.commands]


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
    # every frame received is in the journal but the one whose write failed (none when a labels write failed)
    received = result.figures["frames_received"]
    assert len(journal.points) > 50 and received - 1 <= len(journal.points) <= received
    assert journal.take().n_frames == len(journal.points)


def test_journal_survives_a_killed_process(tmp_path):
    script = f"""
import os, numpy as np
from pathlib import Path
from handmocap.core.live.recorder import FrameJournal
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
    from handmocap.core.io import save_take

    save_take(take, tmp_path / "raw.c3d")
    port = free_port()
    serve = subprocess.Popen(HANDMOCAP + ["live", "serve", str(tmp_path / "raw.c3d"),
                              "--protocol", "natnet", "--port", str(port), "--unlabelled", "--seconds", "30"],
                             stderr=subprocess.PIPE, text=True)
    try:
        serve.stderr.readline()
        record = subprocess.run(HANDMOCAP + ["live", "record", "--natnet",
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
    failed = subprocess.run(HANDMOCAP + ["live", "record", "--qtm",
                             f"127.0.0.1:{free_port()}", "--seconds", "1", "--out", str(tmp_path / "x.c3d")],
                            capture_output=True, text=True, timeout=60)
    assert failed.returncode == 2 and len(failed.stderr.strip().splitlines()) == 1
    assert "Traceback" not in failed.stderr
