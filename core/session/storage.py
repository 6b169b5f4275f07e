"""Snapshots of a review (``.npz``) and the session's marker sets; written with :mod:`core.io.durable`.

A review snapshot holds the state arrays of a :class:`ReviewTake`, a JSON ``meta`` entry (format
version, label names, hands, settings, the journal sequence number it includes, the raw take's shape)
and the undo history: each step's command JSON plus the arrays its undo restores, so undo works across
sessions. A take keeps its last :data:`KEEP_SNAPSHOTS`: ``review.npz`` (the newest) and
``review-<seq>.npz`` (older ones, named by the journal entry they include), so that a damaged newest
snapshot falls back to an older one and the journal since it.

Everything read here is untrusted: sizes are checked before numpy allocates, JSON has no NaN or
infinities, and every malformed value is an InputError of one line.
"""

from __future__ import annotations

import io
import json
import os
import re
import struct
import time
import tokenize
import zipfile
import zlib
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.c3d_events import TakeEvent
from handmocap.core.io.documents import finite_json
from handmocap.core.io.durable import write_atomic
from handmocap.core.model import MarkerSet
from handmocap.core.review.commands import Command, CompoundCommand, UndoStack, command_from_json
from handmocap.core.review.events import FrameSpan
from handmocap.core.review.take import (
    FRAME_ARRAYS,
    HandTrack,
    ReviewSettings,
    ReviewTake,
    copy_health,
    copy_rigid_bodies,
)
from handmocap.core.session.files import read_bytes, refuse_links, regular_files, remove_file

SNAPSHOT_FORMAT = "handmocap-review"
SNAPSHOT_VERSION = 1
SNAPSHOT_NAME = "review.npz"
OLDER_SNAPSHOT = re.compile(r"review-(\d{1,15})\.npz")
KEEP_SNAPSHOTS = 3
# what malformed stored data raises in the code that turns it into objects (caught at the boundary)
MALFORMED = (InputError, KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError, RecursionError)
# what a damaged zip archive raises while it is read
DAMAGED_ZIP = (OSError, EOFError, zipfile.BadZipFile, zlib.error, struct.error, NotImplementedError, RuntimeError,
               MemoryError) + MALFORMED


class SnapshotMismatch(InputError):
    """A readable snapshot made for a raw take of another shape (the raw file changed)."""


def strict_json(data: str | bytes) -> Any:
    """Parse JSON without NaN or infinities; InputError (one line) for anything malformed, too deep or
    too large."""
    try:
        return finite_json(data)
    except (ValueError, RecursionError) as error:
        text = str(error).splitlines()[0][:120] if str(error) else type(error).__name__
        raise InputError(f"malformed JSON ({text})") from None


def check_npy(stream: Any, available: int, name: str) -> None:
    """InputError unless the ``.npy`` data at ``stream``'s position holds a plain array of at most
    ``available`` bytes; checked from its header before numpy allocates. The stream is left where it was."""
    start = stream.tell()
    try:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
        else:
            raise ValueError(f"unsupported .npy version {version}")
    except (ValueError, EOFError, OSError, SyntaxError, tokenize.TokenError) as error:  # numpy tokenizes the header
        raise InputError(f"{name}: not an array ({str(error).splitlines()[0][:80]})") from None
    finally:
        stream.seek(start)
    if dtype.hasobject:
        raise InputError(f"{name}: holds Python objects, which are never loaded")
    if dtype.kind == "V":
        raise InputError(f"{name}: holds raw records, which are never loaded")
    # an element takes at least a byte: a zero-size type cannot claim 2**40 elements from a few bytes
    size = int(np.prod([int(n) for n in shape], dtype=object)) * max(dtype.itemsize, 1)
    if size > available:
        raise InputError(f"{name}: its header asks for {size} bytes, more than the {available} it holds")


