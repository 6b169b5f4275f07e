"""Undoable edits of a :class:`~core.review.take.ReviewTake` and the undo stack.

Every change of a review goes through a :class:`Command`: ``do(review)`` applies it and returns the
:class:`FrameSpan` it touched (so the GUI re-solves exactly those frames), ``undo(review)`` puts
back the exact previous arrays (captured by ``do``), ``text`` describes it for the Edit menu, and
``to_json()`` / :func:`command_from_json` turn it into plain JSON for the journal (large arrays go
to a :class:`BlobStore` when one is given). Commands hold their parameters, not the state: ``do``
resolves them against the review (e.g. which point the label follows from frame to frame), so a
replay on the same state gives the same result.

Selecting points. Point commands name a point by ``frame`` and raw ``column`` (what the operator
clicked), or a whole label by ``label`` name, plus a ``scope``:

* the *track* of a labelled point is its label: the label's point in every frame (the column may
  change from frame to frame, as after per-frame labelling);
* the *track* of an unlabelled point is the chain of points followed from the clicked one
  (:meth:`ReviewTake.follow_point`): the same column while it continues smoothly, else the unique
  nearest point within ``follow_gate_mm``;
* ``scope="fragment"``: from the clicked frame forwards to the end of the track's contiguous run
  (the last frame before the label is missing, or the chain ends) — Nexus' "from here to the end of
  this fragment"; ``scope="range"``: the track's frames within ``start .. stop - 1``;
  ``scope="take"``: every frame of the track.

Undo restores every array the command changed — the solved joint angles and residuals included —
so a re-solve is needed after :meth:`UndoStack.push` only; attach its :class:`SetSolve` with
:meth:`UndoStack.attach` and it is undone and redone with the edit. Frames are 0-based; ``stop`` is
exclusive.
"""

from __future__ import annotations

import base64
import json
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.gaps.methods import fill_method
from handmocap.core.model.provenance import MEASURED, MISSING
from handmocap.core.review.events import EMPTY_SPAN, Change, FrameSpan, ReviewChanged
from handmocap.core.review.take import (
    ReviewTake,
    copy_health,
    copy_rigid_bodies,
    frame_text,
)

SCOPES = ("fragment", "range", "take")
INLINE_ARRAY_LIMIT = 4096  # arrays with more elements go to the blob store when there is one


class BlobStore(Protocol):
    """Where a journal keeps arrays too large for a JSON line."""

    def put(self, array: np.ndarray) -> str: ...

    def get(self, key: str) -> np.ndarray: ...


def encode_array(array: np.ndarray, blobs: BlobStore | None = None) -> dict[str, Any]:
    """JSON form of an array: inline base64 of the exact bytes, or a blob key for large arrays."""
    array = np.ascontiguousarray(array)
    if blobs is not None and array.size > INLINE_ARRAY_LIMIT:
        return {"blob": blobs.put(array)}
    return {"dtype": array.dtype.str, "shape": list(array.shape), "data": base64.b64encode(array.tobytes()).decode()}


def decode_array(data: dict[str, Any], blobs: BlobStore | None = None) -> np.ndarray:
    """Inverse of :func:`encode_array`; InputError when the blob is unavailable or the data malformed."""
    try:
        if "blob" in data:
            if blobs is None:
                raise InputError("an edit refers to stored data but no store was given")
            return blobs.get(str(data["blob"]))
        raw = base64.b64decode(data["data"])
        return np.frombuffer(raw, dtype=np.dtype(data["dtype"])).reshape(data["shape"]).copy()
    except (KeyError, TypeError, ValueError) as error:
        raise InputError(f"malformed array in an edit record ({error})") from None


