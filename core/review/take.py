"""The labelled take under review: raw points, labels, provenance, fills, confidence, solves, problems.

A :class:`ReviewTake` holds the raw :class:`~core.io.Take` (points ``(F, P, 3)`` mm, never modified)
and, per label (M labels, e.g. the layout's markers, ``R_``/``L_`` prefixed for two hands):

* ``assignment (F, M)`` int64: the raw point column each label takes in each frame, -1 for none;
* ``provenance (F, M)`` int8: :data:`MEASURED` 0 (assigned point), 1 linear, 2 spline, 3 pattern,
  4 rigid body, 5 model fill, 6 PCA fill, :data:`MISSING` -1 (the codes of :mod:`core.model.provenance`);
* ``filled_positions (F, M, 3)`` mm: accepted fills, NaN elsewhere;
* ``edited (F, M)`` bool: samples changed by hand (assign, swap, unlabel, ghost);
* ``confidence (F, M)`` mm: labelling margin between the best and the second-best option (NaN unknown);
* ``residuals_mm (F, M)``: distance from the solved model effector to the label's position (NaN none);
* ``ghost (F, P)`` bool: raw points judged spurious (by the labeller or by hand);
* ``hands``: one :class:`HandTrack` per solved hand with its labels and ``joint_angles (F, 26)``;
* ``rigid_bodies``: the labels of each rigid object labelled with the take, ``{name: [label index]}``;
* ``health``: the doubts of the labelling that made the labels (:class:`~core.labelling.health.HealthWarning`,
  0-based inclusive frames) and ``noise_mm``, the marker noise σ per axis it estimated (None unknown);
* ``events``: the take's named frames (:class:`~core.io.c3d_events.TakeEvent`, by the file's frame number;
  first read from the file's C3D ``EVENT`` group) and ``trim``: the frames ``start .. stop - 1`` the take is
  trimmed to (None: the whole take). Exports write the trimmed take (:meth:`ReviewTake.trimmed`).

Invariants kept by every command: ``provenance == 0`` exactly where ``assignment >= 0``; a fill
(codes 1..6, finite ``filled_positions``) only where ``assignment == -1``; a point column is taken by
at most one label per frame; a point taken by a label is not a ghost.

Derived views (cached until the next change): :meth:`ReviewTake.labelled_positions`,
:meth:`ReviewTake.marker_stats`, :meth:`ReviewTake.lane_states` (timeline lanes),
:meth:`ReviewTake.problems` and :meth:`ReviewTake.next_problem` ("next problem" navigation).
Everything here is 0-based; ``take.first_frame`` is the file's number of frame 0 for display.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.c3d_events import TakeEvent, read_events
from handmocap.core.labelling.health_warning import WARNING_KINDS, HealthWarning
from handmocap.core.model.hand_columns import detect_hands
from handmocap.core.model.provenance import MEASURED, MISSING

# Timeline lane states (``lane_states``), in increasing priority within a sample.
LANE_NONE = 0            #: before the label's first or after its last sample: nothing to show
LANE_OBSERVED = 1        #: a measured point
LANE_GAP = 2             #: no point and no fill between two samples (an unfilled gap)
LANE_FILLED = 3          #: an accepted fill
LANE_LOW_CONFIDENCE = 4  #: a measured point whose labelling confidence is below the threshold
LANE_EDITED = 5          #: changed by hand
LANE_NAMES = ("none", "observed", "gap", "filled", "low confidence", "edited")

PROBLEM_KINDS = ("low_confidence", "swap", "gap", "labelling")
#: health warning kinds, most serious first (the status bar names the most serious one)
HEALTH_SEVERITY = ("no_hand", "whole_take_doubt", "whole_take_identity", "side_uncertain", "low_labelled_share",
                   "reinitialised", "many_ghosts", "high_residual", "noisy_take")

#: per-frame arrays a command may change, captured for undo (name -> axis 0 is the frame)
FRAME_ARRAYS = ("assignment", "provenance", "edited", "filled_positions", "confidence", "residuals_mm", "ghost")


@dataclass(frozen=True)
class ReviewSettings:
    """Thresholds of the review views; distances in mm.

    ``low_confidence_mm``: a measured sample whose labelling margin is below this is "low confidence";
    swap suspects (:meth:`ReviewTake.swap_suspects`) are judged from each marker's own speed: a label's jump
    from the constant-velocity prediction of its two previous frames is a suspect when it exceeds
    ``swap_speed_ratio`` times the marker's speed just before and just after it, and ``swap_jump_mm`` (and 10
    times the take's noise) — and the label does not come back to its path the next frame (a one-frame spike
    is no swap); or when two labels jump in the same frame by more than ``swap_pair_mm`` each and each lands
    where the other was going (their prediction error exchanged is below ``swap_pair_ratio`` of their own);
    ``swap_close_mm``: a low-confidence sample with another label's point this close is a swap suspect;
    ``follow_gate_mm``: an unlabelled point is followed to the next frame's nearest point within this.
    """

    low_confidence_mm: float = 1.5
    swap_jump_mm: float = 12.0
    swap_close_mm: float = 20.0
    follow_gate_mm: float = 15.0
    swap_speed_ratio: float = 4.0
    swap_pair_mm: float = 5.0
    swap_pair_ratio: float = 0.5


@dataclass
class HandTrack:
    """One solved hand (or other kinematic model) of the take.

    ``name``: e.g. "right"; ``side``: "right" or "left"; ``layout``: the layout name it was labelled
    with (or None); ``labels (K,)`` int64: indices into ``ReviewTake.label_names``, in layout order;
    ``joint_angles (F, 26)`` rad / mm (NaN where not solved).
    """

    name: str
    side: str
    layout: str | None
    labels: np.ndarray
    joint_angles: np.ndarray

    def __post_init__(self) -> None:
        self.labels = np.asarray(self.labels, dtype=np.int64).reshape(-1)
        self.joint_angles = np.ascontiguousarray(self.joint_angles, dtype=np.float64)
        if self.side not in ("right", "left"):
            raise InputError(f"hand '{self.name}': side must be 'right' or 'left', not '{self.side}'")
        if self.joint_angles.ndim != 2 or self.joint_angles.shape[1] != 26:
            raise InputError(f"hand '{self.name}': joint angles must be (F, 26), got {self.joint_angles.shape}")

    def copy(self) -> HandTrack:
        return HandTrack(self.name, self.side, self.layout, self.labels.copy(), self.joint_angles.copy())

    def meta(self) -> dict[str, Any]:
        """JSON description (without the joint angles)."""
        return {"name": self.name, "side": self.side, "layout": self.layout, "labels": self.labels.tolist()}


def detected_hands(label_names: list[str], n_frames: int, layout: str | None = None,
                   side: str | None = None) -> list[HandTrack]:
    """Unsolved tracks of the hands :func:`core.model.detect_hands` finds among ``label_names`` (with
    ``layout`` given or recognised; ``side`` for a hand whose names do not say it): each track holds the labels
    of the layout markers present, in layout order, and the layout's name."""
    return [HandTrack(hand.side, hand.side, hand.layout_name, hand.labels, np.full((n_frames, 26), np.nan))
            for hand in detect_hands(label_names, layout, side)]


