"""The recording of a live capture: every frame received is journalled into the session as it arrives, and
at the end the take is written (the raw points unchanged) and entered into the session with the live labels
as its first review step.

The journal ``<session>/live/<name>.hmlj`` is append-only: a header line (JSON: format, version, name, rate,
source), then per frame a record ``FRM1`` (frame index, the system's frame number, its timestamp, the time
received, the points ``(N,3)`` float64 mm), for a frame the capture system labelled itself a record ``SYS1``
(frame index, per point the index of the system's label, -1 none; a label first seen is introduced before it by
a record ``NAM1``: its index and its UTF-8 name) and, once the frame is labelled, a record ``LBL1`` (frame index,
the point each scene marker took). Each record goes to the operating system with one ``write`` as it is made, so
a killed process (kill -9) loses nothing the system had sent it; the file is ``fsync``'ed at least every
:data:`SYNC_SECONDS` seconds, so a machine that loses power loses at most that. A write that fails (a full disk)
stops the recording with one line; what was written stays and :func:`read_journal` reads it back (a torn last
record is dropped), as does ``handmocap live recover``.

The capture system's own labels (QTM's labelled 3D markers, Motive's labelled markers) are kept beside the raw
points, which stay unchanged: per point slot of the take (its column ``*k``) the label the system gave that
point (:class:`SystemLabels`). The take records that they exist in its C3D parameter group ``SYSTEM_LABELS``
(:meth:`SystemLabels.parameters`: the system, the label names, the share of the points the system labelled, the
share of frames each label was seen, and the sidecar file); the per-point labels are in the sidecar
``<session>/live/<name>.system-labels.npz`` (:func:`write_system_labels`, :func:`read_system_labels`), which a
C3D parameter section is too small to hold for a take of minutes.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import struct
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.durable import write_atomic
from handmocap.core.io.system_labels import SYSTEM_GROUP
from handmocap.core.session.files import make_folder, open_append, refuse_links, write_file

JOURNAL_FORMAT = "handmocap-live-journal"
SYNC_SECONDS = 0.5
_FRAME = struct.Struct("<4sqqddI")      # magic, index, system frame number, timestamp s, received s, points
_LABELS = struct.Struct("<4sqI")        # magic, index, markers
_SYSTEM = struct.Struct("<4sqI")        # magic, index, points (then int32 label index per point)
_NAME = struct.Struct("<4sII")          # magic, label index, UTF-8 bytes
_MAX_POINTS = 100_000
_MAX_NAME = 4096
SYSTEM_LABELS_FORMAT = "handmocap-system-labels"
_C3D_NAMES = 255            # labels per C3D parameter (its dimensions are bytes)
_C3D_NAME_BYTES = 120       # 255 names of 120 bytes fit one C3D parameter (<= 32767 bytes)


class RecordingError(InputError):
    """The recording stopped (one line); what was written is kept."""


@dataclass
class Journal:
    """What a journal holds: its ``header`` (dict), per frame the ``points`` (list of (N,3) mm arrays), the
    system's ``numbers``, ``timestamps`` and ``received`` times, and the live ``labels`` {frame: (M,) point
    index per marker}."""

    header: dict
    points: list[np.ndarray] = field(default_factory=list)
    numbers: list[int] = field(default_factory=list)
    timestamps: list[float] = field(default_factory=list)
    received: list[float] = field(default_factory=list)
    labels: dict[int, np.ndarray] = field(default_factory=dict)
    #: the capture system's labels: their names, and per frame it labelled the name index per point (-1 none)
    system_names: list[str] = field(default_factory=list)
    system_labels: dict[int, np.ndarray] = field(default_factory=dict)

    def take(self) -> Take:
        """The frames as a raw take: column ``*k`` holds each frame's k-th point as received (NaN beyond); the
        system's labels, when it sent any, in the parameter group ``SYSTEM_LABELS`` (without a sidecar)."""
        columns = max((len(points) for points in self.points), default=0)
        positions = np.full((len(self.points), columns, 3), np.nan)
        for frame, points in enumerate(self.points):
            positions[frame, :len(points)] = points
        rate = float(self.header.get("frame_rate") or 100.0)
        system = self.system()
        return Take(marker_names=[f"*{index}" for index in range(columns)], marker_positions=positions,
                    frame_rate=rate, vendor=str(self.header.get("source", "live")),
                    parameters={SYSTEM_GROUP: system.parameters()} if system is not None else {})

    def system(self) -> SystemLabels | None:
        """The capture system's labels of the frames journalled (None when it sent none)."""
        if not self.system_names:
            return None
        return system_labels(str(self.header.get("source_label") or self.header.get("source", "")),
                             self.system_names, [self.system_labels.get(frame) for frame in range(len(self.points))],
                             [len(points) for points in self.points])