def npz_bytes(arrays: dict[str, np.ndarray], compress_level: int = 1) -> bytes:
    """An ``.npz`` file's bytes for ``arrays`` (readable by ``np.load``); deflate level 1 by default, which
    is several times faster than ``np.savez_compressed`` and nearly as small on these mostly-NaN
    arrays (0: stored uncompressed)."""
    buffer = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compress_level > 0 else zipfile.ZIP_STORED
    with zipfile.ZipFile(buffer, "w", compression=method, compresslevel=compress_level or None,
                         allowZip64=True) as archive:
        for name, array in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as entry:
                np.lib.format.write_array(entry, np.asanyarray(array), allow_pickle=False)
    return buffer.getvalue()


def read_npz(source: str | os.PathLike[str] | bytes, name: str | None = None) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file, or of its bytes (no pickles; each array's size checked against
    its archive entry before it is allocated); InputError naming the file (``name``) when unreadable."""
    name = name or ("the snapshot data" if isinstance(source, bytes) else Path(source).name)
    try:
        with zipfile.ZipFile(io.BytesIO(source) if isinstance(source, bytes) else source) as archive:
            arrays = {}
            for info in archive.infolist():
                key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                with archive.open(info) as member:
                    check_npy(member, info.file_size, f"{name} ({info.filename})")
                    arrays[key] = np.lib.format.read_array(member, allow_pickle=False)
            return arrays
    except DAMAGED_ZIP as error:
        text = str(error).splitlines()[0][:160] if str(error) else type(error).__name__
        raise InputError(f"{name}: cannot read ({text})") from None


MARKER_SET_ARRAYS = ("vertex", "rest_positions", "influence_joints", "influence_weights", "local_points", "offsets_mm")


def write_marker_set(path: str | os.PathLike[str], markers: MarkerSet) -> None:
    """Keep a resolved marker set (e.g. a subject's calibrated markers) as ``.npz``, atomically and durably."""
    arrays = {name: np.asarray(getattr(markers, name)) for name in MARKER_SET_ARRAYS}
    write_atomic(path, npz_bytes({"names": np.array(list(markers.names)), **arrays}))


def read_marker_set(path: str | os.PathLike[str]) -> MarkerSet:
    """A marker set written by :func:`write_marker_set`; InputError naming the file when unreadable."""
    arrays = read_npz(path)
    try:
        return MarkerSet([str(name) for name in arrays["names"]], *(arrays[name] for name in MARKER_SET_ARRAYS))
    except KeyError as error:
        raise InputError(f"{Path(path).name}: not a marker set ({error})") from None


class DictBlobs:
    """A :class:`~core.review.commands.BlobStore` over a dict of arrays (keys ``prefix<n>``)."""

    def __init__(self, arrays: dict[str, np.ndarray], prefix: str = "blob") -> None:
        self.arrays, self.prefix = arrays, prefix

    def put(self, array: np.ndarray) -> str:
        key = f"{self.prefix}{len([k for k in self.arrays if k.startswith(self.prefix)])}"
        self.arrays[key] = np.ascontiguousarray(array)
        return key

    def get(self, key: str) -> np.ndarray:
        if key not in self.arrays:
            raise InputError(f"stored data '{key}' is missing")
        return np.array(self.arrays[key])


def snapshot_bytes(review: ReviewTake, stack: UndoStack | None, journal_seq: int) -> bytes:
    """The ``.npz`` bytes of a snapshot of ``review`` (and its undo history) up to journal entry
    ``journal_seq``."""
    arrays: dict[str, np.ndarray] = {name: value for name, value in review.state_arrays().items()}
    history: dict[str, Any] = {"index": 0, "clean_index": 0, "steps": []}
    if stack is not None:
        blobs = DictBlobs(arrays, "blob")
        steps = []
        for number, command in enumerate(stack.commands):
            steps.append(_step_json(command, f"s{number}", arrays, blobs))
        history = {"index": stack.index, "clean_index": stack.index, "steps": steps}  # a snapshot is a save point
    meta = {
        "format": SNAPSHOT_FORMAT, "version": SNAPSHOT_VERSION, "journal_seq": int(journal_seq),
        "label_names": review.label_names, "hands": [hand.meta() for hand in review.hands],
        "rigid_bodies": review.rigid_bodies,
        "health": [warning.as_dict() for warning in review.health], "noise_mm": review.noise_mm,
        "settings": asdict(review.settings), **review.timeline_state(),
        "take": {"frames": review.n_frames, "points": review.n_points, "source": review.take.source_path},
        "history": history,
    }
    arrays["meta"] = np.array(json.dumps(meta))
    return npz_bytes(arrays)


def _step_json(command: Command, key: str, arrays: dict[str, np.ndarray], blobs: DictBlobs) -> dict[str, Any]:
    """JSON of one undo step; its saved (undo) arrays go into ``arrays`` as ``<key>_<name>``."""
    step: dict[str, Any] = {"command": command.to_json(blobs), "text": command.text}
    if isinstance(command, CompoundCommand):
        step["children"] = [_step_json(child, f"{key}c{index}", arrays, blobs)
                            for index, child in enumerate(command.children)]
        step["span"] = list(command.span)
        return step
    state = command.saved_state()
    if state is None:
        return step
    span, saved = state
    prefix = f"{key}_"
    step["span"] = list(span)
    step["whole"] = bool(saved.get("whole"))
    if saved.get("whole"):
        for name in FRAME_ARRAYS:
            arrays[prefix + name] = saved[name]
        step["label_names"] = saved["label_names"]
        step["hands"] = [hand.meta() for hand in saved["hands"]]
        step["rigid_bodies"] = saved.get("rigid_bodies", {})
        step["health"] = [warning.as_dict() for warning in saved.get("health", [])]
        step["noise_mm"] = saved.get("noise_mm")
        for index, hand in enumerate(saved["hands"]):
            arrays[f"{prefix}hand{index}"] = hand.joint_angles
    else:
        step["keys"] = sorted(saved)
        for name, value in saved.items():
            arrays[prefix + name] = value
    return step


def _span(value: Any, frames: int) -> FrameSpan:
    """A stored frame span ``[start, stop]``, checked against the take's ``frames``."""
    if not isinstance(value, list) or len(value) != 2:
        raise TypeError("a frame span must be [start, stop]")
    start = _int(value[0], "span start", 0, frames + 1)
    return FrameSpan(start, _int(value[1], "span stop", start, frames + 1))


def _restore_step(step: dict[str, Any], key: str, arrays: dict[str, np.ndarray], blobs: DictBlobs,
                  frames: int) -> Command:
    command = command_from_json(step["command"], blobs)
    if isinstance(command, CompoundCommand):
        children = [_restore_step(_typed(child, dict, "history step"), f"{key}c{index}", arrays, blobs, frames)
                    for index, child in enumerate(_typed(step.get("children", []), list, "children"))]
        command.children = children
        command._span, command._saved = _span(step.get("span", [0, 0]), frames), {}
        command._text = str(step.get("text", ""))
        return command
    if "span" not in step:
        command._text = str(step.get("text", ""))
        return command
    prefix = f"{key}_"
    if step.get("whole"):
        saved: dict[str, Any] = {name: arrays[prefix + name] for name in FRAME_ARRAYS}
        saved["whole"] = True
        saved["label_names"] = list(step["label_names"])
        saved["hands"] = [HandTrack(h["name"], h["side"], h.get("layout"), np.asarray(h["labels"], np.int64),
                                    arrays[f"{prefix}hand{index}"]) for index, h in enumerate(step["hands"])]
        saved["rigid_bodies"] = copy_rigid_bodies(step.get("rigid_bodies", {}))
        saved["health"] = copy_health(step.get("health", []))
        saved["noise_mm"] = step.get("noise_mm")
    else:
        saved = {name: arrays[prefix + name] for name in step.get("keys", [])}
    command.set_saved_state(_span(step["span"], frames), saved, str(step.get("text", "")))
    return command


def _timeline(meta: dict[str, Any]) -> dict[str, Any]:
    """The events and trim range a snapshot holds (a snapshot written before they existed: the file's events,
    no trim)."""
    timeline: dict[str, Any] = {}
    if "events" in meta:
        timeline["events"] = [TakeEvent.from_dict(_typed(item, dict, "event"))
                              for item in _typed(meta["events"], list, "events")]
    trim = meta.get("trim")
    if trim is not None:
        values = _typed(trim, list, "trim")
        if len(values) != 2:
            raise ValueError("a trim range must be [start, stop]")
        timeline["trim"] = (_int(values[0], "trim start"), _int(values[1], "trim stop"))
    return timeline


def _settings(value: Any) -> ReviewSettings:
    """Review settings from their JSON: known names with finite numbers."""
    for name, number in _typed(value, dict, "settings").items():
        if type(number) not in (int, float):
            raise TypeError(f"setting {str(name)[:40]} must be a number")
    return ReviewSettings(**value)


def _check_history(review: ReviewTake, commands: list[Command], index: int) -> None:
    """Undo every done step, redo every step and undo back to ``index``: an undo history whose saved
    states do not fit the review fails here, on open, instead of at the operator's undo; the review must
    come back to the state it started from."""
    if not commands:
        return
    before = {name: array.copy() for name, array in review.state_arrays().items()}
    stack = UndoStack(review)
    stack.restore_history(commands, index, None)
    while stack.can_undo():
        stack.undo()
    while stack.can_redo():
        stack.redo()
    while stack.index > index:
        stack.undo()
    after = review.state_arrays()
    if after.keys() != before.keys() or not all(
            after[name].shape == array.shape and np.array_equal(after[name], array, equal_nan=array.dtype.kind == "f")
            for name, array in before.items()):
        raise ValueError("its undo history does not lead back to its state")


def _int(value: Any, what: str, low: int = 0, high: int = 2**53) -> int:
    if type(value) is not int or not low <= value < high:
        raise ValueError(f"{what} must be a whole number from {low}, not {str(value)[:20]}")
    return value


def _typed(value: Any, kind: type, what: str) -> Any:
    if not isinstance(value, kind):
        raise TypeError(f"{what} must be a {kind.__name__}")
    return value


def load_snapshot(data: bytes, take: Take, name: str = SNAPSHOT_NAME) -> tuple[ReviewTake, dict[str, Any],
                                                                                list[Command]]:
    """Read the snapshot bytes ``data`` (file ``name``) made for ``take``: the review, its ``meta`` dict
    and the undo history commands (``meta["history"]`` has ``index`` and ``clean_index``). InputError
    (one line) when unreadable or malformed; :class:`SnapshotMismatch` when the raw take no longer
    matches (frames or point count changed)."""
    arrays = read_npz(data, name)
    try:
        meta = _typed(strict_json(str(arrays.pop("meta"))), dict, "meta")
        if meta.get("format") != SNAPSHOT_FORMAT:
            raise InputError(f"{name}: not a review snapshot")
        version = _int(meta.get("version", 0), "version")
        if version > SNAPSHOT_VERSION:
            raise InputError(f"{name}: written by a newer Hand Mocap Studio (format {version})")
        _int(meta.get("journal_seq"), "journal_seq")
        shape = _typed(meta.get("take", {}), dict, "take")
        if (shape.get("frames"), shape.get("points")) != (take.n_frames, take.n_markers):
            raise SnapshotMismatch(f"{name}: the raw take changed since it was reviewed ({shape.get('frames')} "
                                   f"frames and {shape.get('points')} points then, {take.n_frames} and "
                                   f"{take.n_markers} now)")
        hands = [HandTrack(str(h["name"]), h["side"], h.get("layout"), np.asarray(h["labels"], np.int64),
                           arrays[f"hand{index}"])
                 for index, h in enumerate(_typed(meta["hands"], list, "hands"))]
        frame_arrays: dict[str, Any] = {key: arrays[key] for key in FRAME_ARRAYS}
        review = ReviewTake(take=take, label_names=list(_typed(meta["label_names"], list, "label_names")),
                            hands=hands, rigid_bodies=_typed(meta.get("rigid_bodies", {}), dict, "rigid_bodies"),
                            health=copy_health(meta.get("health", [])), noise_mm=meta.get("noise_mm"),
                            settings=_settings(meta.get("settings", {})), **frame_arrays,
                            **_timeline(meta))
        blobs = DictBlobs(arrays, "blob")
        history = _typed(meta.get("history", {}), dict, "history")
        steps = _typed(history.get("steps", []), list, "history steps")
        index = _int(history.get("index", len(steps)), "history index", 0, len(steps) + 1)
        clean = history.get("clean_index")
        if clean is not None:
            _int(clean, "history clean index", 0, len(steps) + 1)
        commands = [_restore_step(_typed(step, dict, "history step"), f"s{number}", arrays, blobs, take.n_frames)
                    for number, step in enumerate(steps)]
        _check_history(review, commands, index)
    except InputError as error:
        if isinstance(error, SnapshotMismatch) or str(error).startswith(name):
            raise
        raise InputError(f"{name}: damaged review snapshot ({str(error)[:200]})") from None
    except MALFORMED as error:
        text = str(error).splitlines()[0][:200] if str(error) else type(error).__name__
        raise InputError(f"{name}: damaged review snapshot ({'no ' if isinstance(error, KeyError) else ''}{text})"
                         ) from None
    except MemoryError:   # an array far larger than its take (a deflated member of zeros): not this take's
        raise InputError(f"{name}: damaged review snapshot (an array too large for its take)") from None
    return review, meta, commands


# ---------------------------------------------------------------------------------------- the kept snapshots
def snapshot_files(root: Path, folder: Path) -> list[tuple[Path, int | None]]:
    """The snapshots of the take folder ``folder``, newest first, with the journal entry each includes
    as its name tells (None for ``review.npz``, whose ``meta`` tells)."""
    older = [(path, int(match.group(1))) for path in regular_files(root, folder, "review-*.npz")
             if (match := OLDER_SNAPSHOT.fullmatch(path.name))]
    newest = folder / SNAPSHOT_NAME
    refuse_links(root, newest)
    first: list[tuple[Path, int | None]] = [(newest, None)] if newest.is_file() else []
    return first + sorted(older, key=lambda item: -item[1])


def read_snapshot_file(root: Path, path: Path) -> bytes:
    """The bytes of a snapshot file; InputError when it cannot be read."""
    try:
        return read_bytes(root, path)
    except OSError as error:
        raise InputError(f"{path.name}: cannot read ({error.strerror or error})") from None


def keep_older(root: Path, folder: Path, seq: int) -> None:
    """Keep the current ``review.npz`` (which includes journal entry ``seq``) as ``review-<seq>.npz``
    before a new one is written. OSError or InputError when it cannot."""
    newest = folder / SNAPSHOT_NAME
    refuse_links(root, newest)
    if newest.is_file():
        os.replace(newest, folder / f"review-{int(seq)}.npz")


def set_aside(root: Path, path: Path) -> None:
    """Rename a damaged snapshot to ``<name>.damaged-<time>`` (kept for inspection, never read again)."""
    refuse_links(root, path)
    os.replace(path, path.with_name(f"{path.name}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"))


def prune_snapshots(root: Path, folder: Path) -> int:
    """Delete the snapshots beyond the newest :data:`KEEP_SNAPSHOTS`; returns the journal entry up to which
    no kept snapshot needs the journal (0 while fewer are kept: the raw take is the oldest base)."""
    files = snapshot_files(root, folder)
    for path, _ in files[KEEP_SNAPSHOTS:]:
        remove_file(root, path)
    kept = [seq for _, seq in files[:KEEP_SNAPSHOTS] if seq is not None]
    return min(kept) if len(files) >= KEEP_SNAPSHOTS and kept else 0