class Command(ABC):
    """Base of every undoable edit. Subclasses set ``kind``, implement :meth:`_extent`, :meth:`_apply`,
    :meth:`params` and (for arrays) :meth:`_from_params`; ``whole = True`` captures the whole state;
    ``changes`` says what kind of data it changes (what its :class:`ReviewChanged` event announces)."""

    kind: ClassVar[str] = ""
    whole: ClassVar[bool] = False
    changes: ClassVar[Change] = Change.ALL
    registry: ClassVar[dict[str, type[Command]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.kind:
            Command.registry[cls.kind] = cls

    def __init__(self) -> None:
        self._span: FrameSpan | None = None
        self._saved: dict[str, Any] | None = None
        self._text = ""

    # -- to implement --
    @abstractmethod
    def _extent(self, review: ReviewTake) -> FrameSpan:
        """Validate against ``review`` and return the frames ``_apply`` will change (InputError if invalid)."""

    @abstractmethod
    def _apply(self, review: ReviewTake) -> None:
        """Change ``review`` (the frames :meth:`_extent` returned)."""

    @abstractmethod
    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        """JSON-serialisable parameters (arrays through :func:`encode_array`)."""

    @classmethod
    def _from_params(cls, params: dict[str, Any], blobs: BlobStore | None) -> Command:
        return cls(**params)

    def describe(self, review: ReviewTake) -> str:
        """One line for the Edit menu (computed when the command is done)."""
        return self.kind.replace("_", " ")

    # -- common --
    @property
    def text(self) -> str:
        """Description shown as "Undo <text>" (known after :meth:`do`)."""
        return self._text or self.kind.replace("_", " ")

    @property
    def span(self) -> FrameSpan:
        """Frames changed by the last :meth:`do` (empty before)."""
        return self._span or EMPTY_SPAN

    def do(self, review: ReviewTake) -> FrameSpan:
        """Apply to ``review``; returns the changed frames. On InputError nothing is changed."""
        span = self._extent(review)
        self._text = self.describe(review)
        saved = review.capture(span.start, span.stop, whole=self.whole)
        try:
            self._apply(review)
        except BaseException:
            review.restore(span.start, span.stop, saved)
            raise
        review.changed()
        self._span, self._saved = span, review.compact(span.start, span.stop, saved)
        return span

    def undo(self, review: ReviewTake) -> FrameSpan:
        """Put back exactly what :meth:`do` changed; returns the frames."""
        if self._saved is None or self._span is None:
            raise InputError(f"cannot undo '{self.text}': it was not done")
        review.restore(self._span.start, self._span.stop, self._saved)
        span = self._span
        self._saved = None
        return span

    def to_json(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        """``{"type": kind, **params}``: plain JSON (large arrays in ``blobs`` when given)."""
        return {"type": self.kind, **self.params(blobs)}

    def saved_state(self) -> tuple[FrameSpan, dict[str, Any]] | None:
        """What :meth:`undo` restores (for persisting the undo history), or None when not done."""
        if self._saved is None or self._span is None:
            return None
        return self._span, self._saved

    def set_saved_state(self, span: FrameSpan, saved: dict[str, Any], text: str) -> None:
        """Make a command read from a snapshot undoable (inverse of :meth:`saved_state`)."""
        self._span, self._saved, self._text = FrameSpan(*span), saved, text


def command_from_json(data: dict[str, Any], blobs: BlobStore | None = None) -> Command:
    """The command described by ``data`` (from :meth:`Command.to_json`); InputError when unknown."""
    if not isinstance(data, dict) or "type" not in data:
        raise InputError("malformed edit record (no 'type')")
    kind = str(data["type"])
    cls = Command.registry.get(kind)
    if cls is None:
        raise InputError(f"unknown edit type '{kind}'")
    params = {key: value for key, value in data.items() if key != "type"}
    try:
        return cls._from_params(params, blobs)
    except TypeError as error:
        raise InputError(f"malformed '{kind}' edit record ({error})") from None


# --------------------------------------------------------------------------------------------------
# Point selection


@dataclass(frozen=True)
class Track:
    """Resolved selection: the point column per frame ``(F,)`` (-1 where not selected) and the label
    that owned the selection (-1 for an unlabelled point)."""

    columns: np.ndarray
    label: int

    @property
    def frames(self) -> np.ndarray:
        return np.flatnonzero(self.columns >= 0)


def resolve_track(review: ReviewTake, frame: int | None, column: int | None, label: str | None,
                  scope: str, start: int | None, stop: int | None) -> Track:
    """The points a point command acts on (module docstring); InputError when nothing is selected."""
    if scope not in SCOPES:
        raise InputError(f"unknown scope '{scope}' (use {', '.join(SCOPES)})")
    if scope == "range":
        if start is None or stop is None:
            raise InputError("a range edit needs a first and a last frame")
        first, end = review.check_range(start, stop)
    else:
        first, end = 0, review.n_frames
    if label is not None:
        owner = review.label_index(label)
        if frame is None:
            frame = first
        review.check_frame(frame)
    else:
        if frame is None or column is None:
            raise InputError("select a point (frame and column) or a label")
        review.check_point(frame, column)
        owner = review.label_of_point(frame, column)
    columns = np.full(review.n_frames, -1, dtype=np.int64)
    if owner >= 0:
        columns[first:end] = review.assignment[first:end, owner]
        if scope == "fragment":
            if columns[frame] < 0:
                raise InputError(f"label '{review.label_names[owner]}' has no point at frame "
                                 f"{review.frame_number(frame)}")
            missing = np.flatnonzero(columns[frame:] < 0)
            fragment_end = frame + (int(missing[0]) if missing.size else review.n_frames - frame)
            columns[:frame] = -1
            columns[fragment_end:] = -1
    else:
        assert column is not None, "owner < 0 only for a selected unlabelled point"
        chain = review.follow_point(frame, column, first, end)
        if scope == "fragment":
            chain[:frame] = -1
        columns = chain
    if not (columns >= 0).any():
        raise InputError("no point is selected in that range")
    return Track(columns, owner)


def _int_or_none(value: Any) -> int | None:
    return None if value is None else int(value)


def _point_params(frame: int | None, column: int | None, label: str | None, scope: str, start: int | None,
                  stop: int | None) -> dict[str, Any]:
    return {"frame": frame, "column": column, "label": label, "scope": scope, "start": start, "stop": stop}


def _clear_label(review: ReviewTake, frames: np.ndarray, label: int) -> None:
    """Label ``label`` loses its point (and any fill) at ``frames``; marked edited."""
    review.assignment[frames, label] = -1
    review.provenance[frames, label] = MISSING
    review.filled_positions[frames, label] = np.nan
    review.confidence[frames, label] = np.nan
    review.residuals_mm[frames, label] = np.nan
    review.edited[frames, label] = True


def _release_points(review: ReviewTake, frames: np.ndarray, columns: np.ndarray, keep: int = -1) -> None:
    """Whatever label (other than ``keep``) takes point ``columns[i]`` at ``frames[i]`` loses it."""
    if not frames.size:
        return
    owners = review.assignment[frames] == columns[:, None]  # (n, M)
    if keep >= 0:
        owners[:, keep] = False
    rows, labels = np.nonzero(owners)
    for label in np.unique(labels):
        _clear_label(review, frames[rows[labels == label]], int(label))


class _PointCommand(Command):
    """A command on the points selected by (frame, column) or label, and a scope."""

    changes = Change.LABELS | Change.FILLS | Change.SOLVE   # a label losing its point loses its fill and residual

    def __init__(self, frame: int | None = None, column: int | None = None, *, label: str | None = None,
                 scope: str = "fragment", start: int | None = None, stop: int | None = None) -> None:
        super().__init__()
        self.frame, self.column, self.label = _int_or_none(frame), _int_or_none(column), label
        self.scope, self.start, self.stop = str(scope), _int_or_none(start), _int_or_none(stop)
        self._track: Track | None = None

    def _extent(self, review: ReviewTake) -> FrameSpan:
        self._track = resolve_track(review, self.frame, self.column, self.label, self.scope, self.start, self.stop)
        frames = self._track.frames
        return FrameSpan(int(frames[0]), int(frames[-1]) + 1)

    def _selection_text(self, review: ReviewTake) -> str:
        assert self._track is not None
        frames = self._track.frames
        owner = (f"'{review.label_names[self._track.label]}'" if self._track.label >= 0
                 else f"point {self.column}")
        return f"{owner} at frames {frame_text(review.take.first_frame, int(frames[0]), int(frames[-1]) + 1)}"

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return _point_params(self.frame, self.column, self.label, self.scope, self.start, self.stop)


class AssignLabel(_PointCommand):
    """Give label ``new_label`` to the selected points (assign, or change a label).

    At each selected frame the point's previous label loses it, and the point ``new_label`` had there
    (if another) becomes unlabelled; a fill of ``new_label`` there is dropped (a measured point wins).
    """

    kind = "assign_label"

    def __init__(self, frame: int | None = None, column: int | None = None, new_label: str = "", *,
                 label: str | None = None, scope: str = "fragment", start: int | None = None,
                 stop: int | None = None) -> None:
        super().__init__(frame, column, label=label, scope=scope, start=start, stop=stop)
        self.new_label = str(new_label)

    def _extent(self, review: ReviewTake) -> FrameSpan:
        self._target = review.label_index(self.new_label)
        return super()._extent(review)

    def describe(self, review: ReviewTake) -> str:
        return f"label {self._selection_text(review)} as '{review.label_names[self._target]}'"

    def _apply(self, review: ReviewTake) -> None:
        assert self._track is not None
        target = self._target
        frames = self._track.frames
        columns = self._track.columns[frames]
        change = review.assignment[frames, target] != columns
        frames, columns = frames[change], columns[change]
        _release_points(review, frames, columns, keep=-1)
        _clear_label(review, frames, target)
        review.assignment[frames, target] = columns
        review.provenance[frames, target] = MEASURED
        review.ghost[frames, columns] = False

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {**super().params(blobs), "new_label": self.new_label}


class Unlabel(_PointCommand):
    """Remove the label of the selected points (they stay as unlabelled points, not ghosts)."""

    kind = "unlabel"
    mark_ghost = False

    def describe(self, review: ReviewTake) -> str:
        return f"{'mark ghost' if self.mark_ghost else 'unlabel'} {self._selection_text(review)}"

    def _apply(self, review: ReviewTake) -> None:
        assert self._track is not None
        frames = self._track.frames
        columns = self._track.columns[frames]
        _release_points(review, frames, columns)
        review.ghost[frames, columns] = self.mark_ghost


class MarkGhost(Unlabel):
    """Mark the selected points as ghosts (spurious reflections): unlabelled and flagged."""

    kind = "mark_ghost"
    mark_ghost = True


class SwapLabels(Command):
    """Exchange two labels over frames ``start .. stop - 1``: points, fills, confidence, residuals."""

    kind = "swap_labels"
    changes = Change.LABELS | Change.FILLS | Change.SOLVE

    def __init__(self, first_label: str, second_label: str, start: int, stop: int) -> None:
        super().__init__()
        self.first_label, self.second_label = str(first_label), str(second_label)
        self.start, self.stop = int(start), int(stop)

    def _extent(self, review: ReviewTake) -> FrameSpan:
        self._pair = (review.label_index(self.first_label), review.label_index(self.second_label))
        if self._pair[0] == self._pair[1]:
            raise InputError("choose two different labels to swap")
        return FrameSpan(*review.check_range(self.start, self.stop))

    def describe(self, review: ReviewTake) -> str:
        a, b = self._pair
        start, stop = review.check_range(self.start, self.stop)
        return (f"swap '{review.label_names[a]}' and '{review.label_names[b]}' at frames "
                f"{frame_text(review.take.first_frame, start, stop)}")

    def _apply(self, review: ReviewTake) -> None:
        a, b = self._pair
        start, stop = review.check_range(self.start, self.stop)
        for name in ("assignment", "provenance", "filled_positions", "confidence", "residuals_mm"):
            array = getattr(review, name)
            array[start:stop, [a, b]] = array[start:stop, [b, a]]
        had = (review.provenance[start:stop, [a, b]] != MISSING).any(axis=1)
        review.edited[start:stop, a] |= had
        review.edited[start:stop, b] |= had

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"first_label": self.first_label, "second_label": self.second_label,
                "start": self.start, "stop": self.stop}


@dataclass(frozen=True)
class GapFill:
    """A fill to accept: label ``label`` at frames ``start .. start + len(positions) - 1`` by ``method``
    (``linear``, ``spline``, ``pattern``, ``rigid``, ``model`` or ``pca``), ``positions (n, 3)`` mm."""

    label: str
    start: int
    method: str
    positions: np.ndarray

    @property
    def stop(self) -> int:
        return self.start + len(self.positions)


class AcceptFills(Command):
    """Accept one or more gap fills at once ("fill all short gaps" is one undo step).

    Only frames where the label has no measured point are filled; a fill may replace an earlier fill.
    """

    kind = "accept_fills"
    changes = Change.FILLS

    def __init__(self, fills: list[GapFill]) -> None:
        super().__init__()
        self.fills = [GapFill(str(fill.label), int(fill.start), str(fill.method), fill.positions) for fill in fills]

    def _extent(self, review: ReviewTake) -> FrameSpan:
        if not self.fills:
            raise InputError("no fill to accept")
        span = EMPTY_SPAN
        self._resolved = []
        for fill in self.fills:
            label = review.label_index(fill.label)
            code = fill_method(fill.method).code
            positions = np.asarray(fill.positions, dtype=np.float64)
            if positions.ndim != 2 or positions.shape[1] != 3 or not len(positions):
                raise InputError(f"fill of '{fill.label}': positions must be (n, 3), got {positions.shape}")
            if not np.isfinite(positions).all():
                raise InputError(f"fill of '{fill.label}' holds missing or infinite positions")
            start, stop = fill.start, fill.start + len(positions)
            if start < 0 or stop > review.n_frames:
                raise InputError(f"fill of '{fill.label}' (frames {start}..{stop - 1}) is outside the take")
            if (review.assignment[start:stop, label] >= 0).any():
                raise InputError(f"'{fill.label}' has measured points in frames "
                                 f"{frame_text(review.take.first_frame, start, stop)}; fill only its gaps")
            self._resolved.append((label, start, stop, code, positions))
            span = span.union(FrameSpan(start, stop))
        return span

    def describe(self, review: ReviewTake) -> str:
        if len(self.fills) == 1:
            fill = self.fills[0]
            return (f"{fill.method} fill of '{fill.label}' at frames "
                    f"{frame_text(review.take.first_frame, fill.start, fill.stop)}")
        return f"fill {len(self.fills)} gaps"

    def _apply(self, review: ReviewTake) -> None:
        for label, start, stop, code, positions in self._resolved:
            review.filled_positions[start:stop, label] = positions
            review.provenance[start:stop, label] = code

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"fills": [{"label": fill.label, "start": fill.start, "method": fill.method,
                           "positions": encode_array(np.asarray(fill.positions, dtype=np.float64), blobs)}
                          for fill in self.fills]}

    @classmethod
    def _from_params(cls, params: dict[str, Any], blobs: BlobStore | None) -> Command:
        try:
            fills = [GapFill(str(item["label"]), int(item["start"]), str(item["method"]),
                             decode_array(item["positions"], blobs)) for item in params["fills"]]
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(f"malformed fill record ({error})") from None
        return cls(fills)


class RejectFills(Command):
    """Remove accepted fills of ``label`` (None: every label) over frames ``start .. stop - 1``."""

    kind = "reject_fills"
    changes = Change.FILLS

    def __init__(self, label: str | None, start: int, stop: int) -> None:
        super().__init__()
        self.label, self.start, self.stop = None if label is None else str(label), int(start), int(stop)

    def _extent(self, review: ReviewTake) -> FrameSpan:
        self._labels = (np.arange(review.n_labels) if self.label is None
                        else np.array([review.label_index(self.label)]))
        start, stop = review.check_range(self.start, self.stop)
        if not (review.provenance[start:stop][:, self._labels] > 0).any():
            raise InputError("there is no accepted fill there")
        return FrameSpan(start, stop)

    def describe(self, review: ReviewTake) -> str:
        who = "all labels" if self.label is None else f"'{review.label_names[self._labels[0]]}'"
        start, stop = review.check_range(self.start, self.stop)
        return f"reject fills of {who} at frames {frame_text(review.take.first_frame, start, stop)}"

    def _apply(self, review: ReviewTake) -> None:
        start, stop = review.check_range(self.start, self.stop)
        block = review.provenance[start:stop]
        for label in self._labels:
            filled = np.flatnonzero(block[:, label] > 0) + start
            review.provenance[filled, label] = MISSING
            review.filled_positions[filled, label] = np.nan

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"label": self.label, "start": self.start, "stop": self.stop}