@dataclass
class SystemLabels:
    """The capture system's own labels of a recording (module docstring): ``source`` (the system), ``names``
    (its labels, in the order first seen), ``codes (F, C)`` int32: per frame and point slot (the take's column)
    the index into ``names`` of the label the system gave that point, -1 none; ``points (F,)`` the points
    received per frame."""

    source: str
    names: list[str]
    codes: np.ndarray
    points: np.ndarray

    @property
    def labelled_share(self) -> float:
        """The share of the points received that the system labelled."""
        total = int(self.points.sum())
        return float((self.codes >= 0).sum() / total) if total else 0.0

    def seen_share(self) -> np.ndarray:
        """Per name, the share of frames in which the system labelled a point with it."""
        frames = len(self.codes)
        if not frames or not self.names:
            return np.zeros(len(self.names))
        seen = np.zeros((frames, len(self.names) + 1), dtype=bool)
        rows = np.repeat(np.arange(frames), self.codes.shape[1])
        seen[rows, self.codes.reshape(-1)] = True            # -1 lands in the last column, dropped
        return seen[:, :-1].mean(axis=0)

    def labels_of(self, frame: int) -> list[str]:
        """The system's label of each point of ``frame`` ("" none)."""
        count = int(self.points[frame])
        return [self.names[code] if code >= 0 else "" for code in self.codes[frame, :count]]

    def parameters(self, file: str | None = None) -> dict:
        """The C3D parameter group ``SYSTEM_LABELS`` that says the take has the system's labels (module
        docstring); ``file``: the sidecar holding them per point."""
        group: dict = {"SOURCE": self.source or "capture system", "SHARE": round(self.labelled_share, 6),
                       "FRAMES": int((self.codes >= 0).any(axis=1).sum()) if self.codes.size else 0,
                       "COUNT": len(self.names)}
        shares = self.seen_share()
        for index, first in enumerate(range(0, max(len(self.names), 1), _C3D_NAMES)):
            suffix = "" if index == 0 else str(index + 1)
            group[f"NAMES{suffix}"] = [_c3d_text(name) for name in self.names[first:first + _C3D_NAMES]] or [""]
            group[f"SEEN{suffix}"] = np.round(shares[first:first + _C3D_NAMES], 6).astype(np.float32)
        if file and len(file.encode("utf-8")) <= 255:
            group["FILE"] = file
        return group


def system_labels(source: str, names: list[str], codes: list[np.ndarray | None], points: list[int],
                  columns: int | None = None) -> SystemLabels:
    """The system's labels of a recording from its per-frame name indices (None: the frame came without
    labels) and the points received per frame; ``columns``: the take's point slots (default: the most points
    of a frame)."""
    if columns is None:
        columns = max([0, *points])
    table = np.full((len(points), columns), -1, dtype=np.int32)
    for frame, values in enumerate(codes[:len(points)]):
        if values is not None:
            table[frame, :min(len(values), columns)] = values[:columns]
    return SystemLabels(source, list(names), table, np.minimum(np.asarray(points, dtype=np.int32), columns))