def copy_health(warnings: list) -> list[HealthWarning]:
    """``warnings`` (:class:`HealthWarning` or their dicts) as a new list of :class:`HealthWarning`."""
    return [warning if isinstance(warning, HealthWarning) else HealthWarning.from_dict(warning)
            for warning in warnings or []]


def copy_rigid_bodies(groups: dict) -> dict[str, list[int]]:
    """A copy of ``{rigid body name: [label index]}`` with plain ``str`` names and ``int`` indices."""
    return {str(name): [int(label) for label in labels] for name, labels in groups.items()}


@dataclass(frozen=True)
class MarkerStats:
    """Per-label statistics for the marker table, each ``(M,)``.

    ``observed_percent``: % of frames with a measured point; ``filled_percent``: % with an accepted
    fill; ``gap_count`` / ``longest_gap``: unfilled runs between the label's first and last sample
    (frames); ``mean_residual_mm``: mean solve residual (NaN none); ``lowest_confidence_mm``: lowest
    labelling margin (NaN unknown); ``edited_count``: samples changed by hand.
    """

    names: list[str]
    observed_percent: np.ndarray
    filled_percent: np.ndarray
    gap_count: np.ndarray
    longest_gap: np.ndarray
    mean_residual_mm: np.ndarray
    lowest_confidence_mm: np.ndarray
    edited_count: np.ndarray


@dataclass(frozen=True)
class Problem:
    """Something the operator should look at: frames ``start .. stop - 1`` of label ``label``.

    ``kind``: "low_confidence", "swap", "gap" or "labelling" (a health warning of the labelling: then
    ``label`` is the first label of the model it is about, -1 for the whole scene); ``frame``: where to
    jump (the first frame); ``other``: the other label of a suspected swap (-1 none); ``score``: severity
    (mm for swaps and low confidence, frames for gaps and warnings); ``text``: one line for the operator
    (0-based frames inside, the text shows the file's frame numbers).
    """

    kind: str
    label: int
    start: int
    stop: int
    other: int = -1
    score: float = 0.0
    text: str = ""

    @property
    def frame(self) -> int:
        return self.start