class SetSolve(Command):
    """A solver result for hand ``hand`` (index in ``review.hands``) over frames ``start ..``:
    ``joint_angles (n, 26)`` and optionally ``residuals_mm (n, K)`` of the hand's labels (layout order).
    Usually attached to the edit that caused the re-solve (:meth:`UndoStack.attach`)."""

    kind = "set_solve"
    changes = Change.SOLVE

    def __init__(self, hand: int, start: int, joint_angles: np.ndarray, residuals_mm: np.ndarray | None = None,
                 ) -> None:
        super().__init__()
        self.hand, self.start = int(hand), int(start)
        self.joint_angles = np.asarray(joint_angles, dtype=np.float64)
        self.residuals = None if residuals_mm is None else np.asarray(residuals_mm, dtype=np.float64)

    def _extent(self, review: ReviewTake) -> FrameSpan:
        if not 0 <= self.hand < len(review.hands):
            raise InputError(f"no hand {self.hand} in this take ({len(review.hands)} solved)")
        hand = review.hands[self.hand]
        count = len(self.joint_angles)
        if self.joint_angles.ndim != 2 or self.joint_angles.shape[1] != 26 or count == 0:
            raise InputError(f"joint angles must be (n, 26), got {self.joint_angles.shape}")
        if self.start < 0 or self.start + count > review.n_frames:
            raise InputError(f"solve of frames {self.start}..{self.start + count - 1} is outside the take")
        if self.residuals is not None and self.residuals.shape != (count, len(hand.labels)):
            raise InputError(f"residuals must be ({count}, {len(hand.labels)}), got {self.residuals.shape}")
        return FrameSpan(self.start, self.start + count)

    def describe(self, review: ReviewTake) -> str:
        return (f"solve of the {review.hands[self.hand].name} hand at frames "
                f"{frame_text(review.take.first_frame, self.start, self.start + len(self.joint_angles))}")

    def _apply(self, review: ReviewTake) -> None:
        hand = review.hands[self.hand]
        stop = self.start + len(self.joint_angles)
        hand.joint_angles[self.start:stop] = self.joint_angles
        if self.residuals is not None:
            measured = review.assignment[self.start:stop][:, hand.labels] >= 0
            review.residuals_mm[self.start:stop, hand.labels] = np.where(measured, self.residuals, np.nan)

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"hand": self.hand, "start": self.start, "joint_angles": encode_array(self.joint_angles, blobs),
                "residuals_mm": None if self.residuals is None else encode_array(self.residuals, blobs)}

    @classmethod
    def _from_params(cls, params: dict[str, Any], blobs: BlobStore | None) -> Command:
        residuals = params.get("residuals_mm")
        return cls(int(params["hand"]), int(params["start"]), decode_array(params["joint_angles"], blobs),
                   None if residuals is None else decode_array(residuals, blobs))


