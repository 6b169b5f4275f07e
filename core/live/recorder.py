"""The recording of a live capture: every frame received is journalled into the session as it arrives, and
at the end the take is written (the raw points unchanged) and entered into the session with the live labels
as its first review step.

The journal ``<session>/live/<name>.hmlj`` is append-only: a header line (JSON: format, version, name, rate,
source), then per frame a record ``FRM1`` (frame index, the system's frame number, its timestamp, the time
received, the points ``(N,3)`` float64 mm) and, once the frame is labelled, a record ``LBL1`` (frame index, the
point each scene marker took). Each record goes to the operating system with one ``write`` as it is made, so
a killed process (kill -9) loses nothing the system had sent it; the file is ``fsync``'ed at least every
:data:`SYNC_SECONDS` seconds, so a machine that loses power loses at most that. A write that fails (a full disk)
stops the recording with one line; what was written stays and :func:`read_journal` reads it back (a torn last
record is dropped), as does ``handmocap live recover``.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.errors import InputError
from core.io import Take
from core.session.files import make_folder, open_append, refuse_links

JOURNAL_FORMAT = "handmocap-live-journal"
SYNC_SECONDS = 0.5
_FRAME = struct.Struct("<4sqqddI")      # magic, index, system frame number, timestamp s, received s, points
_LABELS = struct.Struct("<4sqI")        # magic, index, markers
_MAX_POINTS = 100_000


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

    def take(self) -> Take:
        """The frames as a raw take: column ``*k`` holds each frame's k-th point as received (NaN beyond)."""
        columns = max((len(points) for points in self.points), default=0)
        positions = np.full((len(self.points), columns, 3), np.nan)
        for frame, points in enumerate(self.points):
            positions[frame, :len(points)] = points
        rate = float(self.header.get("frame_rate") or 100.0)
        return Take(marker_names=[f"*{index}" for index in range(columns)], marker_positions=positions,
                    frame_rate=rate, vendor=str(self.header.get("source", "live")))


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
        self.error = ""
        self._synced = time.monotonic()
        self._write(json.dumps({"format": JOURNAL_FORMAT, "version": 1, **header}).encode("utf-8") + b"\n")

    def add_frame(self, number: int, timestamp: float, received: float, points: np.ndarray) -> int:
        """Journal one received frame; returns its index. RecordingError when the write fails."""
        points = np.ascontiguousarray(points, dtype="<f8").reshape(-1, 3)
        index = self.frames
        self._write(_FRAME.pack(b"FRM1", index, int(number), float(timestamp), float(received), len(points))
                    + points.tobytes())
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
