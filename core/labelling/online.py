"""The labeller driven one frame at a time as frames arrive (live capture): causal, with the same trackers
as :func:`core.labelling.scene.label_scene` in online mode.

:class:`OnlineLabeller` keeps the frames received so far in growing arrays and runs the scene's per-frame
step (:meth:`core.labelling.scene._Run.track_frame`) on each new frame as it is pushed. What the offline
online mode measures on the whole take it measures on a short **start-up window** (the first
``hypothesis_frames + 1`` frames, half a second at 100 Hz): the take's noise and speed (the gates) and,
with ``hands="auto"``, the side of each hand (:func:`core.labelling.sides.decide_sides` tracks each
side's fit over that window). The window's frames are labelled at once when it closes; every frame after
it is labelled as it arrives. Without a hand in the window, the window slides on (frames left behind stay
unlabelled) until one shows. The subject calibration runs after ``calibration_frames`` tracked frames as
in the online mode, on a thread of its own when ``background_calibration`` (so that the stream does not
wait for it), and the calibrated hand tracks from the first frame after it is ready.

:meth:`OnlineLabeller.finish` completes the labelling as the online mode does (trajectories extended
forward into continuing free points, free trajectories given to a hand marker on the evidence of their
first ``fragment_min_frames`` frames: both causal) and returns a :class:`SceneLabelling` of every frame
pushed, with the points exactly as they were pushed.
"""

from __future__ import annotations

import copy
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.labelling.health import assess_labelling
from handmocap.core.labelling.hypotheses import check_whole_take
from handmocap.core.labelling.models import HandTracker, SceneSettings
from handmocap.core.labelling.scene import (
    SceneLabelling,
    _calibrate,
    _link_and_rescue,
    _main_run,
    _result,
    _Run,
    _Scene,
    _scene,
)
from handmocap.core.labelling.take_statistics import TakeStatistics, measure_take
from handmocap.core.model import N_PARAMS, HandModel, MarkerLayout, MarkerSet
from handmocap.core.model.lab_template import LabTemplate
from handmocap.core.model.objects import ObjectSpec

#: frames between two start-up attempts when the window showed no hand (hands="auto")
STARTUP_RETRY = 25


@dataclass
class LabelledFrame:
    """The live labels of one frame: its index among the frames pushed, ``assignment (M,)`` the index of
    the point (in the order pushed) each scene marker took (-1 missing), ``residuals_mm (M,)`` (NaN
    missing), ``confidence (M,)`` mm margins, ``states`` per model name (hand θ (26,), object pose (4,4);
    NaN when not tracked)."""

    frame: int
    assignment: np.ndarray
    residuals_mm: np.ndarray
    confidence: np.ndarray
    states: dict[str, np.ndarray]