@dataclass
class LabellingArrays:
    """A labelling result as plain arrays (what :class:`ApplyLabelling` stores): see
    :meth:`ReviewTake.from_labelling`. ``hands``: :class:`~core.review.take.HandTrack` list;
    ``rigid_bodies``: ``{object name: [label index]}``; ``health``: the labelling's warnings
    (:class:`~core.labelling.health.HealthWarning`); ``noise_mm``: its noise estimate (mm, None unknown)."""

    marker_names: list[str]
    assignment: np.ndarray
    confidence: np.ndarray
    residuals_mm: np.ndarray
    ghost_points: np.ndarray
    hands: list
    filled_positions: np.ndarray | None = None
    provenance: np.ndarray | None = None
    rigid_bodies: dict[str, list[int]] = field(default_factory=dict)
    health: list = field(default_factory=list)
    noise_mm: float | None = None


class ApplyLabelling(Command):
    """Replace the whole labelling by a result (auto-label is undoable like any edit).

    ``result``: anything :meth:`ReviewTake.from_labelling` accepts (e.g. ``core.labelling.SceneLabelling``);
    ``hands``/``side``/``layout`` as there. Edit flags are cleared; undo brings back the previous
    labels, fills, edits and solves exactly.
    """

    kind = "apply_labelling"
    whole = True

    def __init__(self, result: Any, hands: list | None = None, side: str = "right", layout: str | None = None,
                 description: str = "auto-label") -> None:
        super().__init__()
        self.result, self.hands, self.side, self.layout = result, hands, side, layout
        self.description = description
        if isinstance(result, LabellingArrays):
            self._applied = result

    def _extent(self, review: ReviewTake) -> FrameSpan:
        frames = np.shape(self.result.assignment)[0]
        if frames != review.n_frames:
            raise InputError(f"the labelling result has {frames} frames, the take {review.n_frames}")
        return FrameSpan(0, review.n_frames)

    def describe(self, review: ReviewTake) -> str:
        return self.description

    def _apply(self, review: ReviewTake) -> None:
        review.replace_with_labelling(self.result, self.hands, self.side, self.layout)
        # keep the applied state (hands resolved) so that to_json describes exactly what was applied
        self._applied = LabellingArrays(list(review.label_names), review.assignment.copy(), review.confidence.copy(),
                                        review.residuals_mm.copy(), review.ghost.copy(),
                                        [hand.copy() for hand in review.hands],
                                        review.filled_positions.copy(), review.provenance.copy(),
                                        copy_rigid_bodies(review.rigid_bodies), copy_health(review.health),
                                        review.noise_mm)

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        applied = getattr(self, "_applied", None)
        if applied is None:
            raise InputError("a labelling is recorded once it has been applied")
        return {"description": self.description, "marker_names": applied.marker_names,
                "hands": [hand.meta() | {"joint_angles": encode_array(hand.joint_angles, blobs)}
                          for hand in applied.hands],
                "rigid_bodies": applied.rigid_bodies,
                "health": [warning.as_dict() for warning in copy_health(applied.health)], "noise_mm": applied.noise_mm,
                **{name: None if getattr(applied, name) is None else encode_array(getattr(applied, name), blobs)
                   for name in ("assignment", "confidence", "residuals_mm", "ghost_points", "filled_positions",
                                "provenance")}}

    @classmethod
    def _from_params(cls, params: dict[str, Any], blobs: BlobStore | None) -> Command:
        from handmocap.core.review.take import HandTrack

        try:
            hands = [HandTrack(str(h["name"]), str(h["side"]), h.get("layout"), np.asarray(h["labels"], np.int64),
                               decode_array(h["joint_angles"], blobs)) for h in params["hands"]]
            marker_names = [str(name) for name in params["marker_names"]]
            assignment, confidence, residuals, ghosts = (decode_array(params[name], blobs) for name in (
                "assignment", "confidence", "residuals_mm", "ghost_points"))
            filled, provenance = (None if params.get(name) is None else decode_array(params[name], blobs)
                                  for name in ("filled_positions", "provenance"))
            arrays = LabellingArrays(
                marker_names, assignment, confidence, residuals, ghosts, hands, filled, provenance,
                copy_rigid_bodies(params.get("rigid_bodies", {})), copy_health(params.get("health", [])),
                None if params.get("noise_mm") is None else float(params["noise_mm"]))
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(f"malformed labelling record ({error})") from None
        return cls(arrays, hands=hands, description=str(params.get("description", "auto-label")))


