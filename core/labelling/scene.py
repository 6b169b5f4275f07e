"""Automatic labelling of a whole scene: one or two hands and rigid objects (Maycock et al. 2015 §III,
the journal's "Fully automatic tracking", Zhao et al. 2012 eq. 2 for the subject calibration).

Pipeline of :func:`label_scene`:

1. Initialisation (:mod:`core.labelling.initialise`): from the first frame on, cluster the points and
   fit every model not found yet to every cluster (PCA + sign combinations, OBB scale, rigid ICP,
   Hungarian + IK/Kabsch); keep the fits of least ``E + αD`` (eq. 2). A model not found in a frame
   is looked for again every ``retry_every`` frames on the points no model took, so a take whose
   first frames show no hand starts where the hand appears.
2. Subject calibration of every hand (``settings.calibrate``): the hand is tracked with the
   template over up to ``calibration_frames`` frames, :func:`core.calibration.subject.calibrate_subject`
   fits bone lengths and marker offsets to those labelled frames (Levenberg–Marquardt), and the
   take is tracked again with the calibrated hands (online mode: the calibrated hand replaces the
   template from the end of the calibration window on, causally).
3. Tracking, per frame: predict every model by constant velocity; ONE Hungarian assignment of all
   models' predicted markers to all points with a "missing" option (gate: ``gate_mm``, for a marker
   missing in the previous frame ``reappear_gate_mm``); IK per hand, Kabsch per object; assignments
   whose residual exceeds the model's adaptive threshold are dropped (ghost rejection) and the model
   solved again; a second joint assignment against the solved markers with the threshold as gate
   catches markers the prediction missed. A marker whose new point breaks the continuity of its own
   trajectory (farther than ``continuity_mm`` from the extrapolation of its last two points) is
   missing in that frame; a marker missing in the previous frame is accepted only if the IK that
   includes it reaches it below the strict reappearance threshold. A rigid object left with fewer
   than 3 labelled markers, or with a labelled marker its fit misses by more than ``reacquire_fit_mm``,
   is re-acquired from the points no other model took near its pose: every correspondence of its
   markers whose distance matrix agrees (:func:`core.labelling.initialise.rigid_correspondences`) is
   fitted rigidly and the one of most markers and least residual replaces the frame's labels when it
   is unambiguous and better on eq. 2 (causal: the current frame only). Points no marker took are ghosts.
4. Offline mode (default): the first ``verify_frames`` frames after each hand's initialisation are
   tracked again backwards and the better labelling per frame (eq. 2) is kept (a wrong initial fit is
   corrected); a backward pass from each model's first initialisation (or the first appearance of its
   last marker) down to frame 0 labels the frames before it; labelled trajectories are extended into
   continuing free points (:mod:`core.labelling.fragments`; forward only in online mode); long
   trajectories of free points are given to the one hand marker the IK brings onto them
   (:meth:`_Run.rescue`). Online mode is causal only: trajectories are extended forward, and a free
   trajectory is given to a marker from its ``fragment_min_frames``-th frame on, on the evidence of
   those frames alone.

Measured coordinates are never changed: :meth:`SceneLabelling.labelled_positions` returns the input
points rearranged per marker.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import numpy as np
from numba import njit

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.io import Take
from handmocap.core.labelling.fragments import extend_trajectories, free_fragments
from handmocap.core.labelling.health import assess_labelling
from handmocap.core.labelling.hypotheses import check_whole_take
from handmocap.core.labelling.initialise import (
    LINK_MARGIN,
    Candidate,
    cluster_cut,
    gated_assignment,
    initialise_frame,
    pair_distances,
    reacquire_object,
)
from handmocap.core.labelling.models import HandTracker, RigidTrack, SceneSettings, Track
from handmocap.core.labelling.result import SceneLabelling, SceneModel
from handmocap.core.labelling.sides import SideDecision, decide_sides
from handmocap.core.labelling.swaps import neighbour_pairs, point_tracklets, repair_swaps, unify_tracklets
from handmocap.core.labelling.take_statistics import measure_take
from handmocap.core.model import (
    N_PARAMS,
    HandModel,
    MarkerLayout,
    MarkerSet,
    load_layout,
    load_template,
    resolve_layout,
)
from handmocap.core.model.lab_template import LabTemplate, load_lab_template
from handmocap.core.model.objects import ObjectSpec, check_unique_names, load_scene_spec

HANDS = ("auto", "right", "left", "both")
HAND_PREFIX = {"right": "R_", "left": "L_"}


DEGRADED_RATIO = 2.0
"""A hand whose frame's mean residual exceeds this times its running typical residual is degraded."""
SWAP_ROUNDS = 3
"""Swap tests are repeated (up to this many rounds) while they find swaps."""
RECHECK_RATIO = 2.5
"""Offline re-check: a marker whose mean residual over a window exceeds this times its median is suspect."""
TYPICAL_RATE = 0.02
"""Rate of the running typical residual (an exponential mean over about 50 frames)."""
MAX_RECHECK_BACKOFF = 16
"""A hand that stays degraded is fitted afresh ever less often: after each such fit the wait doubles, up to this
many times ``hypothesis_frames``, until the hand has fitted as usual for ``hypothesis_frames`` frames in a row."""