class OnlineLabeller:
    """Label frames one at a time (module docstring). ``layout``: a layout or lab template (or its name or
    path); ``hands``: "auto", "right", "left" or "both"; ``objects``: rigid object specs or a scene spec path.

    :meth:`push` takes a frame's points ``(N,3)`` mm (NaN rows: no point) and returns the frames labelled by
    it (none during the start-up window, the whole window when it closes, else the frame itself).
    """

    def __init__(self, layout: str | MarkerLayout | LabTemplate = "dense", hands: str = "auto",
                 objects: Sequence[ObjectSpec] | str | Path | None = None, settings: SceneSettings | None = None,
                 models: dict[str, HandModel] | None = None, startup_frames: int | None = None,
                 background_calibration: bool = True) -> None:
        self.layout, self.hands, self.objects, self.models = layout, hands, objects, models
        self.base_settings = settings or SceneSettings()
        if hands not in ("auto", "right", "left", "both"):
            raise InputError(f"hands must be one of auto, right, left, both, not '{hands}'")
        self.startup_frames = max(5, startup_frames or self.base_settings.hypothesis_frames + 1)
        self.background_calibration = background_calibration
        self.frames = 0
        self.labelled = 0            # frames labelled so far (the first ``labelled`` frames)
        self.window_start = 0        # first frame of the start-up window
        self.positions = np.full((256, 16, 3), np.nan)
        self.run: _Run | None = None
        self.scene: _Scene | None = None
        self.statistics: TakeStatistics | None = None
        self.startup_error = ""
        self._next_attempt = self.startup_frames
        self._pending_calibration: set[int] = set()
        self._calibrations: dict[int, threading.Thread] = {}
        self._calibrated: dict[int, tuple] = {}
        self._lock = threading.Lock()

    # --- frames in --------------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        """True once the start-up window has closed on a scene (frames are then labelled as they come)."""
        return self.run is not None

    @property
    def marker_names(self) -> list[str]:
        """The scene's marker names once started (else empty)."""
        return [] if self.run is None else [name for track in self.run.tracks for name in track.marker_names]

    def push(self, points: np.ndarray) -> list[LabelledFrame]:
        """Add one frame's points ``(N,3)`` mm and label what can be labelled now (class docstring)."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        frame = self.frames
        self._ensure(frame + 1, len(points))
        self.positions[frame, :len(points)] = points
        self.frames += 1
        if self.run is not None:
            self._sync(frame + 1, len(points))
            self._apply_calibrations()
            return [self._track(frame)]
        if self.frames >= self._next_attempt:
            return self._start()
        return []

    def _ensure(self, frames: int, points: int) -> None:
        capacity, columns = self.positions.shape[:2]
        if frames <= capacity and points <= columns:
            return
        new_capacity = max(capacity, 2 * frames) if frames > capacity else capacity
        new_columns = max(columns, 2 * points) if points > columns else columns
        grown = np.full((new_capacity, new_columns, 3), np.nan)
        grown[:capacity, :columns] = self.positions
        self.positions = grown
        if self.run is not None:
            run = self.run
            run.positions = grown
            present = np.zeros((new_capacity, new_columns), dtype=bool)
            present[:capacity, :columns] = run.present
            run.present = present
            markers = run.assignment.shape[1]
            assignment = np.full((new_capacity, markers), -1, dtype=np.int64)
            assignment[:capacity] = run.assignment
            run.assignment = assignment
            for name in ("confidence", "residuals"):
                values = np.full((new_capacity, markers), np.nan)
                values[:capacity] = getattr(run, name)
                setattr(run, name, values)
            states: list[np.ndarray] = []
            for state in run.states:
                values = np.full((new_capacity, *state.shape[1:]), np.nan)
                values[:capacity] = state
                states.append(values)
            run.states = states

    def _sync(self, frames: int, points: int) -> None:
        """Mark the new frame's points present in the run."""
        assert self.run is not None
        frame = frames - 1
        self.run.present[frame] = np.isfinite(self.positions[frame]).all(axis=1)

    # --- start-up -------------------------------------------------------------------------------------

    def _start(self) -> list[LabelledFrame]:
        """Close the start-up window: measure the gates, decide the scene (sides with ``hands="auto"``) and
        label the window's frames. Without a hand, the window slides on (frames behind it stay unlabelled)."""
        begin = max(self.window_start, self.frames - self.startup_frames)
        window = self.positions[begin:self.frames]
        statistics = measure_take(window)
        settings = self.base_settings.adapted(statistics)
        try:
            scene = _scene(window, self.hands, self.layout, self.objects, settings, self.models)
        except InputError as error:
            if self.hands != "auto" or "initialises a hand" not in str(error):
                raise
            self.startup_error = str(error)
            self._next_attempt = self.frames + STARTUP_RETRY
            self.window_start = max(0, self.frames - self.startup_frames + STARTUP_RETRY)
            return []
        if scene.decision is not None and begin:
            scene.decision = replace(scene.decision, frame=scene.decision.frame + begin)
        self.statistics, self.scene, self.startup_error = statistics, scene, ""
        self.labelled = begin
        run = _main_run(scene, self.positions, True, None, None)
        self.run = run
        self._pending_calibration = set(range(len(scene.sides))) if scene.settings.calibrate else set()
        return [self._track(frame) for frame in range(begin, self.frames)]

    # --- per frame ------------------------------------------------------------------------------------

    def _track(self, frame: int) -> LabelledFrame:
        run = self.run
        assert run is not None and self.scene is not None
        run.track_frame(frame)
        self.labelled = frame + 1
        self._calibration_due(frame)
        states = {track.name: run.states[number][frame] for number, track in enumerate(run.tracks)}
        return LabelledFrame(frame, run.assignment[frame].copy(), run.residuals[frame].copy(),
                             run.confidence[frame].copy(), states)

    def _calibration_due(self, frame: int) -> None:
        """Once a hand has been tracked for ``calibration_frames`` frames, calibrate it on those frames (the
        online mode's step, :func:`core.labelling.scene._online_calibration_hook`): at once, or on a thread."""
        run, scene = self.run, self.scene
        assert run is not None and scene is not None
        for number in list(self._pending_calibration):
            init = run.init_frames[number]
            if init < 0 or frame < init + scene.settings.calibration_frames - 1:
                continue
            self._pending_calibration.discard(number)
            window = _window_copy(run, frame + 1)
            side = scene.sides[number]
            model, markers = scene.hand_models[side], scene.marker_sets[side]
            if not self.background_calibration:
                calibrated = _calibrate([(window, frame + 1)], number, model, markers)
                if calibrated is not None:
                    self._calibrated[number] = calibrated
                    self._apply_calibrations()
                continue

            def work(number: int = number, window: _Run = window, stop: int = frame + 1, model: HandModel = model,
                     markers: MarkerSet = markers) -> None:
                calibrated = _calibrate([(window, stop)], number, model, markers)
                if calibrated is not None:
                    with self._lock:
                        self._calibrated[number] = calibrated

            thread = threading.Thread(target=work, name=f"live-calibration-{side}", daemon=True)
            self._calibrations[number] = thread
            thread.start()

    def _apply_calibrations(self) -> None:
        if not self._calibrated:
            return
        run, scene = self.run, self.scene
        assert run is not None and scene is not None
        with self._lock:
            ready, self._calibrated = self._calibrated, {}
        for number, (model, markers, report) in ready.items():
            side = scene.sides[number]
            scene.hand_models[side], scene.marker_sets[side], scene.calibrations[side] = model, markers, report
            track = run.tracks[number]
            assert isinstance(track, HandTracker)
            track.set_model(model, markers)

    # --- the end --------------------------------------------------------------------------------------

    def wait_calibrations(self, timeout: float = 30.0) -> None:
        """Wait for the subject calibrations still running (at the end of a capture)."""
        for thread in self._calibrations.values():
            thread.join(timeout)

    def finish(self, frame_rate: float | None = None) -> SceneLabelling:
        """The labelling of every frame pushed (module docstring), with the online mode's causal completion.
        Raises InputError when no frame was pushed or the scene never started (no hand found)."""
        if self.frames == 0:
            raise InputError("no frame was received; nothing to label")
        if self.run is None or self.scene is None:
            raise InputError(self.startup_error or f"only {self.frames} frames were received: fewer than the "
                             f"{self.startup_frames} the labeller needs to start")
        self.wait_calibrations()
        run = copy.copy(self.run)
        run.truncate(self.frames)
        columns = self.columns_used()
        run.positions, run.present = run.positions[:, :columns], run.present[:, :columns]
        run.states = [state.copy() for state in run.states]
        run.assignment, run.confidence, run.residuals = (run.assignment.copy(), run.confidence.copy(),
                                                         run.residuals.copy())
        _link_and_rescue(run, self.scene, online=True)
        positions = run.positions
        result = _result(run, self.scene, positions, True)
        statistics = self.statistics
        result.noise_mm = statistics.noise_mm if statistics is not None and statistics.measured else None
        result.side_decision = self.scene.decision
        result.health = assess_labelling(result, frame_rate or 100.0)
        if self.scene.template is not None:
            result.health += check_whole_take(result, self.scene.template, result.noise_mm)
        return result

    def columns_used(self) -> int:
        """Point slots used by the frames pushed: one past the last slot any frame filled."""
        filled = np.isfinite(self.positions[:self.frames]).all(axis=2).any(axis=0)
        return int(filled.nonzero()[0].max() + 1) if filled.any() else 0

    def take(self, frame_rate: float, names: list[str] | None = None) -> Take:
        """The frames pushed as a raw take: one column per point slot in the order pushed (``*0``, ``*1``…),
        the points unchanged, NaN where a frame had fewer."""
        columns = self.columns_used()
        positions = self.positions[:self.frames, :columns].copy()
        return Take(marker_names=names or [f"*{index}" for index in range(columns)], marker_positions=positions,
                    frame_rate=frame_rate)


def _window_copy(run: _Run, stop: int) -> _Run:
    """A copy of ``run``'s first ``stop`` frames (what a subject calibration on another thread reads)."""
    window = copy.copy(run)
    window.positions = run.positions[:stop].copy()
    window.present = run.present[:stop].copy()
    window.assignment = run.assignment[:stop].copy()
    window.confidence = run.confidence[:stop].copy()
    window.residuals = run.residuals[:stop].copy()
    window.states = [state[:stop].copy() for state in run.states]
    window.init_frames = list(run.init_frames)
    return window


__all__ = ["LabelledFrame", "N_PARAMS", "OnlineLabeller"]