def replaced_hand(hands: list, name: str, labels: np.ndarray) -> int | None:
    """Index of the hand :class:`DefineHand` replaces among ``hands``: the one named ``name``, else the one
    holding exactly the label indices ``labels (K,)``; None when it adds one."""
    for number, hand in enumerate(hands):
        if hand.name == name:
            return number
    for number, hand in enumerate(hands):
        if np.array_equal(hand.labels, labels):
            return number
    return None


class DefineHand(Command):
    """Add a solved-hand track (or replace the one of the same ``name``, else the one of the same labels, e.g. a
    hand whose names do not say its side, solved as the other side): ``side`` "right"/"left", its ``labels`` by
    name in layout order, the ``layout`` name; its joint angles start unsolved (NaN) until a :class:`SetSolve`.
    Used for takes that arrive labelled (no labelling result made the hands)."""

    kind = "define_hand"
    whole = True

    def __init__(self, name: str, side: str, labels: list[str], layout: str | None = None) -> None:
        super().__init__()
        self.name, self.side, self.labels, self.layout = name, side, list(labels), layout

    def _extent(self, review: ReviewTake) -> FrameSpan:
        if self.side not in ("right", "left"):
            raise InputError(f"hand side must be 'right' or 'left', not '{self.side}'")
        if not self.labels:
            raise InputError(f"hand '{self.name}' needs at least one label")
        self._indices = np.array([review.label_index(label) for label in self.labels], dtype=np.int64)
        return FrameSpan(0, review.n_frames)

    def describe(self, review: ReviewTake) -> str:
        return f"define the {self.name} hand ({len(self.labels)} labels)"

    def _apply(self, review: ReviewTake) -> None:
        from handmocap.core.review.take import HandTrack

        track = HandTrack(self.name, self.side, self.layout, self._indices, np.full((review.n_frames, 26), np.nan))
        number = replaced_hand(review.hands, self.name, self._indices)
        if number is None:
            review.hands.append(track)
        else:
            review.hands[number] = track

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"name": self.name, "side": self.side, "labels": self.labels, "layout": self.layout}