def write_system_labels(labels: SystemLabels, path: Path, root: Path | None = None) -> None:
    """Write the sidecar of the system's labels (``root``: the session folder it is in; no links followed)."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, format=np.array(SYSTEM_LABELS_FORMAT), version=np.array(1),
                        source=np.array(labels.source), names=np.array(labels.names, dtype=str),
                        codes=labels.codes.astype("<i4"), points=labels.points.astype("<i4"))
    if root is not None:
        make_folder(root, path.parent)
        write_file(root, path, buffer.getvalue())
    else:
        write_atomic(path, buffer.getvalue())


def read_system_labels(path: str | os.PathLike[str]) -> SystemLabels:
    """Read a sidecar of the system's labels (InputError, one line, when it is not one)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != SYSTEM_LABELS_FORMAT:
                raise KeyError("format")
            names = [str(name) for name in data["names"].reshape(-1)]
            codes = np.asarray(data["codes"], dtype=np.int32)
            points = np.asarray(data["points"], dtype=np.int32).reshape(-1)
            source = str(data["source"])
    except OSError as error:
        raise InputError(f"cannot read {path}: {error.strerror or error}") from None
    except (KeyError, ValueError, zipfile.BadZipFile, EOFError):
        raise InputError(f"{path} is not a file of a capture system's labels") from None
    if codes.ndim != 2 or len(codes) != len(points) or (codes.size and (codes.max() >= len(names) or codes.min() < -1)):
        raise InputError(f"{path} is not a file of a capture system's labels (inconsistent arrays)")
    return SystemLabels(source, names, codes, points)


def _c3d_text(name: str) -> str:
    """A label as a C3D string: ASCII-safe UTF-8 cut to :data:`_C3D_NAME_BYTES` bytes."""
    return name.encode("utf-8")[:_C3D_NAME_BYTES].decode("utf-8", "ignore").strip() or "?"


class FrameJournal:
    """The append-only journal of one recording (module docstring). ``root`` is the session folder the
    journal lives in (no links are followed inside it)."""

    def __init__(self, root: Path, path: Path, header: dict) -> None:
        self.root, self.path = Path(root), Path(path)
        make_folder(self.root, self.path.parent)
        if self.path.exists():
            raise InputError(f"{self.path} exists already: a recording of that name is in the session")
        self._handle = open_append(self.root, self.path)
        self.descriptor = self._handle.fileno()
        self.frames = 0
        self.bytes = 0
        self.system_names = 0         # the system's labels introduced so far (NAM1 records)
        self.error = ""
        self._synced = time.monotonic()
        self._write(json.dumps({"format": JOURNAL_FORMAT, "version": 1, **header}).encode("utf-8") + b"\n")

    def add_frame(self, number: int, timestamp: float, received: float, points: np.ndarray,
                  system: np.ndarray | None = None, names: list[str] | tuple[str, ...] = ()) -> int:
        """Journal one received frame (one write); returns its index. ``system``: per point the index into
        ``names`` (the system's labels so far) of the label the capture system gave it, -1 none; None when the
        frame came without labels. RecordingError when the write fails."""
        points = np.ascontiguousarray(points, dtype="<f8").reshape(-1, 3)
        index = self.frames
        record: list[bytes] = []
        introduced = self.system_names
        if system is not None:
            for code in range(introduced, len(names)):       # the labels first seen in this frame
                encoded = str(names[code]).encode("utf-8")[:_MAX_NAME]
                record += [_NAME.pack(b"NAM1", code, len(encoded)), encoded]
            introduced = len(names)
        record += [_FRAME.pack(b"FRM1", index, int(number), float(timestamp), float(received), len(points)),
                   points.tobytes()]
        if system is not None:
            codes = np.ascontiguousarray(system, dtype="<i4").reshape(-1)
            record += [_SYSTEM.pack(b"SYS1", index, len(codes)), codes.tobytes()]
        self._write(b"".join(record))
        self.system_names = introduced
        self.frames += 1
        return index

    def add_labels(self, index: int, assignment: np.ndarray) -> None:
        """Journal the live labels of frame ``index`` (point index per scene marker, -1 none)."""
        values = np.ascontiguousarray(assignment, dtype="<i4")
        self._write(_LABELS.pack(b"LBL1", index, len(values)) + values.tobytes())

    def _write(self, data: bytes) -> None:
        if self.error:
            raise RecordingError(self.error)
        try:
            written = os.write(self.descriptor, data)
            while written < len(data):
                written += os.write(self.descriptor, data[written:])
            if time.monotonic() - self._synced >= SYNC_SECONDS:
                os.fsync(self.descriptor)
                self._synced = time.monotonic()
        except OSError as error:
            full = error.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
            self.error = (f"the disk is full: the recording stopped after {self.frames} frames; what was "
                          f"written is kept in {self.path}" if full else
                          f"cannot write the recording ({error.strerror or error}): it stopped after "
                          f"{self.frames} frames; what was written is kept in {self.path}")
            raise RecordingError(self.error) from None
        self.bytes += len(data)

    def sync(self) -> None:
        """Flush to the disk now."""
        with contextlib.suppress(OSError):
            os.fsync(self.descriptor)
        self._synced = time.monotonic()

    def close(self) -> None:
        self.sync()
        with contextlib.suppress(OSError):
            self._handle.close()


