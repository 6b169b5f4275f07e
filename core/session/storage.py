"""Snapshots of a review (``.npz``) and the session's marker sets; written with :mod:`core.io.durable`.

A review snapshot (``review.npz``) holds the state arrays of a :class:`ReviewTake`, a JSON ``meta``
entry (format version, label names, hands, settings, the journal sequence number it includes, the
raw take's shape) and the undo history: each step's command JSON plus the arrays its undo restores,
so undo works across sessions.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from core.errors import InputError
from core.io import Take
from core.io.durable import write_atomic
from core.model import MarkerSet
from core.review.commands import Command, CompoundCommand, FrameSpan, UndoStack, command_from_json
from core.review.take import FRAME_ARRAYS, HandTrack, ReviewSettings, ReviewTake, copy_health, copy_rigid_bodies

SNAPSHOT_FORMAT = "handmocap-review"
SNAPSHOT_VERSION = 1


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


def read_npz(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file (no pickles); InputError naming the file when unreadable."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in data.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise InputError(f"{Path(path).name}: cannot read ({error})") from None


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
        "settings": asdict(review.settings),
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


def _restore_step(step: dict[str, Any], key: str, arrays: dict[str, np.ndarray], blobs: DictBlobs) -> Command:
    command = command_from_json(step["command"], blobs)
    if isinstance(command, CompoundCommand):
        children = [_restore_step(child, f"{key}c{index}", arrays, blobs)
                    for index, child in enumerate(step.get("children", []))]
        command.children = children
        command._span, command._saved, command._text = FrameSpan(*step.get("span", (0, 0))), {}, step.get("text", "")
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
    command.set_saved_state(FrameSpan(*step["span"]), saved, str(step.get("text", "")))
    return command


def load_snapshot(path: str | os.PathLike[str], take: Take) -> tuple[ReviewTake, dict[str, Any], list[Command]]:
    """Read a snapshot made for ``take``: the review, its ``meta`` dict and the undo history commands
    (``meta["history"]`` has ``index`` and ``clean_index``). InputError when unreadable or when the raw
    take no longer matches (frames or point count changed)."""
    arrays = read_npz(path)
    name = Path(path).name
    try:
        meta = json.loads(str(arrays.pop("meta")))
    except (KeyError, ValueError) as error:
        raise InputError(f"{name}: not a review snapshot ({error})") from None
    if meta.get("format") != SNAPSHOT_FORMAT:
        raise InputError(f"{name}: not a review snapshot")
    if int(meta.get("version", 0)) > SNAPSHOT_VERSION:
        raise InputError(f"{name}: written by a newer Hand Mocap Studio (format {meta.get('version')})")
    shape = meta.get("take", {})
    if (shape.get("frames"), shape.get("points")) != (take.n_frames, take.n_markers):
        raise InputError(f"{name}: the raw take changed since it was reviewed ({shape.get('frames')} frames and "
                         f"{shape.get('points')} points then, {take.n_frames} and {take.n_markers} now)")
    try:
        hands = [HandTrack(h["name"], h["side"], h.get("layout"), np.asarray(h["labels"], np.int64),
                           arrays[f"hand{index}"]) for index, h in enumerate(meta["hands"])]
        review = ReviewTake(take=take, label_names=list(meta["label_names"]), hands=hands,
                            rigid_bodies=dict(meta.get("rigid_bodies", {})),
                            health=copy_health(meta.get("health", [])), noise_mm=meta.get("noise_mm"),
                            settings=ReviewSettings(**meta.get("settings", {})),
                            **{key: arrays[key] for key in FRAME_ARRAYS})
        blobs = DictBlobs(arrays, "blob")
        history = meta.get("history", {})
        commands = [_restore_step(step, f"s{number}", arrays, blobs)
                    for number, step in enumerate(history.get("steps", []))]
    except (KeyError, TypeError, ValueError) as error:
        raise InputError(f"{name}: damaged review snapshot ({error})") from None
    return review, meta, commands