class _TimelineCommand(Command):
    """A change of the take's events or trim range (:meth:`ReviewTake.timeline_state`): no frame of any label
    changes, so nothing is re-solved; undo puts the events and the range back exactly."""

    changes = Change.TIMELINE

    def _extent(self, review: ReviewTake) -> FrameSpan:
        self._check(review)
        return EMPTY_SPAN

    def _check(self, review: ReviewTake) -> None:
        """InputError when the command cannot be done on ``review``."""

    def do(self, review: ReviewTake) -> FrameSpan:
        self._check(review)
        self._text = self.describe(review)
        before = review.timeline_state()
        self._apply(review)
        review.changed()
        self._span, self._saved = EMPTY_SPAN, {"timeline": np.array(json.dumps(before))}
        return EMPTY_SPAN

    def undo(self, review: ReviewTake) -> FrameSpan:
        if self._saved is None:
            raise InputError(f"cannot undo '{self.text}': it was not done")
        review.set_timeline_state(json.loads(str(self._saved["timeline"])))
        review.changed()
        self._saved = None
        return EMPTY_SPAN


def _frame_of(review: ReviewTake, frame_number: int) -> int:
    """0-based frame of the file's ``frame_number``; InputError outside the take."""
    frame = int(frame_number) - review.take.first_frame
    if not 0 <= frame < review.n_frames:
        first = review.take.first_frame
        raise InputError(f"frame {frame_number} is outside the take ({first}..{first + review.n_frames - 1})")
    return frame


class AddEvent(_TimelineCommand):
    """Name frame ``frame_number`` (the file's numbering) ``name`` (e.g. "grasp on"), in ``context``
    ("General", "Left", "Right")."""

    kind = "add_event"

    def __init__(self, name: str, frame_number: int, context: str = "General", description: str = "") -> None:
        super().__init__()
        self.name, self.frame_number = str(name).strip(), int(frame_number)
        self.context, self.description = str(context).strip() or "General", str(description)

    def _check(self, review: ReviewTake) -> None:
        if not self.name:
            raise InputError("an event needs a name (e.g. grasp on)")
        if len(self.name.encode()) > 120 or any(ord(character) < 32 for character in self.name):
            raise InputError("an event name is one line of at most 120 bytes")
        _frame_of(review, self.frame_number)
        if any(event.name == self.name and event.frame_number == self.frame_number for event in review.events or []):
            raise InputError(f"frame {self.frame_number} already has the event '{self.name}'")

    def describe(self, review: ReviewTake) -> str:
        return f"add event '{self.name}' at frame {self.frame_number}"

    def _apply(self, review: ReviewTake) -> None:
        from handmocap.core.io.c3d_events import TakeEvent

        review.events = sorted([*(review.events or []), TakeEvent(self.name, self.frame_number, self.context,
                                                                  self.description)],
                               key=lambda event: (event.frame_number, event.name))

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"name": self.name, "frame_number": self.frame_number, "context": self.context,
                "description": self.description}


