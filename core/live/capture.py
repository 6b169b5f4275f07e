"""A live capture: a source streams frames, each is journalled and labelled causally as it arrives, the
supervisor follows the hands, and at the end the take enters the session with the live labels as its first
review step.

Threads: the source's own (it only puts frames on an unbounded queue: no frame is ever dropped here), and
the capture's worker, which journals each frame at once (:mod:`core.live.recorder`), labels it
(:class:`core.labelling.online.OnlineLabeller`), updates the supervision (:mod:`core.live.supervision`) and
publishes the latest labelled frame for a view (:meth:`LiveCapture.snapshot`, which a view reads at its own
pace: drawing drops frames, the capture never does). The latency of a frame is measured from the moment its
packet had been read to the moment it is labelled. When the source fails (the server gone), the capture
reconnects every second while it runs; the frames the system numbered meanwhile count as dropped. With
``follow_system`` the recording follows the capture system's own start and stop (QTM's events); until the
system starts, the points streamed are shown (a preview snapshot), not recorded.

The capture system's own labels (:attr:`LiveFrame.labels`) are journalled with each frame and kept with the
take (:class:`core.live.recorder.SystemLabels`: the take's C3D parameter group ``SYSTEM_LABELS`` and a sidecar
in the session, entered in the take's ``results`` as ``system_labels``); the share the system labelled is in
the figures (``system_labelled_share``) and the end-of-capture summary, with, where its label names are the
layout's, how often its labels agree with the live ones (``system_agreement``).
"""

from __future__ import annotations

import queue
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.c3d_writer import write_c3d
from handmocap.core.io.system_labels import SYSTEM_GROUP
from handmocap.core.labelling.online import LabelledFrame, OnlineLabeller
from handmocap.core.labelling.result import SceneLabelling
from handmocap.core.live.recorder import (
    FrameJournal,
    RecordingError,
    SystemLabels,
    system_labels,
    write_system_labels,
)
from handmocap.core.live.sources import LiveFrame, LiveSource
from handmocap.core.live.supervision import ModelStatus, Supervisor
from handmocap.core.model.lab_template import LabTemplate
from handmocap.core.review import ApplyLabelling, LabellingArrays
from handmocap.core.session.session import Session
from handmocap.core.workflows.labelling import hand_tracks, labelling_report

RECONNECT_SECONDS = 1.0
RATE_FRAMES = 20
#: the figures a snapshot carries are computed afresh at most this often (percentiles over the whole capture)
FIGURES_SECONDS = 0.2


@dataclass
class Snapshot:
    """The latest labelled frame for a view: its index, points ``(N,3)`` mm, the point each marker took, the
    marker names, the models' states and statuses, the alarms so far and the capture's figures."""

    frame: int
    points: np.ndarray
    assignment: np.ndarray
    marker_names: list[str]
    states: dict[str, np.ndarray]
    statuses: list[ModelStatus]
    alarms: list[str]
    figures: dict[str, Any] = field(default_factory=dict)
    #: (M,) the model (index into ``statuses``) each marker belongs to
    model_of_marker: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    #: False for a preview: the points streamed while the recording waits for the system's start
    recording: bool = True


@dataclass
class CaptureResult:
    """What a finished capture gives: the take file written, the session and take id, the labelling, the
    figures (``frames_received``, ``frames_dropped``, ``latency_ms_p50``/``p99``, ``labelled_share``...),
    the end-of-capture ``summary`` lines and the ``messages`` (failures, reconnections); the capture system's
    own labels (``system``, None when it sent none) and the sidecar they were written to."""

    out: Path | None
    session: Path | None
    take_id: str | None
    labelling: SceneLabelling | None
    figures: dict[str, Any]
    summary: list[str]
    messages: list[str]
    system: SystemLabels | None = None
    system_file: Path | None = None