def read_journal(path: str | os.PathLike[str], root: str | os.PathLike[str] | None = None) -> Journal:
    """Read a journal back (a torn or damaged tail is dropped). InputError when it is no journal."""
    path = Path(path)
    if root is not None:
        refuse_links(Path(root), path)
    try:
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"cannot read {path}: {error.strerror or error}") from None
    line, newline, rest = data.partition(b"\n")
    try:
        header = json.loads(line.decode("utf-8")) if newline else {}
    except (UnicodeDecodeError, json.JSONDecodeError):
        header = {}
    if not isinstance(header, dict) or header.get("format") != JOURNAL_FORMAT:
        raise InputError(f"{path} is not a live capture journal")
    journal = Journal(header)
    position = 0
    view = memoryview(rest)
    while position + 4 <= len(view):
        magic = bytes(view[position:position + 4])
        if magic == b"FRM1" and position + _FRAME.size <= len(view):
            _, index, number, timestamp, received, count = _FRAME.unpack_from(view, position)
            end = position + _FRAME.size + 24 * count
            if count > _MAX_POINTS or end > len(view) or index != len(journal.points):
                break
            journal.points.append(np.frombuffer(view[position + _FRAME.size:end], dtype="<f8").reshape(-1, 3).copy())
            journal.numbers.append(number)
            journal.timestamps.append(timestamp)
            journal.received.append(received)
        elif magic == b"NAM1" and position + _NAME.size <= len(view):
            _, code, length = _NAME.unpack_from(view, position)
            end = position + _NAME.size + length
            if length > _MAX_NAME or end > len(view) or code != len(journal.system_names):
                break
            journal.system_names.append(bytes(view[position + _NAME.size:end]).decode("utf-8", "replace"))
        elif magic == b"SYS1" and position + _SYSTEM.size <= len(view):
            _, index, count = _SYSTEM.unpack_from(view, position)
            end = position + _SYSTEM.size + 4 * count
            if count > _MAX_POINTS or end > len(view):
                break
            codes = np.frombuffer(view[position + _SYSTEM.size:end], dtype="<i4").astype(np.int32)
            if codes.size and (codes.max() >= len(journal.system_names) or codes.min() < -1):
                break
            journal.system_labels[int(index)] = codes
        elif magic == b"LBL1" and position + _LABELS.size <= len(view):
            _, index, count = _LABELS.unpack_from(view, position)
            end = position + _LABELS.size + 4 * count
            if count > _MAX_POINTS or end > len(view):
                break
            journal.labels[int(index)] = np.frombuffer(view[position + _LABELS.size:end], dtype="<i4").astype(np.int64)
        else:
            break
        position = end
    return journal