def runs(flags: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of True along axis 0 of ``flags (F, M)``: columns, starts, stops (exclusive), each ``(R,)``,
    ordered by column then start."""
    flags = np.asarray(flags, dtype=bool)
    if flags.ndim == 1:
        flags = flags[:, None]
    padded = np.zeros((flags.shape[0] + 2, flags.shape[1]), dtype=np.int8)
    padded[1:-1] = flags
    change = np.diff(padded, axis=0).T  # (M, F+1)
    starts = np.argwhere(change == 1)
    stops = np.argwhere(change == -1)
    return starts[:, 0], starts[:, 1], stops[:, 1]


@dataclass(eq=False)
class ReviewTake:
    """The labelled take being reviewed (arrays documented in the module docstring).

    Build with :meth:`from_labelling` (a labelling result), :meth:`from_labelled_take` (a take whose
    columns are the labels), :meth:`unlabelled` (no labels yet) or
    :func:`core.review.export.review_from_labelled_c3d`. Change it only through
    commands (``core.review.commands``) so that every change is undoable and journalled.
    """

    take: Take
    label_names: list[str]
    assignment: np.ndarray
    provenance: np.ndarray
    edited: np.ndarray
    filled_positions: np.ndarray
    confidence: np.ndarray
    residuals_mm: np.ndarray
    ghost: np.ndarray
    hands: list[HandTrack] = field(default_factory=list)
    rigid_bodies: dict[str, list[int]] = field(default_factory=dict)
    health: list[HealthWarning] = field(default_factory=list)
    noise_mm: float | None = None
    settings: ReviewSettings = field(default_factory=ReviewSettings)
    events: list[TakeEvent] | None = None
    trim: tuple[int, int] | None = None
    version: int = 0
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        frames, points = self.take.n_frames, self.take.n_markers
        count = len(self.label_names)
        self.label_names = [str(name) for name in self.label_names]
        if len(set(self.label_names)) != count:
            duplicate = next(n for n in self.label_names if self.label_names.count(n) > 1)
            raise InputError(f"duplicate label name '{duplicate}'")
        self.assignment = _array(self.assignment, np.int64, (frames, count), "assignment")
        self.provenance = _array(self.provenance, np.int8, (frames, count), "provenance")
        self.edited = _array(self.edited, bool, (frames, count), "edited")
        self.filled_positions = _array(self.filled_positions, np.float64, (frames, count, 3), "filled positions")
        self.confidence = _array(self.confidence, np.float64, (frames, count), "confidence")
        self.residuals_mm = _array(self.residuals_mm, np.float64, (frames, count), "residuals")
        self.ghost = _array(self.ghost, bool, (frames, points), "ghost flags")
        if ((self.assignment < -1) | (self.assignment >= points)).any():
            raise InputError(f"assignment holds point columns outside 0..{points - 1}")
        taken = self.assignment >= 0
        present = np.isfinite(self.take.marker_positions).all(axis=2)
        frame_index, label_index = np.nonzero(taken)
        if not present[frame_index, self.assignment[frame_index, label_index]].all():
            raise InputError("assignment gives a label a point column that is missing in that frame")
        for hand in self.hands:
            if hand.joint_angles.shape[0] != frames:
                raise InputError(f"hand '{hand.name}' has {hand.joint_angles.shape[0]} frames of joint angles "
                                 f"for a take of {frames}")
            if len(hand.labels) and (hand.labels.min() < 0 or hand.labels.max() >= count):
                raise InputError(f"hand '{hand.name}' refers to labels outside 0..{count - 1}")
        self.rigid_bodies = copy_rigid_bodies(self.rigid_bodies)
        self.health = copy_health(self.health)
        self.noise_mm = None if self.noise_mm is None else float(self.noise_mm)
        for name, labels in self.rigid_bodies.items():
            if any(not 0 <= label < count for label in labels):
                raise InputError(f"rigid body '{name}' refers to labels outside 0..{count - 1}")
        if self.events is None:         # a new review: the events the file has
            self.events = read_events(self.take.parameters, self.take.frame_rate)
        self.events = sorted((event if isinstance(event, TakeEvent) else TakeEvent.from_dict(event)
                              for event in self.events), key=lambda event: (event.frame_number, event.name))
        if self.trim is not None:
            start, stop = (int(value) for value in self.trim)
            if not 0 <= start < stop <= frames:
                raise InputError(f"trim range {start}..{stop - 1} is outside the take (0..{frames - 1})")
            self.trim = (start, stop)

    # --- construction -------------------------------------------------------------------------------

    @classmethod
    def unlabelled(cls, take: Take, label_names: list[str] | None = None,
                   hands: list[HandTrack] | None = None) -> ReviewTake:
        """A review of a raw take with ``label_names`` (default none) and no point assigned yet."""
        names = list(label_names or [])
        frames, count = take.n_frames, len(names)
        return cls(take=take, label_names=names,
                   assignment=np.full((frames, count), -1, dtype=np.int64),
                   provenance=np.full((frames, count), MISSING, dtype=np.int8),
                   edited=np.zeros((frames, count), dtype=bool),
                   filled_positions=np.full((frames, count, 3), np.nan),
                   confidence=np.full((frames, count), np.nan),
                   residuals_mm=np.full((frames, count), np.nan),
                   ghost=np.zeros((frames, take.n_markers), dtype=bool),
                   hands=list(hands or []))

    @classmethod
    def from_labelled_take(cls, take: Take, hands: list[HandTrack] | None = None,
                           provenance: np.ndarray | None = None) -> ReviewTake:
        """A review of an already-labelled take: the labels are the take's columns, each label takes its
        own column where it is finite; ``hands`` None: the hands its names show (:func:`detected_hands`). With
        ``provenance (F, M)`` (e.g. from a labelled C3D), samples coded as fills (> 0) become accepted fills
        and are removed from the review's raw take (a fill is not a measurement)."""
        if hands is None:
            hands = detected_hands(list(take.marker_names), take.n_frames)
        present = np.isfinite(take.marker_positions).all(axis=2)
        filled = np.zeros_like(present)
        codes = np.zeros(present.shape, dtype=np.int8)
        if provenance is not None:
            codes = np.asarray(provenance).astype(np.int8)
            if codes.shape != present.shape:
                raise InputError(f"provenance has shape {codes.shape}, the take {present.shape}")
            filled = present & (codes > 0)
        raw = take
        if filled.any():
            raw = Take(marker_names=list(take.marker_names),
                       marker_positions=np.where(filled[:, :, None], np.nan, take.marker_positions),
                       frame_rate=take.frame_rate, first_frame=take.first_frame, vendor=take.vendor,
                       source_units=take.source_units, source_path=take.source_path, parameters=take.parameters)
        review = cls.unlabelled(raw, list(take.marker_names), hands)
        measured = present & ~filled
        review.assignment = np.where(measured, np.arange(take.n_markers)[None, :], -1).astype(np.int64)
        review.provenance = np.where(measured, MEASURED, np.where(filled, codes, MISSING)).astype(np.int8)
        review.filled_positions = np.where(filled[:, :, None], take.marker_positions, np.nan)
        return review

    @classmethod
    def from_labelling(cls, take: Take, result: Any, hands: list[HandTrack] | None = None,
                       side: str = "right", layout: str | None = None) -> ReviewTake:
        """A review of a labelling result on ``take`` (points ``(F, P, 3)``).

        ``result`` has ``marker_names (M,)``, ``assignment (F, M)``, ``confidence (F, M)``,
        ``residuals_mm (F, M)``, ``ghost_points (F, P)`` and ``joint_angles`` — ``(F, 26)`` for one hand
        (e.g. :class:`core.review.synthetic.SyntheticLabelling`: then ``side``/``layout`` describe it and
        every label belongs to it) or a dict ``{hand name: (F, 26)}`` with the labels of each hand given by ``hands`` (a
        list of :class:`HandTrack`), a ``result.hands`` list, or ``result.models`` whose hand models
        (``kind`` "right"/"left") have a ``markers`` slice (``core.labelling.SceneLabelling``; rigid
        objects' markers are plain labels, grouped by ``result.rigid_bodies`` ``{name: [label index]}``
        when given). Optional ``filled_positions (F, M, 3)`` and ``provenance (F, M)`` are kept as
        accepted fills.
        """
        review = cls.unlabelled(take, [])
        review.replace_with_labelling(result, hands, side, layout)
        return review

    def replace_with_labelling(self, result: Any, hands: list[HandTrack] | None = None,
                               side: str = "right", layout: str | None = None) -> None:
        """Replace labels, assignment, confidence, residuals, ghosts, fills and hands by ``result``
        (see :meth:`from_labelling`); edit flags are cleared. Use through ``ApplyLabelling``."""
        frames, points = self.take.n_frames, self.take.n_markers
        names = [str(name) for name in result.marker_names]
        count = len(names)
        assignment = _array(result.assignment, np.int64, (frames, count), "labelling assignment")
        ghost = getattr(result, "ghost_points", None)
        ghost = np.zeros((frames, points), dtype=bool) if ghost is None else _array(
            ghost, bool, (frames, points), "labelling ghost points")
        confidence = _optional(getattr(result, "confidence", None), (frames, count), "labelling confidence")
        residuals = _optional(getattr(result, "residuals_mm", None), (frames, count), "labelling residuals")
        filled = _optional(getattr(result, "filled_positions", None), (frames, count, 3), "labelling fills")
        provenance_in = getattr(result, "provenance", None)
        provenance = np.where(assignment >= 0, MEASURED, MISSING).astype(np.int8)
        if provenance_in is not None:
            codes = _array(provenance_in, np.int8, (frames, count), "labelling provenance")
            fill = (assignment < 0) & (codes > 0) & np.isfinite(filled).all(axis=2)
            provenance[fill] = codes[fill]
        filled = np.where((provenance > 0)[:, :, None], filled, np.nan)
        given = hands if hands is not None else getattr(result, "hands", None) or []
        track_list = [hand.copy() for hand in given]  # never change the caller's tracks
        angles = getattr(result, "joint_angles", None)
        if not track_list and isinstance(angles, dict):  # a scene labelling: hands among its models
            for model in getattr(result, "models", None) or []:
                if getattr(model, "kind", None) in ("right", "left") and model.name in angles:
                    markers = model.markers
                    labels = np.arange(count)[markers] if isinstance(markers, slice) else np.asarray(markers)
                    track_list.append(HandTrack(model.name, model.kind, layout, labels, angles[model.name]))
        if not track_list and angles is not None and not isinstance(angles, dict):
            track_list = [HandTrack(side, side, layout, np.arange(count), np.asarray(angles, dtype=float))]
        elif isinstance(angles, dict):
            by_name = {hand.name: hand for hand in track_list}
            for name, values in angles.items():
                if name not in by_name:
                    raise InputError(f"labelling result has joint angles for hand '{name}' but no label list")
                by_name[name].joint_angles = np.array(values, dtype=float)
        self.label_names = names
        self.assignment = assignment
        self.provenance = provenance
        self.edited = np.zeros((frames, count), dtype=bool)
        self.filled_positions = filled
        self.confidence = confidence
        self.residuals_mm = residuals
        self.ghost = ghost & ~self._taken_points(assignment)
        self.hands = track_list
        self.rigid_bodies = copy_rigid_bodies(getattr(result, "rigid_bodies", None) or {})
        self.health = copy_health(getattr(result, "health", None) or [])
        self.noise_mm = getattr(result, "noise_mm", None)
        self.__post_init__()
        self.changed()

    # --- basic views --------------------------------------------------------------------------------

    @property
    def n_frames(self) -> int:
        return self.take.n_frames

    @property
    def n_labels(self) -> int:
        return len(self.label_names)

    @property
    def n_points(self) -> int:
        return self.take.n_markers

    @property
    def points(self) -> np.ndarray:
        """Raw points ``(F, P, 3)`` mm (read-only view; never modified)."""
        view = self.take.marker_positions.view()
        view.setflags(write=False)
        return view

    def label_index(self, name: str) -> int:
        """Index of label ``name`` (exact, else case-insensitive); InputError when unknown."""
        if name in self.label_names:
            return self.label_names.index(name)
        lowered = [label.lower() for label in self.label_names]
        if name.lower() in lowered:
            return lowered.index(name.lower())
        raise InputError(f"unknown label '{name}'")

    def hand_of_label(self, label: int) -> int:
        """Index in ``hands`` of the hand owning ``label``, -1 when none does."""
        for index, hand in enumerate(self.hands):
            if label in hand.labels:
                return index
        return -1

    def label_of_point(self, frame: int, column: int) -> int:
        """The label taking raw point ``column`` at ``frame``, -1 when it is unlabelled."""
        found = np.flatnonzero(self.assignment[frame] == column)
        return int(found[0]) if found.size else -1

    def point_labels(self) -> np.ndarray:
        """``(F, P)`` int64: the label of each raw point, -1 unlabelled."""
        result = np.full((self.n_frames, self.n_points), -1, dtype=np.int64)
        frames, labels = np.nonzero(self.assignment >= 0)
        result[frames, self.assignment[frames, labels]] = labels
        return result

    def unlabelled_points(self) -> np.ndarray:
        """``(F, P)`` bool: measured raw points no label takes (ghosts included)."""
        present = np.isfinite(self.take.marker_positions).all(axis=2)
        return present & ~self._taken_points(self.assignment)

    def _taken_points(self, assignment: np.ndarray) -> np.ndarray:
        taken = np.zeros((self.n_frames, self.n_points), dtype=bool)
        frames, labels = np.nonzero(assignment >= 0)
        taken[frames, assignment[frames, labels]] = True
        return taken

    def measured_positions(self) -> np.ndarray:
        """``(F, M, 3)`` mm: each label's assigned raw point, NaN where it has none."""
        cached = self._cached("measured")
        if cached is not None:
            return cached
        frames = np.arange(self.n_frames)[:, None]
        positions = self.take.marker_positions[frames, np.maximum(self.assignment, 0)]
        positions = np.where((self.assignment >= 0)[:, :, None], positions, np.nan)
        return self._store("measured", positions)

    def labelled_positions(self) -> np.ndarray:
        """``(F, M, 3)`` mm: measured points by assignment plus accepted fills, NaN elsewhere."""
        cached = self._cached("labelled")
        if cached is not None:
            return cached
        positions = np.where((self.provenance > 0)[:, :, None], self.filled_positions, self.measured_positions())
        return self._store("labelled", positions)

    def has_solved_hand(self) -> bool:
        """Whether a hand is solved in some frame (cached until the next change)."""
        cached = self._cached("solved")
        if cached is None:
            cached = self._store("solved", any(np.isfinite(hand.joint_angles).any() for hand in self.hands))
        return bool(cached)

    def labelled_positions_in(self, start: int, stop: int) -> np.ndarray:
        """``(stop - start, M, 3)`` mm: :meth:`labelled_positions` over frames ``start .. stop - 1`` only (what
        drawing one frame needs, without computing the whole take after each change)."""
        cached = self._cached("labelled")
        if cached is not None:
            return cached[start:stop]
        assignment = self.assignment[start:stop]
        frames = np.arange(start, start + len(assignment))[:, None]
        measured = self.take.marker_positions[frames, np.maximum(assignment, 0)]
        measured = np.where((assignment >= 0)[:, :, None], measured, np.nan)
        return np.where((self.provenance[start:stop] > 0)[:, :, None], self.filled_positions[start:stop], measured)

    def rigid_body_segments(self, frame: int) -> np.ndarray:
        """Lines ``(S, 2, 3)`` mm between every two labels of each rigid body that both have a
        position in ``frame`` (measured or filled): how the object is drawn."""
        positions = self.labelled_positions_in(frame, frame + 1)[0]
        segments = []
        for labels in self.rigid_bodies.values():
            present = np.array([label for label in labels if np.isfinite(positions[label]).all()], dtype=np.int64)
            first, second = np.triu_indices(len(present), k=1)
            segments.append(np.stack([positions[present[first]], positions[present[second]]], axis=1))
        return np.concatenate(segments) if segments else np.zeros((0, 2, 3))

    def labelled_take(self, include_fills: bool = True) -> Take:
        """A :class:`Take` with one column per label (measured points, plus fills when asked)."""
        positions = self.labelled_positions() if include_fills else self.measured_positions()
        return Take(marker_names=list(self.label_names), marker_positions=positions.copy(),
                    frame_rate=self.take.frame_rate, first_frame=self.take.first_frame, vendor=self.take.vendor,
                    source_units=self.take.source_units, source_path=self.take.source_path)

    def frame_number(self, frame: int) -> int:
        """The file's number of 0-based ``frame`` (what the operator sees)."""
        return int(frame) + self.take.first_frame

    # --- statistics, lanes, problems ----------------------------------------------------------------

    def low_confidence(self) -> np.ndarray:
        """``(F, M)`` bool: measured samples whose labelling confidence is below the threshold."""
        with np.errstate(invalid="ignore"):
            return (self.assignment >= 0) & (self.confidence < self.settings.low_confidence_mm)

    def _span_mask(self) -> np.ndarray:
        """``(F, M)`` bool: frames between each label's first and last sample (measured or filled)."""
        present = self.provenance != MISSING
        seen_before = np.maximum.accumulate(present, axis=0)
        seen_after = np.maximum.accumulate(present[::-1], axis=0)[::-1]
        return seen_before & seen_after

    def unfilled_gaps(self) -> np.ndarray:
        """``(F, M)`` bool: no point and no fill, between the label's first and last sample."""
        return (self.provenance == MISSING) & self._span_mask()

    def lane_states(self) -> np.ndarray:
        """``(F, M)`` int8 timeline lane state per sample: the ``LANE_*`` codes (``LANE_NAMES``)."""
        cached = self._cached("lanes")
        if cached is not None:
            return cached
        lanes = np.zeros(self.assignment.shape, dtype=np.int8)
        lanes[self.unfilled_gaps()] = LANE_GAP
        lanes[self.assignment >= 0] = LANE_OBSERVED
        lanes[self.provenance > 0] = LANE_FILLED
        lanes[self.low_confidence()] = LANE_LOW_CONFIDENCE
        lanes[self.edited] = LANE_EDITED
        return self._store("lanes", lanes)

    def marker_stats(self) -> MarkerStats:
        """Per-label statistics (:class:`MarkerStats`) for the marker table."""
        cached = self._cached("stats")
        if cached is not None:
            return cached
        frames = max(self.n_frames, 1)
        gaps = self.unfilled_gaps()
        columns, starts, stops = runs(gaps)
        gap_count = np.bincount(columns, minlength=self.n_labels)
        longest = np.zeros(self.n_labels, dtype=np.int64)
        np.maximum.at(longest, columns, stops - starts)
        measured = self.assignment >= 0
        with np.errstate(invalid="ignore"):
            residual = np.where(measured, self.residuals_mm, np.nan)
            residual_count = np.isfinite(residual).sum(axis=0)
            mean_residual = np.where(residual_count > 0, np.nansum(residual, axis=0) / np.maximum(residual_count, 1),
                                     np.nan)
            confidence = np.where(measured & np.isfinite(self.confidence), self.confidence, np.inf)
            lowest = confidence.min(axis=0, initial=np.inf)
        stats = MarkerStats(
            names=list(self.label_names),
            observed_percent=100.0 * measured.sum(axis=0) / frames,
            filled_percent=100.0 * (self.provenance > 0).sum(axis=0) / frames,
            gap_count=gap_count.astype(np.int64),
            longest_gap=longest,
            mean_residual_mm=mean_residual,
            lowest_confidence_mm=np.where(np.isfinite(lowest), lowest, np.nan),
            edited_count=self.edited.sum(axis=0).astype(np.int64),
        )
        return self._store("stats", stats)

    def jumps(self) -> np.ndarray:
        """``(F, M)`` mm: distance of each measured position from the constant-velocity prediction of
        the label's two previous frames (NaN where any of the three is not measured)."""
        positions = self.measured_positions()
        result = np.full(self.assignment.shape, np.nan)
        if self.n_frames >= 3:
            result[2:] = _norms(positions[2:] - 2.0 * positions[1:-1] + positions[:-2])
        return result

    def swap_suspects(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F, M)`` bool: samples where a label jumps as a swap would make it (:class:`ReviewSettings`:
        judged from the marker's own speed, a one-frame spike excluded, or two labels each landing where the
        other was going), and ``(F, M)`` int64: the other label of such a pair (-1: none)."""
        cached = self._cached("swap_suspects")
        if cached is not None:
            return cached
        settings, positions = self.settings, self.measured_positions()
        frames, count = self.assignment.shape
        flags = np.zeros((frames, count), dtype=bool)
        partners = np.full((frames, count), -1, dtype=np.int64)
        if frames >= 4:
            predicted = np.full(positions.shape, np.nan)
            predicted[2:] = 2.0 * positions[1:-1] - positions[:-2]
            jumps = _norms(positions - predicted)
            speed = np.full((frames, count), np.nan)            # a frame's step, not touching the jumping sample
            steps = _norms(positions[1:] - positions[:-1])
            speed[2:] = steps[:-1]                               # |p[f-1] - p[f-2]|
            speed[2:-2] = np.fmax(speed[2:-2], steps[3:])        # |p[f+2] - p[f+1]|
            floor = max(settings.swap_jump_mm, 10.0 * (self.noise_mm or 0.0))
            back = np.full((frames, count), np.nan)             # the next frame, from the path before the jump
            back[2:-1] = _norms(positions[3:] - 3.0 * positions[1:-2] + 2.0 * positions[:-3])
            with np.errstate(invalid="ignore"):
                threshold = np.fmax(floor, settings.swap_speed_ratio * speed)
                flags = (jumps > threshold) & ~(back < threshold)
                candidates = jumps > max(settings.swap_pair_mm, 10.0 * (self.noise_mm or 0.0))
            for frame in np.flatnonzero(candidates.sum(axis=1) >= 2):
                labels = np.flatnonzero(candidates[frame])
                # where each label is against where each other one was going: (a, b) = |p_a - pred_b|
                crossed = _norms(positions[frame, labels][:, None] - predicted[frame, labels][None, :])
                own = jumps[frame, labels]
                exchanged = crossed + crossed.T
                mine = own[:, None] + own[None, :]
                np.fill_diagonal(exchanged, np.inf)
                with np.errstate(invalid="ignore"):
                    pairs = np.argwhere(exchanged < settings.swap_pair_ratio * mine)
                for first, second in pairs:
                    a, b = int(labels[first]), int(labels[second])
                    flags[frame, [a, b]] = True
                    partners[frame, a], partners[frame, b] = b, a
        return self._store("swap_suspects", (flags, partners))

    def problems(self, kinds: tuple[str, ...] | list[str] = PROBLEM_KINDS) -> list[Problem]:
        """Every problem of the given kinds, ordered by first frame then label.

        * "low_confidence": a run of measured samples of one label below ``low_confidence_mm``;
        * "swap": a swap suspect — a label's trajectory jumps more than ``swap_jump_mm`` from its
          constant-velocity prediction (counted once per jump: the run of flagged frames), or a
          low-confidence sample with another label's point within ``swap_close_mm``; when two labels
          jump in the same frame they are reported as a pair (``other``);
        * "gap": an unfilled gap between the label's first and last sample;
        * "labelling": a health warning of the labelling (:attr:`health`) over its frames.
        """
        unknown = set(kinds) - set(PROBLEM_KINDS)
        if unknown:
            raise InputError(f"unknown problem kind '{sorted(unknown)[0]}' (use {', '.join(PROBLEM_KINDS)})")
        every = self._cached("problems")
        if every is None:
            every = self._store("problems", self._find_problems())
        return [problem for problem in every if problem.kind in kinds]

    def next_problem(self, frame: int, kinds: tuple[str, ...] | list[str] = PROBLEM_KINDS,
                     forward: bool = True, label: int | None = None) -> Problem | None:
        """The first problem starting after ``frame`` (before it when ``forward`` is False), optionally
        of one ``label`` only; wraps around the take; None when there is none."""
        candidates = [p for p in self.problems(kinds) if label is None or label in (p.label, p.other)]
        if not candidates:
            return None
        if forward:
            later = [p for p in candidates if p.start > frame]
            return later[0] if later else candidates[0]
        earlier = [p for p in candidates if p.start < frame]
        return earlier[-1] if earlier else candidates[-1]

    def _find_problems(self) -> list[Problem]:
        found: list[Problem] = []
        low = self.low_confidence()
        with np.errstate(invalid="ignore"):
            for column, start, stop in zip(*runs(low), strict=True):
                score = float(np.nanmin(self.confidence[start:stop, column]))
                found.append(Problem("low_confidence", int(column), int(start), int(stop), score=score,
                                     text=f"{self.label_names[column]}: low labelling confidence "
                                          f"({score:.1f} mm) at frames {self._frames_text(start, stop)}"))
            jumps = self.jumps()
        jumped, paired = self.swap_suspects()
        close = self._close_other(low)
        suspect = jumped | (close >= 0)
        for column, start, stop in zip(*(part.tolist() for part in runs(suspect)), strict=True):
            mates = paired[start:stop, column]
            partners = [int(p) for p in mates[mates >= 0]] or \
                [int(p) for p in np.flatnonzero(jumped[start:stop].any(axis=0)) if p != column]
            others = close[start:stop, column]
            other = partners[0] if partners else (int(others[others >= 0][0]) if (others >= 0).any() else -1)
            if other >= 0 and other < column and suspect[start:stop, other].any():
                continue  # reported once, under the lower label
            with np.errstate(invalid="ignore"):
                score = float(np.nanmax(np.where(jumped[start:stop, column], jumps[start:stop, column], 0.0)))
            if (mates >= 0).any():
                reason = f"the two exchange points: a jump of {score:.0f} mm onto the other's path"
            elif score > 0:
                reason = f"a jump of {score:.0f} mm, far more than the marker moves in a frame around it"
            else:
                reason = "low confidence next to another label"
            pair = f" and {self.label_names[other]}" if other >= 0 else ""
            found.append(Problem("swap", column, start, stop, other=other, score=score,
                                 text=f"{self.label_names[column]}{pair}: swap suspect ({reason}) at frames "
                                      f"{self._frames_text(start, stop)}"))
        for column, start, stop in zip(*runs(self.unfilled_gaps()), strict=True):
            found.append(Problem("gap", int(column), int(start), int(stop), score=float(stop - start),
                                 text=f"{self.label_names[column]}: unfilled gap of {stop - start} frame(s) at "
                                      f"frames {self._frames_text(start, stop)}"))
        found += self._health_problems()
        found.sort(key=lambda p: (p.start, p.label, PROBLEM_KINDS.index(p.kind)))
        return found

    def _health_problems(self) -> list[Problem]:
        """The labelling's health warnings as "labelling" problems (clipped to the take)."""
        problems = []
        for warning in self.health if self.n_frames else []:
            start = min(max(0, warning.first_frame), self.n_frames - 1)
            stop = min(self.n_frames, max(start, warning.last_frame) + 1)
            labels = next((hand.labels.tolist() for hand in self.hands if hand.name == warning.model),
                          self.rigid_bodies.get(warning.model, []))
            label = int(labels[0]) if len(labels) else -1
            problems.append(Problem("labelling", label, start, stop, score=float(stop - start),
                                    text=f"Auto-label: {warning.message} (frames {self._frames_text(start, stop)})"))
        return problems

    def health_summary(self) -> str:
        """One line on the labelling's health warnings for the status bar ("" when there are none)."""
        if not self.health:
            return ""
        count = len(self.health)
        order = [kind for kind in HEALTH_SEVERITY if kind in WARNING_KINDS] + list(WARNING_KINDS)
        worst = min(self.health, key=lambda warning: order.index(warning.kind) if warning.kind in order else len(order))
        return f"Auto-label: {count} warning{'s' if count > 1 else ''} — {worst.message}"

    def _close_other(self, flags: np.ndarray) -> np.ndarray:
        """``(F, M)`` int64: for flagged samples, another label whose point is within ``swap_close_mm``
        (the nearest), -1 otherwise."""
        result = np.full(flags.shape, -1, dtype=np.int64)
        frames = np.flatnonzero(flags.any(axis=1))
        if not frames.size:
            return result
        positions = self.measured_positions()[frames]  # (n, M, 3)
        distances = np.linalg.norm(positions[:, :, None] - positions[:, None, :], axis=3)
        distances[:, np.arange(self.n_labels), np.arange(self.n_labels)] = np.inf
        distances = np.where(np.isfinite(distances), distances, np.inf)
        nearest = distances.argmin(axis=2)
        near = np.take_along_axis(distances, nearest[:, :, None], axis=2)[:, :, 0] < self.settings.swap_close_mm
        result[frames] = np.where(flags[frames] & near, nearest, -1)
        return result

    def _frames_text(self, start: int, stop: int) -> str:
        first, last = self.frame_number(start), self.frame_number(stop - 1)
        return f"{first}" if first == last else f"{first}-{last}"

    # --- following points ---------------------------------------------------------------------------

    def follow_point(self, frame: int, column: int, first: int = 0, stop: int | None = None) -> np.ndarray:
        """Point column per frame ``(F,)`` (-1 outside) of the unlabelled point at (``frame``, ``column``),
        followed forwards and backwards within ``first .. stop - 1``.

        The point continues in the same column when that column is finite within ``follow_gate_mm`` of
        it in the next frame (fragmented exports keep a trajectory in one column); otherwise in the
        nearest point within the gate, provided no other point is within the gate too (per-frame
        shuffled exports). The chain stops at the first frame where neither holds.
        """
        stop = self.n_frames if stop is None else stop
        self.check_point(frame, column)
        chain = np.full(self.n_frames, -1, dtype=np.int64)
        chain[frame] = column
        points = self.take.marker_positions
        gate = self.settings.follow_gate_mm
        for step, end in ((1, stop), (-1, first - 1)):
            current, position = column, points[frame, column]
            previous_position = position
            for other_frame in range(frame + step, end, step):
                candidates = points[other_frame]
                predicted = position + (position - previous_position)
                same = candidates[current]
                if np.isfinite(same).all() and np.linalg.norm(same - predicted) <= gate:
                    chosen = current
                else:
                    distances = np.linalg.norm(candidates - predicted, axis=1)
                    distances = np.where(np.isfinite(distances), distances, np.inf)
                    order = np.argsort(distances)
                    if distances[order[0]] > gate or (len(order) > 1 and distances[order[1]] <= gate):
                        break
                    chosen = int(order[0])
                chain[other_frame] = chosen
                previous_position, position, current = position, candidates[chosen], chosen
        return chain

    def check_point(self, frame: int, column: int) -> None:
        """InputError unless raw point ``column`` exists (is measured) at ``frame``."""
        self.check_frame(frame)
        if not 0 <= column < self.n_points:
            raise InputError(f"point column {column} is outside 0..{self.n_points - 1}")
        if not np.isfinite(self.take.marker_positions[frame, column]).all():
            raise InputError(f"there is no point in column {column} at frame {self.frame_number(frame)}")

    def check_frame(self, frame: int) -> None:
        """InputError unless ``0 <= frame < F``."""
        if not 0 <= frame < self.n_frames:
            raise InputError(f"frame {frame} is outside the take (0..{self.n_frames - 1})")

    def check_range(self, start: int, stop: int) -> tuple[int, int]:
        """``(start, stop)`` clipped to the take; InputError when empty or reversed."""
        start, stop = max(0, int(start)), min(self.n_frames, int(stop))
        if stop <= start:
            raise InputError(f"empty frame range {start}..{stop - 1}")
        return start, stop

    # --- capture / restore (undo) -------------------------------------------------------------------

    def capture(self, start: int, stop: int, whole: bool = False) -> dict[str, Any]:
        """Copies of everything a command may change over frames ``start .. stop - 1``: the arrays of
        ``FRAME_ARRAYS`` and each hand's joint angles (``hand<i>``). With ``whole``: the whole state,
        label names and hands included (for commands that change the labels themselves)."""
        if whole:
            return {"whole": True, "label_names": list(self.label_names), "hands": [h.copy() for h in self.hands],
                    "rigid_bodies": copy_rigid_bodies(self.rigid_bodies), "health": copy_health(self.health),
                    "noise_mm": self.noise_mm, **{name: getattr(self, name).copy() for name in FRAME_ARRAYS}}
        saved: dict[str, Any] = {name: getattr(self, name)[start:stop].copy() for name in FRAME_ARRAYS}
        saved.update({f"hand{index}": hand.joint_angles[start:stop].copy() for index, hand in enumerate(self.hands)})
        return saved

    def compact(self, start: int, stop: int, saved: dict[str, Any]) -> dict[str, Any]:
        """``saved`` (from :meth:`capture` before a change) reduced to the entries the change touched:
        ``<name>.index`` (flat indices within frames ``start .. stop - 1``) and ``<name>.values`` (the old
        values). :meth:`restore` accepts both forms; whole captures are returned as they are."""
        if saved.get("whole"):
            return saved
        compacted: dict[str, Any] = {}
        for key, old in saved.items():
            new = self._saved_target(key)[start:stop]
            same = old == new
            if old.dtype.kind == "f":
                same |= np.isnan(old) & np.isnan(new)
            changed = np.flatnonzero(~same.reshape(-1))
            if changed.size:
                compacted[f"{key}.index"] = changed
                compacted[f"{key}.values"] = old.reshape(-1)[changed]
        return compacted

    def restore(self, start: int, stop: int, saved: dict[str, Any]) -> None:
        """Put back what :meth:`capture` (or :meth:`compact`) returned, exactly."""
        if saved.get("whole"):
            self.label_names = list(saved["label_names"])
            self.hands = [hand.copy() for hand in saved["hands"]]
            self.rigid_bodies = copy_rigid_bodies(saved.get("rigid_bodies", {}))
            self.health = copy_health(saved.get("health", []))
            self.noise_mm = saved.get("noise_mm")
            for name in FRAME_ARRAYS:
                setattr(self, name, saved[name].copy())
        else:
            for key, values in saved.items():
                if key.endswith(".values"):
                    continue
                if key.endswith(".index"):
                    name = key[:-len(".index")]
                    block = self._saved_target(name)[start:stop]
                    block[np.unravel_index(values, block.shape)] = saved[f"{name}.values"]
                else:
                    self._saved_target(key)[start:stop] = values
        self.changed()

    def _saved_target(self, key: str) -> np.ndarray:
        """The array a captured entry belongs to (``hand<i>`` is a hand's joint angles)."""
        if key.startswith("hand"):
            return self.hands[int(key[4:])].joint_angles
        return getattr(self, key)

    def state_arrays(self) -> dict[str, np.ndarray]:
        """Every array of the state (for snapshots and comparisons), hands' joint angles as ``hand{i}``."""
        arrays = {name: getattr(self, name) for name in FRAME_ARRAYS}
        arrays.update({f"hand{index}": hand.joint_angles for index, hand in enumerate(self.hands)})
        return arrays

    def same_state(self, other: ReviewTake) -> bool:
        """True when labels, hands and every array equal ``other``'s exactly (NaN equal to NaN)."""
        if (self.label_names != other.label_names or self.rigid_bodies != other.rigid_bodies
                or self.health != other.health or self.noise_mm != other.noise_mm
                or [h.meta() for h in self.hands] != [h.meta() for h in other.hands]):
            return False
        mine, theirs = self.state_arrays(), other.state_arrays()
        return mine.keys() == theirs.keys() and all(
            mine[key].shape == theirs[key].shape
            and np.array_equal(mine[key], theirs[key], equal_nan=mine[key].dtype.kind == "f") for key in mine)

    def copy(self) -> ReviewTake:
        """An independent copy of the review (the raw take is shared: it is never changed), e.g. for a worker
        to run commands on while the original stays shown."""
        return ReviewTake(take=self.take, label_names=list(self.label_names), assignment=self.assignment,
                          provenance=self.provenance, edited=self.edited, filled_positions=self.filled_positions,
                          confidence=self.confidence, residuals_mm=self.residuals_mm, ghost=self.ghost,
                          hands=[hand.copy() for hand in self.hands], rigid_bodies=self.rigid_bodies,
                          health=list(self.health), noise_mm=self.noise_mm, settings=self.settings,
                          events=list(self.events or []), trim=self.trim)

    # --- events and trim ----------------------------------------------------------------------------

    def event_frames(self) -> list[tuple[int, TakeEvent]]:
        """``(0-based frame, event)`` of every event inside the take, by frame."""
        return [(event.frame_number - self.take.first_frame, event) for event in self.events or []
                if 0 <= event.frame_number - self.take.first_frame < self.n_frames]

    def next_event(self, frame: int, forward: bool = True) -> tuple[int, TakeEvent] | None:
        """The first event after 0-based ``frame`` (before it when not ``forward``), wrapping around; None
        when the take has none."""
        events = self.event_frames()
        if not events:
            return None
        if forward:
            return next((entry for entry in events if entry[0] > frame), events[0])
        return next((entry for entry in reversed(events) if entry[0] < frame), events[-1])

    def frame_range(self) -> tuple[int, int]:
        """The frames ``start, stop`` (0-based, stop exclusive) the take is trimmed to; the whole take when
        it is not trimmed."""
        return self.trim if self.trim is not None else (0, self.n_frames)

    def trimmed(self) -> ReviewTake:
        """The review of the trimmed take (itself when not trimmed): every array over the trim range, the raw
        take's frames too, numbered as in the file (its first frame is the range's first), the events inside
        the range. What every export writes."""
        if self.trim is None:
            return self
        start, stop = self.trim
        take = self.take
        part = Take(marker_names=list(take.marker_names), marker_positions=take.marker_positions[start:stop],
                    frame_rate=take.frame_rate, first_frame=take.first_frame + start, vendor=take.vendor,
                    source_units=take.source_units, source_path=take.source_path, parameters=take.parameters)
        first, last = take.first_frame + start, take.first_frame + stop - 1
        hands = [HandTrack(hand.name, hand.side, hand.layout, hand.labels, hand.joint_angles[start:stop])
                 for hand in self.hands]
        return ReviewTake(take=part, label_names=list(self.label_names), assignment=self.assignment[start:stop],
                          provenance=self.provenance[start:stop], edited=self.edited[start:stop],
                          filled_positions=self.filled_positions[start:stop],
                          confidence=self.confidence[start:stop], residuals_mm=self.residuals_mm[start:stop],
                          ghost=self.ghost[start:stop], hands=hands, rigid_bodies=self.rigid_bodies,
                          health=[], noise_mm=self.noise_mm, settings=self.settings,
                          events=[event for event in self.events or [] if first <= event.frame_number <= last])

    def timeline_state(self) -> dict[str, Any]:
        """The events and the trim range as plain JSON (what the event and trim commands change)."""
        return {"events": [event.as_dict() for event in self.events or []],
                "trim": None if self.trim is None else list(self.trim)}

    def set_timeline_state(self, state: dict[str, Any]) -> None:
        """Put back what :meth:`timeline_state` returned."""
        self.events = sorted((TakeEvent.from_dict(item) for item in state.get("events", [])),
                             key=lambda event: (event.frame_number, event.name))
        trim = state.get("trim")
        self.trim = None if trim is None else (int(trim[0]), int(trim[1]))

    # --- change tracking ----------------------------------------------------------------------------

    def changed(self) -> None:
        """Drop the cached views after a change (called by the commands)."""
        self.version += 1
        self._cache.clear()

    def _cached(self, key: str) -> Any:
        entry = self._cache.get(key)
        return entry[1] if entry is not None and entry[0] == self.version else None

    def _store(self, key: str, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
        self._cache[key] = (self.version, value)
        return value


def _norms(vectors: np.ndarray) -> np.ndarray:
    """Euclidean norms over the last axis (NaN where a component is)."""
    return np.sqrt(np.einsum("...i,...i->...", vectors, vectors))


def _array(values: Any, dtype: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``values`` as a C-contiguous copy of ``dtype`` and ``shape``; InputError otherwise."""
    try:
        array = np.array(values, dtype=dtype, copy=True)
    except (TypeError, ValueError) as error:
        raise InputError(f"{what}: not an array of numbers ({error})") from None
    if array.shape != shape:
        raise InputError(f"{what} must have shape {shape}, got {array.shape}")
    return np.ascontiguousarray(array)


def _optional(values: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    return np.full(shape, np.nan) if values is None else _array(values, np.float64, shape, what)


def frame_text(first_frame: int, start: int, stop: int) -> str:
    """File frame numbers of ``start .. stop - 1`` as "a-b" (or "a")."""
    first, last = first_frame + start, first_frame + stop - 1
    return f"{first}" if first == last else f"{first}-{last}"