class RemoveEvent(_TimelineCommand):
    """Remove the event ``name`` at frame ``frame_number`` (the file's numbering)."""

    kind = "remove_event"

    def __init__(self, name: str, frame_number: int) -> None:
        super().__init__()
        self.name, self.frame_number = str(name), int(frame_number)

    def _check(self, review: ReviewTake) -> None:
        if not any(event.name == self.name and event.frame_number == self.frame_number
                   for event in review.events or []):
            raise InputError(f"there is no event '{self.name}' at frame {self.frame_number}")

    def describe(self, review: ReviewTake) -> str:
        return f"remove event '{self.name}' at frame {self.frame_number}"

    def _apply(self, review: ReviewTake) -> None:
        review.events = [event for event in review.events or []
                         if not (event.name == self.name and event.frame_number == self.frame_number)]

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"name": self.name, "frame_number": self.frame_number}


class TrimTake(_TimelineCommand):
    """Trim the take to frames ``start .. stop - 1`` (0-based; both None: the whole take again). The frames
    outside are kept (undo brings them back) but no longer shown, played or exported."""

    kind = "trim_take"

    def __init__(self, start: int | None, stop: int | None) -> None:
        super().__init__()
        self.start, self.stop = _int_or_none(start), _int_or_none(stop)

    def _check(self, review: ReviewTake) -> None:
        if (self.start is None) != (self.stop is None):
            raise InputError("a trim needs a first and a last frame (or neither, to keep the whole take)")
        if self.start is None:
            if review.trim is None:
                raise InputError("the take is not trimmed")
            return
        assert self.stop is not None
        first = review.take.first_frame
        if not 0 <= self.start < self.stop <= review.n_frames:
            raise InputError(f"trim range {first + self.start}..{first + self.stop - 1} is outside the take "
                             f"({first}..{first + review.n_frames - 1})")
        if self.stop - self.start < 2:
            raise InputError("a take trimmed to fewer than 2 frames would be no take: mark a longer range")

    def describe(self, review: ReviewTake) -> str:
        if self.start is None or self.stop is None:
            return "keep the whole take (no trim)"
        return f"trim the take to frames {frame_text(review.take.first_frame, self.start, self.stop)}"

    def _apply(self, review: ReviewTake) -> None:
        review.trim = None if self.start is None or self.stop is None else (self.start, self.stop)

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"start": self.start, "stop": self.stop}


class CompoundCommand(Command):
    """Several commands done (and undone) as one step: ``children`` in order."""

    kind = "compound"

    def __init__(self, children: list[Command], description: str | None = None) -> None:
        super().__init__()
        self.children = list(children)
        self.description = description

    def _extent(self, review: ReviewTake) -> FrameSpan:
        return self.span

    def _apply(self, review: ReviewTake) -> None:
        """Unused: :meth:`do` does and :meth:`undo` undoes the children one by one."""

    def do(self, review: ReviewTake) -> FrameSpan:
        span = EMPTY_SPAN
        done: list[Command] = []
        try:
            for child in self.children:
                span = span.union(child.do(review))
                done.append(child)
        except BaseException:
            for child in reversed(done):
                child.undo(review)
            raise
        self._span = span
        self._saved = {}
        self._text = self.description or (self.children[0].text if self.children else "nothing")
        return span

    def undo(self, review: ReviewTake) -> FrameSpan:
        span = EMPTY_SPAN
        for child in reversed(self.children):
            span = span.union(child.undo(review))
        self._saved = None
        return span

    @property
    def changes(self) -> Change:  # type: ignore[override]
        """What the children change together."""
        combined = Change.NONE
        for child in self.children:
            combined |= child.changes
        return combined

    def append_done(self, child: Command) -> None:
        """Add a child that was just done on the review (used by :meth:`UndoStack.attach`)."""
        self.children.append(child)
        self._span = self.span.union(child.span)

    def saved_state(self) -> tuple[FrameSpan, dict[str, Any]] | None:
        return None  # persisted child by child

    def params(self, blobs: BlobStore | None = None) -> dict[str, Any]:
        return {"description": self.description, "children": [child.to_json(blobs) for child in self.children]}

    @classmethod
    def _from_params(cls, params: dict[str, Any], blobs: BlobStore | None) -> Command:
        return cls([command_from_json(child, blobs) for child in params.get("children", [])],
                   params.get("description"))


# --------------------------------------------------------------------------------------------------
# Undo stack


Recorder = Callable[[str, "Command | None"], None]
"""Called after each successful operation: ("do" | "attach" | "undo" | "redo", command or None)."""
Listener = Callable[[ReviewChanged], None]
"""Told what changed after each successful operation."""