class LiveCapture:
    """One capture from ``source`` (module docstring). ``layout``, ``hands``, ``objects`` as for
    :func:`core.labelling.scene.label_scene`; ``session``: the session folder (created when missing) the
    journal and the take go into; ``name``: the take's name (also the journal's)."""

    def __init__(self, source: LiveSource, layout: str | LabTemplate = "dense", hands: str = "auto",
                 objects: Any = None, session: str | Path | None = None, name: str = "live",
                 background_calibration: bool = True, reconnect: bool = True, follow_system: bool = False,
                 unseen_seconds: float = 3.0) -> None:
        self.source, self.layout, self.hands, self.objects = source, layout, hands, objects
        self.session_folder = Path(session) if session is not None else None
        self.name = _safe_name(name)
        self.labeller = OnlineLabeller(layout, hands, objects, background_calibration=background_calibration)
        self.reconnect, self.follow_system, self.unseen_seconds = reconnect, follow_system, unseen_seconds
        self.recording = not follow_system
        self.queue: queue.Queue[tuple[str, Any]] = queue.Queue()
        self.journal: FrameJournal | None = None
        self.supervisor: Supervisor | None = None
        self.frames_received = 0
        self.frames_dropped = 0
        self._last_number: int | None = None
        self._received: list[float] = []
        self._points: list[np.ndarray] = []
        self.latencies: list[float] = []
        #: True once the labeller has started and labelled every frame queued meanwhile: the latency of the
        #: frames before (the start-up) is reported apart (``startup_frames``, ``startup_ms``)
        self.caught_up = False
        self.startup_latencies: list[float] = []
        self.messages: list[str] = []
        self.events: list[str] = []
        self.recording_error = ""
        self._snapshot: Snapshot | None = None
        self._owners = np.empty(0, dtype=np.int64)
        self._lock = threading.Lock()
        self._worker: threading.Thread | None = None
        self._stopping = threading.Event()
        self._failed_at: float | None = None
        self._timestamps: list[float] = []
        self.frame_rate: float | None = None
        self.started = time.monotonic()
        #: the capture system's labels: their names (first seen first), per recorded frame the name index per
        #: point (None: the frame came without labels), and the points it labelled so far
        self.system_names: list[str] = []
        self._system_index: dict[str, int] = {}
        self._system_codes: list[np.ndarray | None] = []
        self.system_labelled = 0
        self.points_received = 0
        #: the system's state from its events (QTM): True while it captures, None before any event says
        self.system_capturing: bool | None = None
        #: True once the recording ended (stopped here, or by the system's stop when following it)
        self.ended = False
        self._closed = False
        self._figures: dict[str, Any] = {}
        self._figures_at = -1.0

    # --- the sink the source calls (its thread) ------------------------------------------------------------

    def frame(self, frame: LiveFrame) -> None:
        if not self._closed:
            self.queue.put(("frame", frame))

    def event(self, name: str) -> None:
        if not self._closed:
            self.queue.put(("event", name))

    def failed(self, message: str) -> None:
        if not self._closed:
            self.queue.put(("failed", message))

    # --- running ------------------------------------------------------------------------------------------

    def start(self, timeout: float = 5.0) -> None:
        """Warm the labeller up, connect (SourceError when it cannot) and start the worker."""
        warm_up(self.layout, self.hands)
        self.source.start(self, timeout)
        self.frame_rate = self.source.frame_rate
        self.started = time.monotonic()
        self._worker = threading.Thread(target=self._work, name="live-capture", daemon=True)
        self._worker.start()

    def run_for(self, seconds: float) -> None:
        """Capture for ``seconds`` (reconnecting when the source fails), then return (call :meth:`stop`)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end and not self._stopping.is_set():
            time.sleep(min(0.05, max(end - time.monotonic(), 0.0)))

    def _work(self) -> None:
        while True:
            try:
                kind, value = self.queue.get(timeout=RECONNECT_SECONDS)
            except queue.Empty:
                if self._stopping.is_set():
                    return
                self._try_reconnect()
                continue
            if kind == "stop":
                return
            if kind == "frame":
                self._take_frame(value)
            elif kind == "event":
                self._on_event(value)
            elif kind == "failed":
                self.messages.append(value)
                self._failed_at = time.monotonic()
                self.source.stop()
            if self._failed_at is not None and not self._stopping.is_set():
                self._try_reconnect()

    def _try_reconnect(self) -> None:
        if self._failed_at is None or not self.reconnect or self._stopping.is_set():
            return
        if time.monotonic() - self._failed_at < RECONNECT_SECONDS:
            return
        try:
            self.source.start(self, timeout=2.0)
        except InputError:
            self._failed_at = time.monotonic()
            return
        self.messages.append(f"reconnected to {self.source.address}")
        self._failed_at = None

    def _on_event(self, name: str) -> None:
        self.events.append(name)
        if name == "capture started":
            self.system_capturing = True
        elif name in ("capture stopped", "connected", "connection closed"):
            self.system_capturing = False
        if not self.follow_system or self.ended:
            return
        if name == "capture started" and not self._stopping.is_set():
            self.recording = True
        elif name == "capture stopped" and self.recording:
            self.recording = False
            self.ended = True
            self._stopping.set()

    def _take_frame(self, frame: LiveFrame) -> None:
        if self._last_number is not None and frame.number > self._last_number + 1:
            self.frames_dropped += frame.number - self._last_number - 1
        self._last_number = frame.number
        if not self.recording:
            if self.follow_system and not self.ended and not self._stopping.is_set():
                self._publish_preview(frame.points)
            return
        self.frames_received += 1
        self._timestamps.append(frame.timestamp_s)
        if self.frame_rate is None:
            self.frame_rate = _rate_from(self._timestamps)
        if self.journal is None and not self.recording_error:
            self._open_journal()
        index = len(self._received)
        self._received.append(frame.received)
        self._points.append(frame.points)
        codes = self._system_labels_of(frame)
        self._system_codes.append(codes)
        self.points_received += len(frame.points)
        if self.journal is not None:
            try:
                self.journal.add_frame(frame.number, frame.timestamp_s, frame.received, frame.points,
                                       codes, self.system_names)
            except RecordingError as error:
                self._stop_recording(str(error))
                return
        try:
            labelled = self.labeller.push(frame.points)
        except InputError as error:
            self.messages.append(f"labelling stopped: {error}")
            labelled = []
        done = time.perf_counter()
        if self.labeller.started and not self.caught_up and self.queue.empty():
            self.caught_up = True          # the start-up window labelled and the frames queued meanwhile
        for result in labelled:
            (self.latencies if self.caught_up else self.startup_latencies).append(done - self._received[result.frame])
            self._labelled(result)
        if index == 0 or not labelled:
            self._publish_unlabelled(index, frame.points)

    def _system_labels_of(self, frame: LiveFrame) -> np.ndarray | None:
        """Per point of ``frame`` the index into :attr:`system_names` of the system's label (-1 none); None when
        the frame came without labels (or with a label list that does not match its points)."""
        labels = frame.labels
        if not labels or len(labels) != len(frame.points):
            return None
        codes = np.full(len(labels), -1, dtype=np.int32)
        for point, label in enumerate(labels):
            if label:
                code = self._system_index.get(label)
                if code is None:
                    code = self._system_index[label] = len(self.system_names)
                    self.system_names.append(label)
                codes[point] = code
        self.system_labelled += int((codes >= 0).sum())
        return codes

    def system_labels(self, frames: int | None = None, columns: int | None = None) -> SystemLabels | None:
        """The capture system's labels of the frames recorded so far (None when it sent none), for the first
        ``frames`` frames and ``columns`` point slots (the take's) when given."""
        if not self.system_names:
            return None
        points = [len(points) for points in self._points][:frames]
        return system_labels(self.source.label, self.system_names, self._system_codes, points, columns)

    def _open_journal(self) -> None:
        if self.session_folder is None:
            return
        try:
            session = Session.open(self.session_folder) if (self.session_folder / "session.json").exists() \
                else Session.create(self.session_folder)
            session.close()
            path = self.session_folder / "live" / f"{self.name}.hmlj"
            self.journal = FrameJournal(self.session_folder, path, {
                "name": self.name, "frame_rate": self.frame_rate, "source": self.source.kind,
                "source_label": self.source.label, "address": self.source.address,
                "layout": _layout_name(self.layout), "hands": self.hands})
        except (InputError, OSError) as error:
            self._stop_recording(f"the recording cannot be journalled: {error}")

    def _stop_recording(self, message: str) -> None:
        self.recording_error = message
        self.messages.append(message)
        self.recording = False
        self._stopping.set()

    def _labelled(self, result: LabelledFrame) -> None:
        if self.supervisor is None:
            self._make_supervisor()
        assert self.supervisor is not None
        alarms = self.supervisor.update(result.assignment, result.residuals_mm, result.confidence)
        self.messages += alarms
        if self.journal is not None and not self.recording_error:
            try:
                self.journal.add_labels(result.frame, result.assignment)
            except RecordingError as error:
                self._stop_recording(str(error))
        snapshot = Snapshot(result.frame, self._points[result.frame], result.assignment,
                            self.labeller.marker_names, result.states, self.supervisor.status(),
                            list(self.supervisor.alarms), self._recent_figures(), self._owners)
        with self._lock:
            self._snapshot = snapshot

    def _make_supervisor(self) -> None:
        run = self.labeller.run
        assert run is not None
        models = [(track.name, track.kind, run.columns(number)) for number, track in enumerate(run.tracks)]
        self.supervisor = Supervisor(models, self.labeller.marker_names, self.frame_rate or 100.0, self.unseen_seconds)
        self._owners = np.concatenate([np.full(track.count, number) for number, track in enumerate(run.tracks)])

    def _publish_unlabelled(self, index: int, points: np.ndarray) -> None:
        with self._lock:
            if self._snapshot is None or not self.labeller.started:
                self._snapshot = Snapshot(index, points, np.empty(0, dtype=np.int64), [], {}, [],
                                          [self.labeller.startup_error] if self.labeller.startup_error else [],
                                          self._recent_figures())

    def _publish_preview(self, points: np.ndarray) -> None:
        snapshot = Snapshot(-1, points, np.empty(0, dtype=np.int64), [], {}, [], [], self._recent_figures(),
                            recording=False)
        with self._lock:
            self._snapshot = snapshot

    def _recent_figures(self) -> dict[str, Any]:
        """:meth:`figures`, computed afresh at most every :data:`FIGURES_SECONDS` (a snapshot per frame would
        otherwise sort every latency of the capture at every frame)."""
        now = time.monotonic()
        if now - self._figures_at >= FIGURES_SECONDS:
            self._figures, self._figures_at = self.figures(), now
        return self._figures

    def snapshot(self) -> Snapshot | None:
        """The latest labelled frame (None before the first): what a view draws at its own pace."""
        with self._lock:
            return self._snapshot

    def control(self, command: str, argument: str = "") -> str:
        """Capture control on the system (QTM): see :meth:`LiveSource.control`."""
        return self.source.control(command, argument)

    # --- the end -------------------------------------------------------------------------------------------

    def figures(self) -> dict[str, Any]:
        """The capture's figures so far (module and :class:`CaptureResult` docstrings)."""
        latencies = np.array(self.latencies) * 1000.0
        startup = np.array(self.startup_latencies) * 1000.0
        labelled = [status.labelled_share for status in self.supervisor.status()] if self.supervisor else []
        return {
            "frames_received": self.frames_received, "frames_dropped": self.frames_dropped,
            "frames_labelled": self.labeller.labelled,
            "latency_ms_p50": round(float(np.percentile(latencies, 50)), 2) if len(latencies) else None,
            "latency_ms_p99": round(float(np.percentile(latencies, 99)), 2) if len(latencies) else None,
            "latency_ms_max": round(float(latencies.max()), 2) if len(latencies) else None,
            "startup_frames": len(startup), "startup_ms": round(float(startup.max()), 1) if len(startup) else None,
            "labelled_share_now": round(float(np.mean(labelled)), 3) if labelled else None,
            "frame_rate_hz": self.frame_rate,
            "system_labelled_share": round(self.system_labelled / self.points_received, 4)
            if self.points_received and self.system_names else None,
            "system_capturing": self.system_capturing,
        }

    def stop(self, out: str | Path | None = None, overwrite: bool = False, disconnect: bool = True) -> CaptureResult:
        """End the recording, label what is left, and (with ``out``) write the take and enter it in the session.
        ``disconnect=False`` keeps the source connected for capture control (QTM's Save after its Stop): the
        frames it streams afterwards are ignored; :meth:`close` disconnects."""
        self._stopping.set()
        if disconnect:
            self.close()
        self.queue.put(("stop", None))
        if self._worker is not None:
            self._worker.join()
        self._closed = True                          # nothing more is queued: later frames are ignored
        while not self.queue.empty():               # frames that arrived after the stop marker
            kind, value = self.queue.get_nowait()
            if kind == "frame":
                self._take_frame(value)
        self.recording = False
        self.ended = True
        if self.journal is not None:
            self.journal.close()
        figures = self.figures()
        labelling = None
        summary = self.supervisor.summary() if self.supervisor is not None else []
        messages = list(self.messages)
        try:
            labelling = self.labeller.finish(self.frame_rate)
        except InputError as error:
            messages.append(f"no labels: {error}")
        if labelling is not None:
            labelled = labelling.assignment >= 0
            figures["labelled_share"] = round(float(labelled.mean()), 4) if labelled.size else 0.0
            hands = [model for model in labelling.models if model.kind in ("right", "left")]
            figures["hands"] = {model.name: round(float(labelled[:, model.markers].mean()), 4) for model in hands}
        else:
            figures["labelled_share"] = 0.0
        take = self.labeller.take(self.frame_rate or 100.0)
        system = self.system_labels(take.n_frames, take.n_markers)
        if system is not None:
            figures["system_labelled_share"] = round(system.labelled_share, 4)
            figures["system_labels"] = len(system.names)
            agreement = system_agreement(system, labelling) if labelling is not None else None
            if agreement is not None:
                figures["system_agreement"] = agreement
        take_id = None
        written = system_file = None
        if out is not None and self.frames_received:
            written, take_id, system_file = self._save(take, Path(out), labelling, system, overwrite, messages)
        if system is not None:
            kept = (_relative_to(system_file, self.session_folder) if system_file is not None else
                    f"the journal {self.journal.path}" if self.journal is not None else "nothing: it was not saved")
            summary.append(_system_summary(system, figures.get("system_agreement"), kept))
        return CaptureResult(written, self.session_folder, take_id, labelling, figures, summary, messages,
                             system, system_file)

    def _save(self, take: Take, out: Path, labelling: SceneLabelling | None, system: SystemLabels | None,
              overwrite: bool, messages: list[str]) -> tuple[Path | None, str | None, Path | None]:
        if out.exists() and not overwrite:
            messages.append(f"{out} exists; the take was not written (the journal keeps the frames)")
            return None, None, None
        system_file = self._save_system_labels(system, out, overwrite, messages) if system is not None else None
        if system is not None:
            take.parameters[SYSTEM_GROUP] = system.parameters(str(system_file.absolute()) if system_file else None)
        try:
            write_c3d(take, out)
        except (InputError, OSError) as error:
            messages.append(f"the take could not be written: {error} (the journal keeps the frames)")
            return None, None, system_file
        if self.session_folder is None:
            return out, None, system_file
        try:
            session = Session.open(self.session_folder) if (self.session_folder / "session.json").exists() \
                else Session.create(self.session_folder)
        except (InputError, OSError) as error:
            messages.append(f"the take was written but not entered into the session: {error}")
            return out, None, system_file
        try:
            sides = [model.kind for model in labelling.models if model.kind in ("right", "left")] \
                if labelling is not None else []
            entry = session.add_take(out, layout=_layout_name(self.layout), hands=sides or ["right"],
                                     name=self.name, labelled=False, take=take)
            if system_file is not None:
                relative = system_file.relative_to(self.session_folder).as_posix()
                session.update(lambda: session.take(entry.id).results.__setitem__("system_labels", relative))
            if labelling is not None:
                opened = session.open_take(entry.id)
                try:
                    opened.push(_review_step(labelling, self.layout))
                    opened.save()
                finally:
                    opened.close(save=False)
                session.set_state(entry.id, "labelled")
            return out, entry.id, system_file
        except (InputError, OSError) as error:
            messages.append(f"the take was written but not entered into the session: {error}")
            return out, None, system_file
        finally:
            session.close()

    def _save_system_labels(self, system: SystemLabels, out: Path, overwrite: bool, messages: list[str]
                            ) -> Path | None:
        """The sidecar of the system's labels: in the session's ``live`` folder beside the journal (beside the
        take without a session); None, with a message, when it cannot be written."""
        folder = self.session_folder
        path = (folder / "live" / f"{self.name}.system-labels.npz") if folder is not None \
            else out.with_name(f"{out.stem}.system-labels.npz")
        if path.exists() and not overwrite:
            messages.append(f"{path} exists; the system's labels were not written beside the take (the journal "
                            "keeps them)")
            return None
        try:
            write_system_labels(system, path, folder)
        except (InputError, OSError) as error:
            messages.append(f"the system's labels could not be written: {error} (the journal keeps them)")
            return None
        return path

    def close(self) -> None:
        """Disconnect from the capture system (idempotent; :meth:`stop` does it unless ``disconnect=False``)."""
        self.source.stop()


def warm_up(layout: str | LabTemplate, hands: str = "auto", frames: int = 80) -> None:
    """Label a short simulated stream of ``layout`` once, so that the first real frames find the labeller's
    kernels loaded (about a second otherwise, which the frames of the start-up would wait)."""
    from handmocap.core.model import load_layout
    from handmocap.core.simulate.take import simulate_take

    try:
        plain = layout.layout_for("right") if isinstance(layout, LabTemplate) else load_layout(layout)
        positions = simulate_take(plain, n_frames=frames, seed=1, unlabelled=True).take.marker_positions
        labeller = OnlineLabeller(plain, "right" if hands == "auto" else hands.replace("both", "right"),
                                  background_calibration=False)
        for points in positions:
            labeller.push(points)
    except (InputError, ValueError):
        return


def _review_step(labelling: SceneLabelling, layout: str | LabTemplate) -> ApplyLabelling:
    """The live labels as an undoable review step."""
    arrays = LabellingArrays(list(labelling.marker_names), labelling.assignment.copy(), labelling.confidence.copy(),
                             labelling.residuals_mm.copy(), labelling.ghost_points.copy(),
                             hand_tracks(labelling, _layout_name(layout)), rigid_bodies=labelling.rigid_bodies,
                             health=list(labelling.health), noise_mm=labelling.noise_mm)
    return ApplyLabelling(arrays, hands=arrays.hands, description=f"live labels ({_layout_name(layout)})")


def live_report(result: CaptureResult) -> dict[str, Any]:
    """The figures of a capture and its labelling's report (JSON-ready)."""
    report = dict(result.figures)
    if result.labelling is not None:
        report["labelling"] = labelling_report(result.labelling, 0.0)
    report["summary"], report["messages"] = result.summary, result.messages
    return report


def system_agreement(system: SystemLabels, labelling: SceneLabelling) -> float | None:
    """Of the points both the system and the live labelling labelled, where the system's label is one of the
    labelling's marker names: the share given the same name (None when no label name is shared)."""
    names = list(labelling.marker_names)
    index = {name: marker for marker, name in enumerate(names)}
    as_marker = np.array([index.get(name, -1) for name in system.names] + [-1], dtype=np.int64)
    if not (as_marker >= 0).any():
        return None
    frames = min(len(system.codes), len(labelling.assignment))
    columns = system.codes.shape[1]
    ours = np.full((frames, columns + 1), -1, dtype=np.int64)
    assignment = labelling.assignment[:frames]
    rows, markers = np.nonzero(assignment >= 0)
    points = np.minimum(assignment[rows, markers], columns)            # a point beyond the table: dropped
    ours[rows, points] = markers
    theirs = as_marker[system.codes[:frames]]
    both = (ours[:, :columns] >= 0) & (theirs >= 0)
    if not both.any():
        return None
    return round(float((ours[:, :columns] == theirs)[both].mean()), 4)


def _relative_to(path: Path, folder: Path | None) -> str:
    return path.relative_to(folder).as_posix() if folder is not None and path.is_relative_to(folder) else str(path)


def _system_summary(system: SystemLabels, agreement: float | None, where: str) -> str:
    """The end-of-capture line on the capture system's own labels (``where``: where they are kept)."""
    return (f"{system.source or 'the capture system'} labelled {100 * system.labelled_share:.1f} % of the points "
            f"itself ({len(system.names)} label{'s' if len(system.names) != 1 else ''})"
            + (f"; its labels agree with the live ones on {100 * agreement:.1f} % of the points both labelled"
               if agreement is not None else "")
            + f"; kept per point in {where}")


def _rate_from(timestamps: list[float]) -> float | None:
    if len(timestamps) < RATE_FRAMES:
        return None
    steps = np.diff(np.array(timestamps[-RATE_FRAMES:]))
    steps = steps[np.isfinite(steps) & (steps > 0)]
    return round(float(1.0 / np.median(steps)), 3) if len(steps) else None


def _layout_name(layout: Any) -> str:
    return layout if isinstance(layout, str) else str(getattr(layout, "name", "layout"))


def _safe_name(name: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("._") or "live"
    return cleaned[:80]