class _Run:
    """Forward/backward tracking of a set of tracks over a take's points; fills the result arrays."""

    def __init__(self, tracks: list[Track], positions: np.ndarray, settings: SceneSettings,
                 make_track: Callable[[int], Track] | None = None):
        self.tracks, self.positions, self.settings = tracks, positions, settings
        #: a fresh copy of track ``number``; when given, an initial fit with runner-up hypotheses is
        #: decided by tracking each over ``settings.hypothesis_frames`` frames (:meth:`_window_cost`)
        self.make_track = make_track
        frames = len(positions)
        self.offsets = np.cumsum([0] + [track.count for track in tracks])
        marker_count = int(self.offsets[-1])
        self.present = np.isfinite(positions).all(axis=2)
        self.assignment = np.full((frames, marker_count), -1, dtype=np.int64)
        self.confidence = np.full((frames, marker_count), np.nan)
        self.residuals = np.full((frames, marker_count), np.nan)
        self.states = [np.full((frames, N_PARAMS), np.nan) if isinstance(track, HandTracker)
                       else np.full((frames, 4, 4), np.nan) for track in tracks]
        self.init_frames = [-1] * len(tracks)
        self.cut = cluster_cut(tracks, settings)
        #: frame -> [(track index, known labels (K,) point columns, starting state)]: tracks to start
        #: there with the labels found by an earlier pass (the calibration pre-pass)
        self.scheduled: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        #: (F,P) linked point trajectories (:func:`core.labelling.swaps.point_tracklets`), made when needed
        self.tracklets: np.ndarray | None = None
        #: per hand track: consecutive frames it has been lost; frames where it was fitted afresh
        self.lost: dict[int, int] = {}
        self.reinitialised: dict[int, list[int]] = {}
        #: per hand track: running typical mean residual (mm) and the last frame it was re-checked
        self.typical_residual: dict[int, float] = {}
        self.last_recheck: dict[int, int] = {}
        #: per hand track: frames to wait (in ``hypothesis_frames``) before a degraded hand is fitted afresh again,
        #: and the frames in a row it has not been degraded
        self.recheck_backoff: dict[int, int] = {}
        self.fitting: dict[int, int] = {}
        #: the frame of the last initialisation attempt for the models not found yet
        self.last_attempt = -10 ** 9

    def columns(self, index: int) -> slice:
        return slice(int(self.offsets[index]), int(self.offsets[index + 1]))

    def free_columns(self, frame: int, track_index: int) -> np.ndarray:
        """The point columns of ``frame`` present and not taken by a model other than ``track_index``."""
        others = np.ones(self.assignment.shape[1], dtype=bool)
        others[self.columns(track_index)] = False
        foreign = self.assignment[frame, others]
        columns = np.flatnonzero(self.present[frame])
        return columns[~np.isin(columns, foreign[foreign >= 0])]

    def step(self, tracks: Sequence[Track], points: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
        """Track one frame of ``points (N,3)`` with ``tracks`` (all active). Returns, over the tracks'
        markers in order, the point index (K,) (-1 missing), the confidence (K,) mm and the residuals
        (K,) mm, and the state per track."""
        settings = self.settings
        starts = [track.predict() for track in tracks]
        predicted = np.concatenate([track.effectors(start) for track, start in zip(tracks, starts, strict=True)])
        seen = np.concatenate([track.seen for track in tracks])
        first = gated_assignment(predicted, points, np.where(seen, settings.gate_mm, settings.reappear_gate_mm))
        bounds = np.cumsum([0] + [track.count for track in tracks])
        taken_points = np.where((first >= 0)[:, None], points[np.maximum(first, 0)], np.nan)
        for number, track in enumerate(tracks):
            part = slice(bounds[number], bounds[number + 1])
            if track.seen.any():
                jumped = track.jumped(taken_points[part]) & track.seen
                if jumped.any():      # a continuing marker does not jump: missing in this frame
                    track.seen = track.seen & ~jumped
                    first[part][jumped] = -1
        thresholds = np.concatenate([track.thresholds() for track in tracks])
        chosen = first.copy()
        residuals_all = np.empty(len(first))
        effectors_all = np.empty((len(first), 3))
        states: list[np.ndarray] = []
        for number, track in enumerate(tracks):
            part = slice(bounds[number], bounds[number + 1])
            index = chosen[part]
            state, effectors, residuals = self._solve(track, points, index, starts[number])
            bad = residuals > thresholds[part]
            if bad.any():
                index[bad] = -1
                state, effectors, residuals = self._solve(track, points, index, state)
            states.append(state)
            effectors_all[part], residuals_all[part] = effectors, residuals
        distances = pair_distances(effectors_all, points)
        second = gated_assignment(effectors_all, points, thresholds, distances)
        if np.array_equal(second, chosen):
            second = chosen
        changed_tracks = []
        if second is not chosen:
            for number, track in enumerate(tracks):
                part = slice(bounds[number], bounds[number + 1])
                changed = second[part] != chosen[part]
                if not changed.any():
                    continue
                changed_tracks.append(number)
                index = second[part].copy()
                state, effectors, residuals = self._solve(track, points, index, states[number])
                unreached = (residuals > thresholds[part]) & (changed | ~track.seen)
                if unreached.any():
                    index[unreached] = -1
                    state, effectors, residuals = self._solve(track, points, index, state)
                chosen[part], states[number] = index, state
                effectors_all[part], residuals_all[part] = effectors, residuals
        restarted = []
        for number, track in enumerate(tracks):
            if isinstance(track, RigidTrack):
                part = slice(bounds[number], bounds[number + 1])
                found = self._reacquire(track, points, chosen, part, states[number], residuals_all[part])
                if found is not None:
                    index, state, effectors, residuals = found
                    if np.abs(effectors - effectors_all[part]).max() > settings.continuity_mm:
                        restarted.append(number)
                    chosen[part], states[number] = index, state
                    effectors_all[part], residuals_all[part] = effectors, residuals
                    changed_tracks.append(number)
        if changed_tracks:
            distances = pair_distances(effectors_all, points)
        confidence = _margins(distances, chosen, thresholds)
        observed = chosen >= 0
        taken_points = np.where(observed[:, None], points[np.maximum(chosen, 0)], np.nan)
        for number, track in enumerate(tracks):
            part = slice(bounds[number], bounds[number + 1])
            track.commit(states[number], residuals_all[part], observed[part], taken_points[part])
            if isinstance(track, RigidTrack) and number in restarted:
                track.restart(states[number], observed[part], taken_points[part])
        return chosen, confidence, residuals_all, states

    def _reacquire(self, track: RigidTrack, points: np.ndarray, chosen: np.ndarray, part: slice, state: np.ndarray,
                   residuals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """Re-acquisition of a rigid object that has fewer than 3 labelled markers in this frame, or a
        labelled marker its fit misses by more than ``reacquire_fit_mm`` (lost, or a self-consistent
        wrong correspondence): the best rigid correspondence among the points no other model took
        (:func:`reacquire_object`) replaces the frame's labels when it scores better on eq. 2 (RMS
        residual + α · unlabelled markers). Returns (point index (K,), pose, effectors, residuals) or None."""
        settings = self.settings
        own = chosen[part]
        observed = own >= 0
        matched = int(observed.sum())
        if track.count < 3 or (matched >= 3 and residuals[observed].max() <= settings.reacquire_fit_mm):
            return None
        others = np.ones(len(chosen), dtype=bool)
        others[part] = False
        free = np.ones(len(points), dtype=bool)
        taken = chosen[others]
        free[taken[taken >= 0]] = False
        columns = np.flatnonzero(free)
        if len(columns) < 3:
            return None
        found = reacquire_object(track, points[columns], state, settings)
        if found is None:
            return None
        index, pose, new_residuals = found
        index = np.where(index >= 0, columns[np.maximum(index, 0)], -1)
        if np.array_equal(index, own):
            return None
        alpha = settings.alpha

        def cost(labels: np.ndarray, values: np.ndarray) -> float:
            seen = labels >= 0
            rms = float(np.sqrt((values[seen] ** 2).mean())) if seen.any() else 0.0
            return rms + alpha * float((~seen).sum())

        if cost(index, new_residuals) >= cost(own, residuals):
            return None
        return index, pose, track.effectors(pose), new_residuals

    @staticmethod
    def _solve(track: Track, points: np.ndarray, index: np.ndarray, start: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        observed = index >= 0
        targets = np.where(observed[:, None], points[np.maximum(index, 0)], np.nan)
        state, effectors = track.solve(targets, observed, start)
        residuals = np.sqrt(((effectors - targets) ** 2).sum(axis=1))
        return state, effectors, residuals

    def record(self, frame: int, track_indices: list[int], columns: np.ndarray, index: np.ndarray,
               confidence: np.ndarray, residuals: np.ndarray, states: list[np.ndarray]) -> None:
        """Store one frame's result of the tracks ``track_indices`` (their markers concatenated)."""
        cells = slice(None) if len(track_indices) == len(self.tracks) else np.concatenate(
            [np.arange(self.offsets[number], self.offsets[number + 1]) for number in track_indices])
        observed = index >= 0
        self.assignment[frame, cells] = np.where(observed, columns[np.maximum(index, 0)], -1)
        self.confidence[frame, cells] = confidence
        self.residuals[frame, cells] = np.where(observed, residuals, np.nan)
        for number, state in zip(track_indices, states, strict=True):
            self.states[number][frame] = state

    def forward(self, start: int, stop: int, report: Callable[[int], None],
                on_frame: Callable[[int], None] | None = None) -> None:
        """Track frames ``start..stop-1``, initialising models as they are found."""
        self.last_attempt = -10 ** 9
        for frame in range(start, stop):
            report(frame)
            self.track_frame(frame)
            if on_frame is not None:
                on_frame(frame)

    def track_frame(self, frame: int) -> None:
        """Track one frame causally (a step of :meth:`forward`, also driven frame by frame by the live
        labeller, :mod:`core.labelling.online`): the active models, the tracks scheduled to start there, an
        initialisation attempt for the models not found yet (every ``retry_every`` frames while others are
        tracked) and a fresh fit of the hands lost for ``retry_every`` frames."""
        settings = self.settings
        columns = np.flatnonzero(self.present[frame])
        points = self.positions[frame, columns]
        active = [number for number, track in enumerate(self.tracks) if track.active]
        taken = np.zeros(len(columns), dtype=bool)
        if active:
            index, confidence, residuals, states = self.step([self.tracks[number] for number in active], points)
            self.record(frame, active, columns, index, confidence, residuals, states)
            taken[index[index >= 0]] = True
            self._count_lost(frame, active)
        for number, labels, state in self.scheduled.pop(frame, []):
            taken |= self._start_with(frame, number, columns, labels, state, taken)
        waiting = [number for number, track in enumerate(self.tracks)
                   if not track.active and not any(number == entry[0] for entries in self.scheduled.values()
                                                  for entry in entries)]
        if waiting and (not active or frame - self.last_attempt >= settings.retry_every):
            self.last_attempt = frame
            free = np.flatnonzero(~taken)
            if len(free) >= 3:
                for candidate in initialise_frame(self.tracks, waiting, points[free], settings, self.cut):
                    self._start(frame, candidate, columns[free], points[free])
        for number in [number for number, count in self.lost.items() if count >= settings.retry_every]:
            self._reinitialise(frame, number)

    def _count_lost(self, frame: int, active: list[int]) -> None:
        """Count, per active hand, the consecutive frames up to ``frame`` in which it labelled fewer than
        ``init_min_share`` of its markers (a hand the tracker has lost, e.g. after a long occlusion) or
        fitted with a mean residual above :data:`DEGRADED_RATIO` × its running typical residual (a
        finger shift or a swap the tracker settled into); a degraded hand is counted at most once per
        ``hypothesis_frames`` frames, as re-checking it costs a fresh fit (and ever less often while it stays
        degraded, :data:`MAX_RECHECK_BACKOFF`)."""
        settings = self.settings
        for number in active:
            track = self.tracks[number]
            if not isinstance(track, HandTracker):
                continue
            labels = self.assignment[frame, self.columns(number)] >= 0
            least = max(3, int(np.ceil(settings.init_min_share * track.count)))
            lost = int(labels.sum()) < least
            residual = float(self.residuals[frame, self.columns(number)][labels].mean()) if labels.any() else np.nan
            typical = self.typical_residual.get(number, residual)
            degraded = bool(np.isfinite(residual) and residual > max(DEGRADED_RATIO * typical,
                                                                    settings.reappear_floor_mm))
            if np.isfinite(residual) and not degraded:
                self.typical_residual[number] = typical + TYPICAL_RATE * (residual - typical)
            self.fitting[number] = self.fitting.get(number, 0) + 1 if not degraded else 0
            if self.fitting[number] >= settings.hypothesis_frames:
                self.recheck_backoff[number] = 1
            wait = settings.hypothesis_frames * self.recheck_backoff.get(number, 1)
            recently = frame - self.last_recheck.get(number, -10 ** 9) < wait
            count = lost or (degraded and not recently)
            self.lost[number] = self.lost.get(number, 0) + 1 if count else 0

    def _reinitialise(self, frame: int, number: int) -> None:
        """Fit a lost or degraded hand ``number`` afresh in ``frame`` (:meth:`_refit`) and continue tracking
        from that fit. Tried every ``retry_every`` frames while lost, once per ``hypothesis_frames`` while
        degraded, and after each fit of a degraded hand twice as long until the hand fits as usual again (up to
        :data:`MAX_RECHECK_BACKOFF` times: a fit that did not help is not repeated every ``hypothesis_frames``
        to the end of the take)."""
        self.lost[number] = 0
        self.last_recheck[number] = frame
        labelled = int((self.assignment[frame, self.columns(number)] >= 0).sum())
        lost = labelled < max(3, int(np.ceil(self.settings.init_min_share * self.tracks[number].count)))
        self.recheck_backoff[number] = 1 if lost else min(2 * self.recheck_backoff.get(number, 1),
                                                          MAX_RECHECK_BACKOFF)
        refit = self._refit(frame, number)
        if refit is not None:
            labels, state = refit
            columns = np.flatnonzero(self.present[frame])
            taken = ~np.isin(columns, self.free_columns(frame, number))
            state, observed, residuals = self._record_start(frame, number, self.tracks[number], columns, labels,
                                                            state, taken)
            self.tracks[number].start(state, observed)
            self.tracks[number].remember(residuals[observed])
            self.reinitialised.setdefault(number, []).append(frame)

    def _refit(self, frame: int, number: int) -> tuple[np.ndarray, np.ndarray] | None:
        """A fresh fit of hand ``number`` (:func:`initialise_frame`) to the points of ``frame`` no other model
        took, when it beats the labelling the hand has there: offline, when one of its hypotheses holds up
        better over the next ``hypothesis_frames`` frames (:func:`window_cost`); online (no look-ahead), when
        it labels more markers. Returns (point column per marker (K,), θ) or None."""
        free = self.free_columns(frame, number)
        state = self.states[number][frame]
        if len(free) < 3 or not np.isfinite(state).all():
            return None
        found = initialise_frame(self.tracks, [number], self.positions[frame, free], self.settings, self.cut)
        if not found:
            return None
        candidate = found[0]
        current = self.assignment[frame, self.columns(number)]
        if self.make_track is None:
            if candidate.matched <= int((current >= 0).sum()):
                return None
            return _columns_of(candidate.point_index, free), candidate.state
        kept = self._window_cost(frame, number, current, state)
        hypotheses = [(_columns_of(labels, free), start) for start, labels in
                      [(candidate.state, candidate.point_index), *candidate.alternatives]]
        costs = self._window_costs(frame, number, hypotheses, kept)
        return hypotheses[int(np.argmin(costs))] if min(costs) < kept else None

    def _start_with(self, frame: int, number: int, columns: np.ndarray, labels: np.ndarray, state: np.ndarray,
                    taken: np.ndarray) -> np.ndarray:
        """Start track ``number`` in ``frame`` with known labels (point column per marker, -1 none) and
        a starting state; returns the frame's points (mask over ``columns``) it took."""
        track = self.tracks[number]
        state, observed, residuals = self._record_start(frame, number, track, columns, labels, state, taken)
        track.start(state, observed)
        track.remember(residuals[observed])
        self.init_frames[number] = frame
        return np.isin(columns, self.assignment[frame, self.columns(number)])

    def _record_start(self, frame: int, number: int, track: Track, columns: np.ndarray, labels: np.ndarray,
                      state: np.ndarray, taken: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve ``track`` in ``frame`` from ``state`` with ``labels`` (point column per marker, -1 none; a
        column not among the frame's sorted ``columns`` or ``taken`` (mask over them) is dropped) and record
        it as track ``number``'s labelling there. Returns the state, the observed markers (K,) and their
        residuals (K,) mm."""
        found = np.searchsorted(columns, labels)
        inside = (labels >= 0) & (found < len(columns))
        index = np.where(inside & (columns[np.minimum(found, len(columns) - 1)] == labels), found, -1)
        if taken is not None:
            index[(index >= 0) & taken[np.maximum(index, 0)]] = -1
        points = self.positions[frame, columns]
        for _ in range(3):
            state, effectors, residuals = self._solve(track, points, index, state)
        self.record(frame, [number], columns, index, _margins(pair_distances(effectors, points), index,
                                                              track.thresholds()), residuals, [state])
        return state, index >= 0, residuals

    def _start(self, frame: int, candidate: Candidate, columns: np.ndarray, points: np.ndarray) -> None:
        track = self.tracks[candidate.track_index]
        index, state = candidate.point_index, candidate.state
        if candidate.alternatives and self.make_track is not None:
            hypotheses = [(candidate.state, candidate.point_index), *candidate.alternatives]
            costs = self._window_costs(frame, candidate.track_index,
                                       [(_columns_of(labels, columns), start) for start, labels in hypotheses])
            state, index = hypotheses[int(np.argmin(costs))]
        state, effectors, residuals = self._solve(track, points, index, state)
        observed = index >= 0
        track.start(state, observed)
        track.remember(residuals[observed])
        self.init_frames[candidate.track_index] = frame
        confidence = _margins(pair_distances(effectors, points), index, track.thresholds())
        self.record(frame, [candidate.track_index], columns, index, confidence, residuals, [state])

    def _window_cost(self, frame: int, number: int, labels: np.ndarray, state: np.ndarray,
                     bound: float = np.inf) -> float:
        assert self.make_track is not None
        return window_cost(self.make_track(number), self.positions, frame, labels, state, self.settings, bound)

    def _window_costs(self, frame: int, number: int, hypotheses: list[tuple[np.ndarray, np.ndarray]],
                      bound: float = np.inf) -> list[float]:
        """:func:`window_cost` of each (labels, state) hypothesis of model ``number`` in ``frame``. Only the
        lowest cost, and whether it is below ``bound``, is ever used: a hypothesis is tracked only until it
        cannot be below ``bound`` or the lowest so far (its value is then a lower bound above them)."""
        costs: list[float] = []
        for labels, state in hypotheses:
            costs.append(self._window_cost(frame, number, labels, state, min([bound, *costs])))
        return costs

    def start_at(self, frame: int, track_index: int, state: np.ndarray) -> None:
        """Start a track from a given state (e.g. a known first posture) and label ``frame``."""
        track = self.tracks[track_index]
        track.start(state)
        columns = np.flatnonzero(self.present[frame])
        index, confidence, residuals, states = self.step([track], self.positions[frame, columns])
        self.record(frame, [track_index], columns, index, confidence, residuals, states)
        self.init_frames[track_index] = frame

    def backward(self, track_index: int, make_track: Callable[[], Track]) -> None:
        """Label the frames before the track's first initialisation (and before the first appearance of
        each of its markers) by tracking backwards from there; only samples the forward pass left
        empty, with points no other marker took, are added."""
        init = self.init_frames[track_index]
        if init < 0:
            return
        part = self.columns(track_index)
        labelled = self.assignment[:, part] >= 0
        first_seen = np.where(labelled.any(axis=0), labelled.argmax(axis=0), init)
        begin = int(max(init, first_seen.max()))
        if begin <= 0:
            return
        track = make_track()
        states = self.states[track_index]
        seeds = [states[frame] for frame in (begin + 1, begin) if frame < len(states)
                 and np.isfinite(states[frame]).all()]
        if not seeds:
            return
        track.start(seeds[0], labelled[begin] if len(seeds) == 1 else labelled[begin + 1])
        if len(seeds) == 2:
            track.commit(seeds[1], np.nan_to_num(self.residuals[begin, part]), labelled[begin])
        for frame in range(begin - 1, -1, -1):
            free = self.free_columns(frame, track_index)
            own = self.assignment[frame, part]
            index, confidence, residuals, solved = self.step([track], self.positions[frame, free])
            taken = _columns_of(index, free)
            if frame < init:
                self.record(frame, [track_index], free, index, confidence, residuals, solved)
                continue
            add = (own < 0) & (taken >= 0) & (frame < first_seen) & ~np.isin(taken, own)
            if add.any():
                cells = np.arange(part.start, part.stop)[add]
                self.assignment[frame, cells] = taken[add]
                self.confidence[frame, cells] = confidence[add]
                self.residuals[frame, cells] = residuals[add]

    def link(self, track_index: int, track: Track, backward: bool) -> None:
        """Extend the track's labelled trajectories into continuing free points
        (:mod:`core.labelling.fragments`), then re-solve the frames that gained samples; a linked sample
        the model cannot reach below the ceiling threshold is dropped again."""
        part = self.columns(track_index)
        added = extend_trajectories(self.positions, self.assignment, np.arange(part.start, part.stop),
                                    self.settings.link_mm, backward)
        if not added:
            return
        states = self.states[track_index]
        margins = {(frame, marker): margin for frame, marker, _, margin in added}
        for frame in sorted({frame for frame, _, _, _ in added}):
            index = self.assignment[frame, part]
            new = [marker - part.start for marker in range(part.start, part.stop) if (frame, marker) in margins]
            if not np.isfinite(states[frame]).all():
                self.assignment[frame, part.start + np.array(new)] = -1
                continue
            state, _, residuals = self._solve(track, self.positions[frame], index, states[frame])
            refused = [k for k in new if residuals[k] > self.settings.threshold_ceiling_mm]
            if refused:
                index = index.copy()
                index[refused] = -1
                self.assignment[frame, part] = index
                state, _, residuals = self._solve(track, self.positions[frame], index, states[frame])
            states[frame] = state
            self.residuals[frame, part] = np.where(index >= 0, residuals, np.nan)
            for k in new:
                if k not in refused:
                    self.confidence[frame, part.start + k] = margins[(frame, part.start + k)]

    def rescue(self, track_index: int, track: HandTracker, causal: bool = False) -> None:
        """Give a long trajectory of free points (:func:`free_fragments`, at least
        ``fragment_min_frames``) to the hand marker missing all along it that the IK brings to it below
        the ceiling threshold in sampled frames of the fragment, when no other candidate marker comes
        within twice its distance (a fingertip or an abducted thumb the posture estimate had lost,
        seen far from where it was guessed). ``causal`` (online mode): the evidence is the fragment's
        first ``fragment_min_frames`` frames only, and the marker takes the fragment from the last of
        them on, so that no label depends on later frames."""
        for _round in range(3):    # a fragment given away can settle another (thumb tip after thumb middle)
            if not self._rescue_round(track_index, track, causal):
                break

    def _rescue_round(self, track_index: int, track: HandTracker, causal: bool) -> bool:
        settings = self.settings
        part = self.columns(track_index)
        states = self.states[track_index]
        fragments = free_fragments(self.positions, self.assignment, settings.link_mm, settings.fragment_min_frames)
        given = False
        for first, columns in fragments:
            frames = np.arange(first, first + len(columns))
            evidence = settings.fragment_min_frames if causal else len(frames)
            if not np.isfinite(states[frames[:evidence]]).all():
                continue
            missing = (self.assignment[frames[:evidence], part] < 0).all(axis=0)
            if not missing.any():
                continue
            picks = np.unique(np.linspace(0, evidence - 1, min(5, evidence)).round().astype(int))
            sample = frames[picks]
            sample_points = self.positions[sample, columns[picks]]
            estimates = np.stack([track.effectors(states[frame]) for frame in sample])
            distance = np.linalg.norm(estimates - sample_points[:, None], axis=2).mean(axis=0)
            candidates = np.flatnonzero(missing & (distance < settings.rescue_reach_mm))
            tried = []
            for marker in candidates[np.argsort(distance[candidates])][:4]:
                worst = 0.0
                for frame, pick in zip(sample, picks, strict=True):
                    index = self.assignment[frame, part].copy()
                    index[marker] = columns[pick]
                    state = states[frame]
                    for _ in range(3):
                        state, _, residuals = self._solve(track, self.positions[frame], index, state)
                    worst = max(worst, float(residuals[marker]))
                    if worst > settings.threshold_ceiling_mm:
                        break
                tried.append((worst, int(marker)))
            reached = sorted(entry for entry in tried if entry[0] <= settings.threshold_ceiling_mm)
            if not reached or (len(tried) > 1 and sorted(tried)[1][0] < 2.0 * reached[0][0]):
                continue
            marker = reached[0][1]
            start = evidence - 1 if causal else 0
            for frame, column in zip(frames[start:], columns[start:], strict=True):
                index = self.assignment[frame, part].copy()
                if index[marker] >= 0 or not np.isfinite(states[frame]).all():   # found again; hand lost
                    continue
                index[marker] = column
                state = states[frame]
                for _ in range(3):
                    state, _, residuals = self._solve(track, self.positions[frame], index, state)
                if residuals[marker] > settings.threshold_ceiling_mm:
                    continue
                self.assignment[frame, part] = index
                states[frame] = state
                self.residuals[frame, part] = np.where(index >= 0, residuals, np.nan)
                self.confidence[frame, part.start + marker] = 0.0
                given = True
        return given

    def repair_swaps(self, track_index: int, track: HandTracker, every_fragment: bool = False
                     ) -> list[tuple[int, int, int, int]]:
        """Offline: neighbouring markers of the hand labelled the wrong way round over a fragment are
        exchanged when the IK fits clearly better so (:mod:`core.labelling.swaps`; ``every_fragment``: not
        only the fragments of suspect residual), and a point trajectory labelled with two markers is
        given to the one it mostly carries; the frames changed are solved again. Returns the swaps as
        (marker a, marker b, start, stop) within the hand."""
        part = self.columns(track_index)
        states = self.states[track_index]
        assignment = self.assignment[:, part]

        known: dict[tuple[int, bytes], float] = {}    # the states stay as they are until the end: one solve each

        def energy(frame: int, index: np.ndarray) -> float:
            key = (frame, index.tobytes())
            if key not in known:
                state = states[frame]
                if not np.isfinite(state).all():
                    known[key] = np.inf
                else:
                    _, _, residuals = self._solve(track, self.positions[frame], index, state)
                    known[key] = float((residuals[index >= 0] ** 2).sum())
            return known[key]

        if self.tracklets is None:
            self.tracklets = point_tracklets(self.positions)
        pairs = neighbour_pairs(track.effectors(track.mean_theta))
        before = assignment.copy()
        swaps: list[tuple[int, int, int, int]] = []
        for _round in range(SWAP_ROUNDS):      # an exchange can complete another (three fingers rotated)
            found = repair_swaps(assignment, self.residuals[:, part], self.tracklets, pairs, energy,
                                 self.settings.reappear_floor_mm, every_fragment)
            swaps += found
            if not found:
                break
        unify_tracklets(assignment, self.tracklets, energy)
        for frame in np.flatnonzero((assignment != before).any(axis=1)):
            if not np.isfinite(states[frame]).all():
                continue
            index = assignment[frame]
            state, _, residuals = self._solve(track, self.positions[frame], index, states[frame])
            states[frame] = state
            self.residuals[frame, part] = np.where(index >= 0, residuals, np.nan)
        self.assignment[:, part] = assignment
        return swaps

    def truncate(self, stop: int) -> None:
        """Keep only the frames before ``stop`` (the calibration window of the pre-pass)."""
        self.positions, self.present = self.positions[:stop], self.present[:stop]
        self.assignment, self.confidence = self.assignment[:stop], self.confidence[:stop]
        self.residuals = self.residuals[:stop]
        self.states = [states[:stop] for states in self.states]
        self.tracklets = None

    def verify_start(self, track_index: int, track: Track) -> None:
        """Offline: track the first ``verify_frames`` frames after the initialisation again, backwards
        from their end (where tracking has settled), keeping per frame the better labelling
        (:meth:`retrack`): an initial fit that took a neighbouring finger's points is corrected from the
        later, settled posture."""
        init = self.init_frames[track_index]
        if init >= 0:
            self.retrack(track_index, track, min(init + self.settings.verify_frames, len(self.positions) - 2), init)

    def retrack(self, track_index: int, track: Track, end: int, stop: int, direction: int = -1,
                converge: int | None = None, still: bool = False) -> None:
        """Offline: track the frames from ``end + direction`` to ``stop`` (inclusive) again, in
        ``direction`` (-1 backwards, +1 forwards), from the states of ``end`` and the frame before it in
        that direction (``still``: from ``end`` alone, with no velocity), and keep per frame whichever
        labelling of the model has the lower eq. 2 cost (mean residual + α · markers left unlabelled);
        with ``converge``, stop once that many consecutive frames agree with the labels already there
        (the two labellings have met)."""
        states = self.states[track_index]
        before = end if still else end - direction
        if (stop - end) * direction < 1 or not 0 <= before < len(states) or not (
                np.isfinite(states[end]).all() and np.isfinite(states[before]).all()):
            return
        part = self.columns(track_index)
        labelled = self.assignment[:, part] >= 0
        track.start(states[before], labelled[before])
        track.commit(states[end], np.nan_to_num(self.residuals[end, part]), labelled[end])
        alpha = self.settings.alpha

        def cost(index: np.ndarray, residuals: np.ndarray) -> float:
            seen = index >= 0
            return float(residuals[seen].mean() if seen.any() else 0.0) + alpha * float((~seen).sum())

        agreeing = 0
        for frame in range(end + direction, stop + direction, direction):
            free = self.free_columns(frame, track_index)
            index, confidence, residuals, states_now = self.step([track], self.positions[frame, free])
            own = self.assignment[frame, part]
            if np.array_equal(_columns_of(index, free), own):
                agreeing += 1
                if converge is not None and agreeing >= converge:
                    return
                continue
            agreeing = 0
            if cost(index, residuals) < cost(own, np.nan_to_num(self.residuals[frame, part])):
                self.record(frame, [track_index], free, index, confidence, residuals, states_now)

    def recheck(self, track_index: int) -> None:
        """Offline: where a marker of the hand fits much worse than it does over the rest of the take (mean
        residual over a window of ``hypothesis_frames`` frames above :data:`RECHECK_RATIO` × its median, and
        above the noise floor: a finger shift or swap the tracker settled into), fit the hand afresh at the
        window's first frame; when that holds up better over the window (:func:`window_cost`), label from
        it forwards and backwards until the labellings agree again (:meth:`retrack`)."""
        settings = self.settings
        if self.make_track is None:
            return
        part = self.columns(track_index)
        residuals = np.where(self.assignment[:, part] >= 0, self.residuals[:, part], np.nan)
        finite = np.isfinite(residuals)
        if not finite.any():
            return
        counts = finite.sum(axis=0)
        medians = np.array([np.median(residuals[finite[:, k], k]) if counts[k] else np.inf
                            for k in range(residuals.shape[1])])
        size = settings.hypothesis_frames
        frames = len(self.positions)
        for start in range(max(self.init_frames[track_index], 0), frames - 1, size):
            block = residuals[start:start + size]
            seen = np.isfinite(block).sum(axis=0)
            means = np.where(seen >= size // 2, np.nansum(block, axis=0) / np.maximum(seen, 1), 0.0)
            if not (means > np.maximum(RECHECK_RATIO * medians, settings.reappear_floor_mm)).any():
                continue
            refit = self._refit(start, track_index)
            if refit is None:
                continue
            labels, state = refit
            before = self.assignment[:, part].copy()
            self._record_start(start, track_index, self.make_track(track_index), np.flatnonzero(self.present[start]),
                               labels, state)
            self.retrack(track_index, self.make_track(track_index), start, frames - 1, +1, converge=size, still=True)
            self.retrack(track_index, self.make_track(track_index), start, 0, -1, converge=size, still=True)
            if not np.array_equal(before, self.assignment[:, part]):      # the labels changed: the operator checks
                self.reinitialised.setdefault(track_index, []).append(start)

    def ghost_points(self) -> np.ndarray:
        ghosts = self.present.copy()
        frames, markers = np.nonzero(self.assignment >= 0)
        ghosts[frames, self.assignment[frames, markers]] = False
        return ghosts


def _columns_of(index: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Point index per marker (K,) into a frame's ``columns`` → point column per marker, -1 kept."""
    return np.where(index >= 0, columns[np.maximum(index, 0)], -1)


def window_cost(track: Track, positions: np.ndarray, frame: int, labels: np.ndarray, state: np.ndarray,
                settings: SceneSettings, bound: float = np.inf) -> float:
    """Mean eq. 2 cost per frame (mean residual mm + α · markers unlabelled) of ``track`` (fresh) started
    in ``frame`` of ``positions (F,P,3)`` with ``labels (K,)`` (point columns, -1 none) and ``state``,
    tracked alone over the next ``settings.hypothesis_frames`` frames: how well a hypothesis holds up.
    The tracking stops once the cost is sure to exceed ``bound`` (no frame's cost is negative); the value
    returned then is the part tracked so far, itself above ``bound``."""
    stop = min(frame + settings.hypothesis_frames, len(positions))
    frames = stop - frame
    trial = _Run([track], positions[frame:stop], settings)
    trial.scheduled[0] = [(0, labels, state)]
    limit = bound * frames
    partial = 0.0

    def frame_cost(rows: slice) -> np.ndarray:
        labelled = trial.assignment[rows] >= 0
        residuals = np.where(labelled, trial.residuals[rows], 0.0).sum(axis=1) / np.maximum(labelled.sum(axis=1), 1)
        return residuals + settings.alpha * (~labelled).sum(axis=1)

    def check(tracked: int) -> None:
        nonlocal partial
        partial += float(frame_cost(slice(tracked, tracked + 1))[0])
        if partial > limit:
            raise _WindowDone

    try:
        trial.forward(0, frames, lambda _frame: None, check if np.isfinite(limit) else None)
    except _WindowDone:
        return partial / frames
    return float(frame_cost(slice(None)).mean())


@njit(cache=True)
def _margins(distances: np.ndarray, index: np.ndarray, gate: np.ndarray) -> np.ndarray:
    """Confidence (K,) mm from the marker-point ``distances (K,N)``: margin between the best and the
    second-best option (a point, or missing at the marker's ``gate (K,)``) of each marker, 0 when
    the marker did not take its best option."""
    rows, columns = distances.shape
    margins = np.zeros(rows)
    for i in range(rows):
        best, second, best_option = gate[i], np.inf, columns       # option ``columns`` = missing
        for j in range(columns):
            value = distances[i, j]
            if value < best:
                second, best, best_option = best, value, j
            elif value < second:
                second = value
        chosen = index[i] if index[i] >= 0 else columns
        if chosen == best_option and np.isfinite(second):
            margins[i] = second - best
    return margins


def _hand_sides(hands: str) -> list[str]:
    if hands not in HANDS or hands == "auto":
        raise InputError(f"hands must be one of {', '.join(HANDS)}, not '{hands}'")
    return ["right", "left"] if hands == "both" else [hands]


def _objects(objects: Sequence[ObjectSpec] | str | Path | None) -> list[ObjectSpec]:
    if objects is None:
        return []
    if isinstance(objects, (str, Path)):
        return load_scene_spec(objects)
    objects = list(objects)
    if not all(isinstance(spec, ObjectSpec) for spec in objects):
        raise InputError("objects must be ObjectSpec entries or the path of a scene spec JSON file")
    return objects


def _positions(take: Take) -> np.ndarray:
    positions = np.asarray(take.marker_positions, dtype=float)
    if positions.ndim != 3 or positions.shape[0] == 0:
        raise InputError("the take has no frames; nothing to label")
    counts = np.isfinite(positions).all(axis=2).sum(axis=1)
    if not counts.any():
        raise InputError("every point of the take is missing (all NaN); nothing to label")
    if counts.max() < 3:
        raise InputError(f"no frame of the take has 3 or more points (at most {counts.max()}); automatic "
                         "labelling needs at least 3 to find a model")
    return positions


_Refreshed = dict[int, list[tuple[int, HandModel, MarkerSet]]]
"""Calibrations of single windows: {first frame of the window: [(hand track number, model, marker set)]}."""


def label_scene(take: Take, hands: str = "auto", layout: str | MarkerLayout | LabTemplate = "dense",
                objects: Sequence[ObjectSpec] | str | Path | None = None, online: bool = False,
                settings: SceneSettings | None = None,
                progress: Callable[[float], None] | None = None,
                cancelled: Callable[[], bool] | None = None,
                models: dict[str, HandModel] | None = None,
                initial_states: dict[str, object] | None = None) -> SceneLabelling:
    """Label the unlabelled points of ``take`` (``marker_positions (F,P,3)`` mm, NaN = no point) with
    the markers of ``hands`` ("auto": decided from the markers, see :mod:`core.labelling.sides`; "right",
    "left" or "both") wearing ``layout`` and of rigid ``objects``
    (specs, or the path of a scene spec JSON file; see :mod:`core.model.objects`). A lab template
    (:mod:`core.model.lab_template`, given or named as ``layout``) gives each side its own placement and the
    lab's own marker names (written as they are, unprefixed), its rigid objects join ``objects``, and each
    hand's labelling is judged against the whole-take hypotheses (:mod:`core.labelling.hypotheses`).

    ``online``: causal tracking only (no backward pass, calibration applied from the end of its
    window on); ``models``: hand models per side to use instead of the shipped template (they are
    still calibrated unless ``settings.calibrate`` is False); ``initial_states``: known states in
    frame 0 per model name (hand θ (26,), object pose (4,4)) instead of the automatic initialisation.
    Raises :class:`InputError` (empty or all-NaN take, fewer than 3 points, bad spec, no frame where
    any model initialises) and :class:`CancelledError` when ``cancelled()`` turns true.
    """
    positions = _positions(take)
    statistics = measure_take(positions)
    settings = (settings or SceneSettings()).adapted(statistics)
    scene = _scene(positions, hands, layout, objects, settings, models)
    stages = _Progress(progress, cancelled)
    calibrate_offline = settings.calibrate and not online
    pre: _Run | None = None
    refreshed: _Refreshed = {}
    if calibrate_offline and scene.sides:
        pre, refreshed = _calibrate_offline(scene, positions, initial_states, stages)
    run = _main_run(scene, positions, online, initial_states, pre)
    on_frame = None
    if refreshed:
        on_frame = _refresh_hook(run, refreshed)
    if settings.calibrate and online and scene.sides:
        on_frame = _online_calibration_hook(scene, run)
    run.forward(0, len(positions), stages.stage(0.15 if calibrate_offline else 0.0, 0.9, len(positions)), on_frame)
    if all(init < 0 for init in run.init_frames):
        raise InputError("no frame of the take initialises any model (is the layout right, and is each hand or "
                         "object a separate cluster with most of its markers visible in some frame?)")
    if not online:
        _backward_passes(run, scene, stages.stage(0.9, 1.0, len(run.tracks)))
    _link_and_rescue(run, scene, online)
    if progress is not None:
        progress(1.0)
    result = _result(run, scene, positions, online)
    result.noise_mm = statistics.noise_mm if statistics.measured else None
    result.side_decision = scene.decision
    result.health = assess_labelling(result, take.frame_rate)
    if scene.template is not None:
        result.health += check_whole_take(result, scene.template, result.noise_mm)
    return result


@dataclass
class _Scene:
    """What :func:`label_scene` tracks: the hands ``sides`` with their marker names, models and marker sets
    (replaced by the subject calibration, whose reports are kept in ``calibrations``), then the rigid
    objects ``specs``; ``decision`` how ``hands="auto"`` decided the sides (None when given)."""

    settings: SceneSettings
    layouts: dict[str, MarkerLayout]
    sides: list[str]
    specs: list[ObjectSpec]
    hand_names: dict[str, list[str]]
    hand_models: dict[str, HandModel]
    marker_sets: dict[str, MarkerSet]
    decision: SideDecision | None
    calibrations: dict[str, dict] = field(default_factory=dict)
    template: LabTemplate | None = None

    def track(self, number: int) -> Track:
        """A fresh track ``number``: the hands first (with their current models), then the objects."""
        if number < len(self.sides):
            side = self.sides[number]
            return HandTracker(side, side, self.hand_models[side], self.marker_sets[side], self.settings,
                             self.hand_names[side])
        return RigidTrack(self.specs[number - len(self.sides)], self.settings)

    def tracks(self) -> list[Track]:
        """Fresh tracks of every model of the scene, in order."""
        return [self.track(number) for number in range(len(self.sides) + len(self.specs))]

    def calibrate(self, number: int, windows: list[tuple[_Run, int]]) -> bool:
        """Subject calibration of hand ``number`` from its labels in ``windows`` (:func:`_calibrate`);
        when it succeeds the hand's model and marker set are replaced. Returns whether it succeeded."""
        side = self.sides[number]
        calibrated = _calibrate(windows, number, self.hand_models[side], self.marker_sets[side])
        if calibrated is None:
            return False
        self.hand_models[side], self.marker_sets[side], self.calibrations[side] = calibrated
        return True


def _scene(positions: np.ndarray, hands: str, layout: str | MarkerLayout | LabTemplate,
           objects: Sequence[ObjectSpec] | str | Path | None, settings: SceneSettings,
           models: dict[str, HandModel] | None) -> _Scene:
    """The hands (``hands="auto"``: decided from ``positions (F,P,3)`` mm) and objects to track, with the
    given hand models or the shipped templates; with a plain layout the hands' marker names are prefixed
    ``R_``/``L_`` when both are tracked, with a lab template each side has its own names (a side the template
    lacks borrows the other's placement, prefixed). Raises :class:`InputError` for unknown ``hands``, a bad
    spec or clashing names."""
    template = _lab_template(layout)
    layouts = _side_layouts(layout, template)
    if template is not None:
        settings = replace(settings, cluster_cut_mm=max(settings.cluster_cut_mm, template_cluster_cut(template)))
    specs = _objects(objects)
    if template is not None:
        given_names = {spec.name for spec in specs}
        specs += [spec for spec in template.objects if spec.name not in given_names]
    given = dict(models or {})
    expect_both = template is not None and len(template.sides) == 2
    decision = _decide_sides(positions, layouts, settings, given, specs, expect_both) if hands == "auto" else None
    sides = decision.sides if decision is not None else _hand_sides(hands)
    hand_models = {side: given.get(side) or load_template(side) for side in sides}
    hand_names = {}
    for side in sides:
        own = template is not None and side in template.hands
        prefix = "" if own or len(sides) == 1 else HAND_PREFIX[side]
        hand_names[side] = [prefix + name for name in layouts[side].names]
    check_unique_names(specs, "scene", [name for names in hand_names.values() for name in names])
    marker_sets = {side: resolve_layout(hand_models[side], layouts[side]) for side in sides}
    return _Scene(settings, {side: layouts[side] for side in sides}, sides, specs, hand_names, hand_models,
                  marker_sets, decision, template=template)


REACH_SD = 2.0
"""A template hand's markers reach each other up to their mean distance plus this many standard deviations."""


def template_cluster_cut(template: LabTemplate) -> float:
    """The single-linkage cut (mm) that keeps each of the template's hands one cluster in the postures it was
    learned in: the largest gap of the hand's minimum spanning tree over the learned pair distances (mean +
    :data:`REACH_SD` standard deviations) × the linking margin (a fretting hand's thumb behind the neck stands
    farther from its fingers than the model's mean posture says)."""
    from scipy.sparse.csgraph import minimum_spanning_tree  # imported when first needed (start-up)

    cut = 0.0
    for side in template.sides:
        statistics = template.hands[side].statistics
        reach = statistics.mean_mm + REACH_SD * statistics.sd_mm
        if len(reach) < 2 or not np.isfinite(reach).all():
            continue
        tree = minimum_spanning_tree(np.maximum(reach, 1e-6) * (1 - np.eye(len(reach)))).toarray()
        cut = max(cut, LINK_MARGIN * float(tree.max()))
    return cut


def _lab_template(layout: str | MarkerLayout | LabTemplate) -> LabTemplate | None:
    """The lab template ``layout`` is or names (None for a plain layout)."""
    if isinstance(layout, LabTemplate):
        return layout
    return load_lab_template(layout) if isinstance(layout, str) else None


def _side_layouts(layout: str | MarkerLayout | LabTemplate, template: LabTemplate | None) -> dict[str, MarkerLayout]:
    """The layout each side wears: the template's per side, else the one layout for both."""
    if template is not None:
        return {side: template.layout_for(side) for side in ("right", "left")}
    plain = load_layout(layout) if isinstance(layout, str) else layout
    assert isinstance(plain, MarkerLayout)
    return {"right": plain, "left": plain}


class _Progress:
    """Progress and cancellation of one labelling, in stages: calibration pre-passes 0..0.15, forward
    pass 0.15..0.9 (from 0 without pre-passes), backward passes 0.9..1."""

    def __init__(self, progress: Callable[[float], None] | None, cancelled: Callable[[], bool] | None):
        self.progress, self.cancelled = progress, cancelled

    def stage(self, low: float, high: float, total: int) -> Callable[[int], None]:
        """A reporter for steps ``0..total`` mapped onto ``low..high``; it checks for cancellation (raising
        :class:`CancelledError`) and reports about 100 times over the stage."""
        every = max(1, total // 100)

        def report(step: int) -> None:
            if step % every == 0:
                if self.cancelled is not None and self.cancelled():
                    raise CancelledError("automatic labelling cancelled; the take is unchanged")
                if self.progress is not None:
                    self.progress(low + (high - low) * min(step, total) / max(total, 1))
        return report


def _calibrate_offline(scene: _Scene, positions: np.ndarray, initial_states: dict[str, object] | None,
                       stages: _Progress) -> tuple[_Run, _Refreshed]:
    """Offline subject calibration (module docstring, step 2): a pre-pass with the template hands over each
    calibration window, one calibration per hand pooled over the windows (replacing the scene's hands),
    and the later windows that calibration fits clearly worse calibrated alone
    (:func:`_refreshed_calibrations`). Returns the first window's pre-pass and those refreshed calibrations."""
    frames = len(positions)
    windows = _calibration_windows(frames, scene.settings)
    prepasses = []
    for number, offset in enumerate(windows):
        report = stages.stage(0.15 * number / len(windows), 0.15 * (number + 1) / len(windows), frames - offset)
        prepasses.append(_prepass(positions[offset:], scene.tracks(), scene.settings,
                                  initial_states if offset == 0 else None, scene.track, report,
                                  scene.decision if offset == 0 else None))
    template_models = dict(scene.hand_models)
    for number in range(len(scene.sides)):
        scene.calibrate(number, [(run, len(run.positions)) for run in prepasses])
    refreshed = _refreshed_calibrations(prepasses, windows, scene.tracks(), template_models, scene.layouts)
    return prepasses[0], refreshed


def _main_run(scene: _Scene, positions: np.ndarray, online: bool, initial_states: dict[str, object] | None,
              pre: _Run | None) -> _Run:
    """The run that labels the take with the scene's (calibrated) models: seeded with ``initial_states``;
    the hands scheduled to start where the calibration pre-pass ``pre`` started them (with its labels and
    states: re-running the initial fit with a model adapted to the window could pick another,
    self-consistent labelling), or else where ``hands="auto"`` decided them. Offline, initial fits with
    runner-up hypotheses are decided by tracking each (:meth:`_Run._window_cost`)."""
    tracks = scene.tracks()
    run = _Run(tracks, positions, scene.settings, None if online else scene.track)
    _seed(run, tracks, initial_states)
    if pre is None:
        _schedule_decided(run, tracks, scene.decision)
        return run
    for number, init in enumerate(pre.init_frames):
        if init >= 0 and run.init_frames[number] < 0:
            run.scheduled.setdefault(init, []).append(
                (number, pre.assignment[init, pre.columns(number)].copy(), pre.states[number][init].copy()))
    return run


def _refresh_hook(run: _Run, refreshed: _Refreshed) -> Callable[[int], None]:
    """Per frame of the forward pass: from the first frame of each window with a calibration of its own
    (:func:`_refreshed_calibrations`) on, its hands track with that calibration."""
    def on_frame(frame: int) -> None:
        for number, model, markers in refreshed.get(frame + 1, []):
            track = run.tracks[number]
            assert isinstance(track, HandTracker)
            track.set_model(model, markers)
    return on_frame


def _online_calibration_hook(scene: _Scene, run: _Run) -> Callable[[int], None]:
    """Per frame of the online forward pass: once a hand has been tracked for ``calibration_frames`` frames,
    calibrate it on those frames (causal) and track on with the calibrated hand."""
    pending = set(range(len(scene.sides)))

    def on_frame(frame: int) -> None:
        for number in list(pending):
            init = run.init_frames[number]
            if init >= 0 and frame >= init + scene.settings.calibration_frames - 1:
                pending.discard(number)
                if scene.calibrate(number, [(run, frame + 1)]):
                    side, track = scene.sides[number], run.tracks[number]
                    assert isinstance(track, HandTracker)
                    track.set_model(scene.hand_models[side], scene.marker_sets[side])
    return on_frame


def _backward_passes(run: _Run, scene: _Scene, report: Callable[[int], None]) -> None:
    """Offline, per model: a hand is tracked again backwards from each frame where it was fitted afresh,
    its start verified and its labelling re-checked; then the frames before its first initialisation
    are labelled backwards (:meth:`_Run.backward`)."""
    for number in range(len(run.tracks)):
        report(number)
        if isinstance(run.tracks[number], HandTracker):
            for frame in run.reinitialised.get(number, []):
                run.retrack(number, scene.track(number), frame, 0, converge=scene.settings.hypothesis_frames)
            run.verify_start(number, scene.track(number))
            run.recheck(number)
        run.backward(number, partial(scene.track, number))


def _link_and_rescue(run: _Run, scene: _Scene, online: bool) -> None:
    """Per model: extend its trajectories into continuing free points (forward only online); per hand,
    give long free trajectories to the marker the IK brings onto them and, offline, repair swaps."""
    for number in range(len(run.tracks)):
        track = scene.track(number)
        run.link(number, track, backward=not online)
        if isinstance(track, HandTracker):
            run.rescue(number, track, causal=online)
            if not online:
                run.repair_swaps(number, track)


def _decide_sides(positions: np.ndarray, layouts: dict[str, MarkerLayout], settings: SceneSettings,
                  models: dict[str, HandModel], specs: list[ObjectSpec], expect_both: bool = False) -> SideDecision:
    """``hands="auto"``: which hands the take shows (:func:`core.labelling.sides.decide_sides`), each side
    tried with the layout it wears."""
    hand_models = {side: models.get(side) or load_template(side) for side in ("right", "left")}
    marker_sets = {side: resolve_layout(model, layouts[side]) for side, model in hand_models.items()}

    def make_track(side: str) -> HandTracker:
        return HandTracker(side, side, hand_models[side], marker_sets[side], settings)

    objects = [RigidTrack(spec, settings) for spec in specs]
    cut = cluster_cut([make_track("right"), *objects], settings)
    return decide_sides(positions, make_track, settings, cut,
                        lambda track, frame, labels, state: window_cost(track, positions, frame, labels, state,
                                                                        settings), objects, expect_both)


class _WindowDone(Exception):
    """Internal: a window has been tracked far enough (the calibration window, a hypothesis out of the running)."""


def _seed(run: _Run, tracks: list[Track], initial_states: dict[str, object] | None) -> None:
    for name, given in (initial_states or {}).items():
        number = next((i for i, track in enumerate(tracks) if track.name == name), None)
        if number is None:
            raise InputError(f"initial state for unknown model '{name}'")
        state = np.asarray(given, dtype=float)
        expected = (N_PARAMS,) if isinstance(tracks[number], HandTracker) else (4, 4)
        if state.shape != expected or not np.isfinite(state).all():
            raise InputError(f"the initial state of '{name}' must be finite with shape {expected}, got {state.shape}")
        run.start_at(0, number, state)


def _schedule_decided(run: _Run, tracks: list[Track], decision: SideDecision | None) -> None:
    """Start the hands of ``run`` where, and with the labels and states that, ``hands="auto"`` decided."""
    if decision is None:
        return
    for number, track in enumerate(tracks):
        start = decision.starts.get(track.kind) if isinstance(track, HandTracker) else None
        if start is not None and run.init_frames[number] < 0:
            run.scheduled.setdefault(decision.frame, []).append((number, start[0].copy(), start[1].copy()))


def _calibration_windows(frames: int, settings: SceneSettings) -> list[int]:
    """First frames of the calibration pre-passes: one window per :data:`CALIBRATION_SPACING` ×
    ``calibration_frames`` frames of the take (at most :data:`MAX_CALIBRATION_WINDOWS`), evenly spread,
    so the subject calibration of a long take sees all of it, not only its start."""
    count = int(np.clip(np.ceil(frames / (CALIBRATION_SPACING * settings.calibration_frames)), 1,
                        MAX_CALIBRATION_WINDOWS))
    return [int(round(number * frames / count)) for number in range(count)]


def _prepass(positions: np.ndarray, tracks: list[Track], settings: SceneSettings,
             initial_states: dict[str, object] | None, make_track: Callable[[int], Track],
             report: Callable[[int], None], decision: SideDecision | None = None) -> _Run:
    """Label ``positions (F,P,3)`` with the uncalibrated ``tracks`` until every hand has been tracked for
    ``calibration_frames`` frames (or the end), then verify, link, rescue and repair swaps: the labelled
    window a subject calibration is fitted to (hands starting from the fits ``decision`` chose, when
    given). Returns the run, truncated to the window."""
    pre = _Run(tracks, positions, settings, make_track)
    _seed(pre, tracks, initial_states)
    _schedule_decided(pre, tracks, decision)
    window_end = len(positions)
    hands = [number for number, track in enumerate(tracks) if isinstance(track, HandTracker)]

    def stop_when_calibrated(frame: int) -> None:
        nonlocal window_end
        inits = [pre.init_frames[number] for number in hands]
        if all(init >= 0 for init in inits) and frame >= max(inits) + settings.calibration_frames - 1:
            window_end = frame + 1
            raise _WindowDone

    with contextlib.suppress(_WindowDone):
        pre.forward(0, len(positions), report, stop_when_calibrated)
    pre.truncate(window_end)
    for number in hands:
        track = make_track(number)
        assert isinstance(track, HandTracker)
        pre.verify_start(number, track)
        pre.link(number, track, backward=True)
        pre.rescue(number, track)
        pre.repair_swaps(number, track, every_fragment=True)
    return pre


def _refreshed_calibrations(prepasses: list[_Run], windows: list[int], tracks: list[Track],
                            template_models: dict[str, HandModel], layouts: dict[str, MarkerLayout]) -> _Refreshed:
    """Per later calibration window whose frames the pooled subject model fits clearly worse than the
    first window's (mean residual above :data:`REFRESH_RATIO` × the first's: the markers moved on the
    skin, a glove slipped), a calibration of that window alone, to track with from the window's first
    frame on. Returns {first frame: [(hand track number, model, marker set)]}."""
    refreshed: _Refreshed = {}
    for number, track in enumerate(tracks):
        if not isinstance(track, HandTracker) or len(prepasses) < 2:
            continue
        fits = [_window_residual(run, number, track) for run in prepasses]
        for run, offset, fit in zip(prepasses[1:], windows[1:], fits[1:], strict=True):
            if not (np.isfinite(fit) and fit > REFRESH_RATIO * fits[0]):
                continue
            calibrated = _calibrate([(run, len(run.positions))], number, template_models[track.kind],
                                    resolve_layout(template_models[track.kind], layouts[track.kind]))
            if calibrated is not None:
                refreshed.setdefault(offset, []).append((number, calibrated[0], calibrated[1]))
    return refreshed


def _window_residual(run: _Run, number: int, track: HandTracker, samples: int = 12) -> float:
    """Mean residual (mm) of ``track``'s (calibrated) hand on up to ``samples`` labelled frames of a pre-pass."""
    part = run.columns(number)
    states = run.states[number]
    frames = np.flatnonzero(np.isfinite(states).all(axis=1) & ((run.assignment[:, part] >= 0).sum(axis=1) >= 3))
    if not len(frames):
        return np.nan
    chosen = frames[np.unique(np.linspace(0, len(frames) - 1, min(samples, len(frames))).round().astype(int))]
    values = []
    for frame in chosen:
        index = run.assignment[frame, part]
        _, _, residuals = run._solve(track, run.positions[frame], index, states[frame])
        values.append(float(residuals[index >= 0].mean()))
    return float(np.mean(values))


REFRESH_RATIO = 1.25
"""A later window fitted this much worse than the first by the pooled subject model gets its own calibration."""
CALIBRATION_SPACING = 10
"""One calibration window per this many × ``calibration_frames`` frames of a take (15 s at 100 Hz)."""
MAX_CALIBRATION_WINDOWS = 6


def _calibrate(windows: list[tuple[_Run, int]], number: int, model: HandModel, markers: MarkerSet
               ) -> tuple[HandModel, MarkerSet, dict] | None:
    """Subject calibration of hand track ``number`` from its labelled frames in ``windows``: (run, the
    frame before which its labels are used), pooled."""
    from handmocap.core.calibration.subject import calibrate_subject

    labelled_parts, angle_parts = [], []
    for run, stop in windows:
        init = run.init_frames[number]
        if init < 0 or stop <= init:
            continue
        part = run.columns(number)
        assignment = run.assignment[init:stop, part]
        taken = np.take_along_axis(run.positions[init:stop], np.maximum(assignment, 0)[:, :, None], axis=1)
        labelled_parts.append(np.where((assignment >= 0)[:, :, None], taken, np.nan))
        angle_parts.append(run.states[number][init:stop])
    if not labelled_parts:
        return None
    try:
        return calibrate_subject(np.concatenate(labelled_parts), model, markers,
                                 initial_angles=np.concatenate(angle_parts))
    except InputError:
        return None


def _result(run: _Run, scene: _Scene, positions: np.ndarray, online: bool) -> SceneLabelling:
    """The labelling ``run`` made of the scene's models over ``positions (F,P,3)`` mm."""
    names: list[str] = []
    owner: list[int] = []
    scene_models: list[SceneModel] = []
    joint_angles: dict[str, np.ndarray] = {}
    object_poses: dict[str, np.ndarray] = {}
    for number, track in enumerate(run.tracks):
        names += track.marker_names
        owner += [number] * track.count
        if isinstance(track, HandTracker):
            scene_models.append(SceneModel(track.name, track.kind, run.columns(number),
                                           scene.hand_models[track.kind], scene.marker_sets[track.kind], None,
                                           run.init_frames[number], scene.calibrations.get(track.kind, {}),
                                           run.reinitialised.get(number, [])))
            joint_angles[track.name] = run.states[number]
        else:
            assert isinstance(track, RigidTrack)
            scene_models.append(SceneModel(track.name, "object", run.columns(number), None, None, track.spec,
                                           run.init_frames[number]))
            object_poses[track.name] = run.states[number]
    return SceneLabelling(names, np.array(owner, dtype=np.int64), scene_models, run.assignment, run.confidence,
                         run.residuals, run.ghost_points(), joint_angles, object_poses, positions, online)