class UndoStack:
    """Undo/redo of the commands applied to one review.

    ``push`` does a command and drops the redo side; ``attach`` does a command as part of the last
    done one (a re-solve after an edit is undone with it); ``undo``/``redo`` return the frames to
    re-solve. ``recorder`` (the journal) is told about every operation after it succeeded in memory;
    if it fails, the operation is reverted and the error raised, so memory and journal never
    disagree. Listeners ``callback(change)`` hear a :class:`~core.review.events.ReviewChanged` after
    every change ("do", "attach", "undo", "redo"; "clean" when only the history changed). At most
    ``limit`` steps are kept (the oldest are dropped).
    """

    def __init__(self, review: ReviewTake, recorder: Recorder | None = None, limit: int = 200) -> None:
        self.review = review
        self.recorder = recorder
        self.limit = max(1, int(limit))
        self._commands: list[Command] = []
        self._index = 0
        self._clean_index: int | None = 0
        self._listeners: list[Listener] = []

    # -- queries --
    @property
    def index(self) -> int:
        """Number of done commands (the position between undo and redo sides)."""
        return self._index

    @property
    def commands(self) -> list[Command]:
        return list(self._commands)

    def can_undo(self) -> bool:
        return self._index > 0

    def can_redo(self) -> bool:
        return self._index < len(self._commands)

    def undo_text(self) -> str:
        return self._commands[self._index - 1].text if self.can_undo() else ""

    def redo_text(self) -> str:
        return self._commands[self._index].text if self.can_redo() else ""

    def texts(self) -> list[str]:
        """Descriptions of every step, oldest first (``index`` of them are done)."""
        return [command.text for command in self._commands]

    def is_clean(self) -> bool:
        """True when the review is as it was at the last :meth:`set_clean` (e.g. saved)."""
        return self._clean_index == self._index

    def set_clean(self) -> None:
        self._clean_index = self._index
        self._notify("clean", EMPTY_SPAN, Change.NONE)

    def add_listener(self, callback: Listener) -> None:
        """``callback(change)`` after every change."""
        self._listeners.append(callback)

    def remove_listener(self, callback: Listener) -> None:
        if callback in self._listeners:
            self._listeners.remove(callback)

    # -- operations --
    def push(self, command: Command) -> FrameSpan:
        """Do ``command`` and make it the top of the stack; returns the changed frames."""
        span = command.do(self.review)
        try:
            self._record("do", command)
        except BaseException:
            command.undo(self.review)
            raise
        del self._commands[self._index:]
        if self._clean_index is not None and self._clean_index > self._index:
            self._clean_index = None
        self._commands.append(command)
        self._index += 1
        self._trim()
        self._notify("do", span, command.changes)
        return span

    def attach(self, command: Command) -> FrameSpan:
        """Do ``command`` as part of the last done step (its undo undoes both). With nothing done, the
        command is applied without an undo step (e.g. the first solve of a take)."""
        span = command.do(self.review)
        try:
            self._record("attach", command)
        except BaseException:
            command.undo(self.review)
            raise
        if self._index > 0:
            top = self._commands[self._index - 1]
            if not isinstance(top, CompoundCommand):
                top = _wrap(top)
                self._commands[self._index - 1] = top
            top.append_done(command)
        self._notify("attach", span, command.changes)
        return span

    def undo(self) -> FrameSpan:
        """Undo the last done step; returns its frames (empty when there is nothing to undo)."""
        if not self.can_undo():
            return EMPTY_SPAN
        command = self._commands[self._index - 1]
        span = command.undo(self.review)
        try:
            self._record("undo", None)
        except BaseException:
            command.do(self.review)
            raise
        self._index -= 1
        self._notify("undo", span, command.changes)
        return span

    def redo(self) -> FrameSpan:
        """Redo the next step; returns its frames (empty when there is nothing to redo)."""
        if not self.can_redo():
            return EMPTY_SPAN
        command = self._commands[self._index]
        span = command.do(self.review)
        try:
            self._record("redo", None)
        except BaseException:
            command.undo(self.review)
            raise
        self._index += 1
        self._notify("redo", span, command.changes)
        return span

    def clear(self) -> None:
        """Forget every step (the review keeps its current state)."""
        self._commands.clear()
        self._index = 0
        self._clean_index = 0
        self._notify("clean", EMPTY_SPAN, Change.NONE)

    def restore_history(self, commands: list[Command], index: int, clean_index: int | None) -> None:
        """Install an undo history read from a snapshot (commands already carry their saved states)."""
        self._commands = list(commands)
        self._index = min(max(0, index), len(self._commands))
        self._clean_index = clean_index

    # -- internals --
    def _record(self, operation: str, command: Command | None) -> None:
        if self.recorder is not None:
            self.recorder(operation, command)

    def _trim(self) -> None:
        excess = len(self._commands) - self.limit
        if excess > 0:
            del self._commands[:excess]
            self._index -= excess
            if self._clean_index is not None:
                self._clean_index = self._clean_index - excess if self._clean_index >= excess else None

    def _notify(self, operation: str, span: FrameSpan, what: Change) -> None:
        change = ReviewChanged(operation, span, what)
        for callback in list(self._listeners):
            callback(change)


def _wrap(command: Command) -> CompoundCommand:
    """A done command as the first child of a done compound (same text and span)."""
    compound = CompoundCommand([command], command.text)
    compound._span, compound._saved, compound._text = command.span, {}, command.text
    return compound
