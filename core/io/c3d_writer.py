"""C3D writing with numpy, streamed: the header, the parameter section, then the frames a chunk at a time.

The file is an Intel float C3D in mm: 512-byte header block, parameter blocks from block 2, then per
frame and point x, y, z and the fourth word as float32. Memory beyond the caller's arrays is one chunk
of frames (about :data:`CHUNK_BYTES`), so a 100 000-frame export costs no more than the take itself.

The fourth word follows the C3D standard (c3d.org, "3D Data - Floating-point Format" and the residual
glossary): a float holding a signed integer whose high byte is the camera mask (0: we keep none) and
whose low byte is the point's average residual in units of ``|POINT:SCALE|`` mm. -1 marks a missing
sample (its coordinates written 0); 0 a valid point that is not the measured value (interpolated,
filled, modelled); 1..255 a measured point and its residual, rounded to a scale unit and clipped to
that range (a measured point whose residual is not known gets 1, the smallest measured value).
``POINT:SCALE`` is negative (float data) with the magnitude the standard asks for: the largest
coordinate over 32000 (at 1 m, 0.03 mm per unit; residuals up to 255 units, 8 mm, are stored).

Writes labels (past 255 in LABELS2...), rate, first frame (header and TRIAL:ACTUAL_START_FIELD /
ACTUAL_END_FIELD, which also carry frame numbers past 65535), MANUFACTURER:COMPANY "handmocap" and the
given parameter groups. The file goes through :mod:`core.io.durable`, and before it replaces the
target its header and parameter section are parsed again and its size checked against the frames.
"""

from __future__ import annotations

import math
import re
import struct
from collections.abc import Sequence
from os import PathLike
from pathlib import Path
from typing import BinaryIO

import numpy as np

from handmocap.core.io.c3d_file import _DATA_GROUPS, _LIBRARY_GROUPS, ParameterValue, _parse
from handmocap.core.io.durable import durable_stream
from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.take import Take

CHUNK_BYTES = 8 << 20  # float32 frame data converted per write (8 MiB)
_BLOCK = 512
_INTEL = 84
_CHAR, _INT, _FLOAT = -1, 2, 4
_MAX_DIM = 255  # every C3D dimension is one unsigned byte
_MAX_ENTRY = 32767  # an entry's offset to the next one is a signed 16-bit word
_LABELS_PER_PARAMETER = 255
_C3D_NAME = re.compile(r"[A-Z0-9_]{1,127}")
_MAX_LABEL_BYTES = 125  # 255 labels x 125 bytes still fit one parameter (<= 32767 bytes)
_MAX_GAP = 10  # header word 6: largest gap a reader may interpolate (ezc3d and Vicon write 10)
_SCALE_RANGE = 32000.0  # C3D: POINT:SCALE = largest coordinate / 32000
_DEFAULT_SCALE = 0.1  # mm per unit when the take holds no coordinate at all
RESIDUAL_MEASURED = np.nan  # residual value meaning "measured, residual not known"
RESIDUAL_PROCESSED = 0.0  # residual value meaning "valid but not measured" (a fill)


def write_c3d(take: Take, path: str | PathLike[str]) -> None:
    """Write ``take`` as a float C3D in mm (module docstring), replacing ``path`` durably.
    Raises TakeFormatError (one line) when the take cannot be stored as C3D, WriteError when the file
    cannot be written (the old file is then kept)."""
    write_c3d_points(path, list(take.marker_names), [take.marker_positions], take.frame_rate, take.first_frame,
                     take.parameters)


def write_c3d_points(path: str | PathLike[str], names: list[str], blocks: Sequence[np.ndarray], frame_rate: float,
                     first_frame: int, parameters: dict[str, dict[str, ParameterValue]],
                     residuals: Sequence[np.ndarray | None] | None = None) -> None:
    """Write the points ``blocks`` (each ``(F, m_i, 3)`` mm, NaN missing; their columns side by side are the
    points named ``names``) as a C3D, without joining the blocks in memory. ``parameters``: groups to store.
    ``residuals``: per block ``(F, m_i)`` mm or None (module docstring: > 0 a measured point's residual,
    :data:`RESIDUAL_PROCESSED` 0 a fill, NaN :data:`RESIDUAL_MEASURED` a measured point of unknown
    residual, the default); missing samples are always -1."""
    frames = blocks[0].shape[0] if blocks else 0
    if any(block.ndim != 3 or block.shape[0] != frames or block.shape[2] != 3 for block in blocks):
        raise TakeFormatError.at(path, "point blocks must be (frames, points, 3) with the same frames")
    if sum(block.shape[1] for block in blocks) != len(names):
        raise TakeFormatError.at(path, f"{len(names)} names for {sum(block.shape[1] for block in blocks)} points")
    residuals = list(residuals) if residuals is not None else [None] * len(blocks)
    if len(residuals) != len(blocks) or any(values is not None and values.shape != block.shape[:2]
                                            for block, values in zip(blocks, residuals, strict=True)):
        raise TakeFormatError.at(path, "residuals must be (frames, points) per point block")
    if Path(path).suffix.lower() != ".c3d":
        raise TakeFormatError.at(path, "a C3D file name must end in '.c3d'")
    scale = point_scale(blocks)
    section = _parameter_section(path, names, frames, frame_rate, first_frame, parameters, scale)
    data_block = 2 + len(section) // _BLOCK
    header = _header(len(names), frames, first_frame, frame_rate, data_block, scale)
    frame_bytes = 16 * len(names)
    expected = _BLOCK + len(section) + frames * frame_bytes

    def verify(written: Path) -> None:
        with written.open("rb") as stream:
            parsed = _parse(stream.read(_BLOCK + len(section)), written)
            size = stream.seek(0, 2)
        if parsed.n_points != len(names) or parsed.data_block != data_block or size < expected:
            raise TakeFormatError.at(path, "the written file does not read back")

    with durable_stream(path, verify=verify) as stream:
        stream.write(header)
        stream.write(section)
        _write_frames(stream, blocks, residuals, frame_bytes, scale)
        stream.write(bytes(-stream.tell() % _BLOCK))


def point_scale(blocks: Sequence[np.ndarray]) -> float:
    """``|POINT:SCALE|`` in mm per unit for the points ``blocks``: the largest finite coordinate magnitude
    over 32000 (C3D standard), of the float32 values written, a block of frames at a time;
    :data:`_DEFAULT_SCALE` for no data."""
    largest = 0.0
    for block in blocks:
        step = max(1, CHUNK_BYTES // max(24 * block.shape[1], 1))
        for start in range(0, block.shape[0], step):
            values = np.abs(block[start:start + step].astype(np.float32))
            finite = values[np.isfinite(values)]
            if finite.size:
                largest = max(largest, float(finite.max()))
    return float(np.float32(largest / _SCALE_RANGE)) if largest > 0 else _DEFAULT_SCALE


def residual_words(present: np.ndarray, residuals: np.ndarray | None, scale: float) -> np.ndarray:
    """The fourth word of each sample (module docstring): ``present (F, m)`` bool, ``residuals (F, m)`` mm
    or None (measured, unknown), ``scale`` mm per unit; float32 ``(F, m)``."""
    if residuals is None:
        units = np.ones(present.shape, dtype=np.float32)
    else:
        values = np.asarray(residuals, dtype=np.float64)
        units = np.where(np.isnan(values), 1.0, np.clip(np.rint(values / scale), 1.0, 255.0))
        units = np.where(values == RESIDUAL_PROCESSED, 0.0, units).astype(np.float32)
    return np.where(present, units, np.float32(-1.0))


def _write_frames(stream: BinaryIO, blocks: Sequence[np.ndarray], residuals: Sequence[np.ndarray | None],
                  frame_bytes: int, scale: float) -> None:
    """The frames as float32 ``x, y, z, residual word`` per point, ``CHUNK_BYTES`` at a time."""
    frames = blocks[0].shape[0] if blocks else 0
    points = frame_bytes // 16
    step = max(1, CHUNK_BYTES // max(frame_bytes, 1))
    buffer = np.empty((min(step, frames), points, 4), dtype="<f4")
    for start in range(0, frames, step):
        stop = min(start + step, frames)
        chunk = buffer[:stop - start]
        column = 0
        for block, values in zip(blocks, residuals, strict=True):
            width = block.shape[1]
            chunk[:, column:column + width, :3] = block[start:stop]
            present = np.asarray(np.isfinite(chunk[:, column:column + width, :3]).all(axis=2))
            chunk[:, column:column + width, 3] = residual_words(present, None if values is None
                                                                else values[start:stop], scale)
            column += width
        chunk[chunk[..., 3] < 0, :3] = 0.0
        stream.write(chunk.data)


def _header(points: int, frames: int, first_frame: int, frame_rate: float, data_block: int, scale: float) -> bytes:
    """The 512-byte header block: 16-bit frame numbers saturate at 65535 (TRIAL fields carry the rest)."""
    first = min(max(first_frame, 0), 0xFFFF)
    last = min(max(first_frame + frames - 1, 0), 0xFFFF)
    header = bytearray(_BLOCK)
    struct.pack_into("<BBHHHHHfHHf", header, 0, 2, 0x50, points, 0, first, last, _MAX_GAP, -scale,
                     data_block, 0, frame_rate)
    return bytes(header)


def _parameter_section(path: str | PathLike[str], names: list[str], frames: int, frame_rate: float,
                       first_frame: int, parameters: dict[str, dict[str, ParameterValue]], scale: float) -> bytes:
    """The parameter blocks (first byte of the section at block 2), padded to whole blocks."""
    clashing = sorted({group.upper() for group in parameters} & (_DATA_GROUPS | _LIBRARY_GROUPS))
    if clashing:
        raise TakeFormatError.at(path, f"parameter group {clashing[0]} is written from the take itself")
    too_long = [name for name in names if len(name.encode()) > _MAX_LABEL_BYTES]
    if too_long:
        raise TakeFormatError.at(path, f"marker name '{too_long[0][:40]}...' is longer than {_MAX_LABEL_BYTES} "
                                 "bytes, the C3D label limit")
    groups: dict[str, dict[str, ParameterValue]] = {
        group.upper(): {name.upper(): value for name, value in values.items()} for group, values in parameters.items()
    }
    for group, values in groups.items():
        for name in [group, *values]:
            if not _C3D_NAME.fullmatch(name):
                raise TakeFormatError.at(path, f"parameter name '{name}' is not a C3D name (A-Z, 0-9, _)")
    point: dict[str, ParameterValue] = {"USED": len(names), "SCALE": -scale, "RATE": float(frame_rate),
                                        "DATA_START": 0, "UNITS": "mm",
                                        "FRAMES": np.array(min(frames, 0xFFFF)).astype(np.uint16).astype(np.int16)}
    for index, first in enumerate(range(0, max(len(names), 1), _LABELS_PER_PARAMETER)):
        point["LABELS" if index == 0 else f"LABELS{index + 1}"] = names[first:first + _LABELS_PER_PARAMETER]
    last = first_frame + frames - 1
    groups.setdefault("TRIAL", {}).update(ACTUAL_START_FIELD=_int16_words(first_frame),
                                          ACTUAL_END_FIELD=_int16_words(last))
    groups.setdefault("MANUFACTURER", {}).update(COMPANY="handmocap", SOFTWARE="Hand Mocap Studio")
    analog: dict[str, ParameterValue] = {"USED": 0, "RATE": 0.0, "GEN_SCALE": 1.0}
    ordered = {"POINT": point, "ANALOG": analog, **groups}

    def encode(data_start: int) -> bytes:
        point["DATA_START"] = data_start
        entries = []
        for group_id, (group, values) in enumerate(ordered.items(), start=1):
            entries.append(_entry(group, -group_id, b"\x00"))
            for name, value in values.items():
                entries.append(_entry(name, group_id, _parameter_body(path, f"{group}:{name}", value) + b"\x00"))
        body = bytes([1, 0x50, 0, _INTEL]) + b"".join(entries)
        blocks = math.ceil(len(body) / _BLOCK)
        body = body[:2] + bytes([min(blocks, 255)]) + body[3:]
        return body + bytes(blocks * _BLOCK - len(body))

    section = encode(0)
    data_start = 2 + len(section) // _BLOCK
    if data_start > 0x7FFF:
        raise TakeFormatError.at(path, "the parameters are too large for a C3D file")
    return encode(data_start)  # same length: DATA_START is a fixed-size word


def _entry(name: str, entry_id: int, body: bytes) -> bytes:
    """One group (``entry_id`` < 0) or parameter entry: name, offset to the next entry, then ``body``
    (a parameter's type, dimensions and data, and for both an empty description)."""
    encoded = name.encode("ascii")
    return struct.pack("<bb", len(encoded), entry_id) + encoded + struct.pack("<h", 2 + len(body)) + body


def _parameter_body(path: str | PathLike[str], where: str, value: ParameterValue) -> bytes:
    """Type, dimensions and data of one parameter: strings -> CHAR, integers in int16 range -> INT,
    other numbers -> FLOAT (float32); arrays keep their shape (first dimension varying fastest)."""
    if isinstance(value, str) or (isinstance(value, list | tuple) and all(isinstance(item, str) for item in value)):
        strings = [value] if isinstance(value, str) else list(value)
        encoded = [text.encode("utf-8") for text in strings]
        width = max([1, *map(len, encoded)])
        dims: tuple[int, ...] = (width,) if isinstance(value, str) else (width, len(encoded))
        type_code, data = _CHAR, b"".join(text.ljust(width) for text in encoded)
    else:
        array = np.asarray(value)
        if array.dtype.kind not in "biuf" or array.ndim > 7:
            raise TakeFormatError.at(path, f"parameter {where} has a value C3D cannot store: {value!r}"[:200])
        integer = array.dtype.kind in "biu" and (array.size == 0 or (array.min() >= -32768 and array.max() <= 32767))
        type_code = _INT if integer else _FLOAT
        dims = array.shape
        data = np.asarray(array, dtype="<i2" if integer else "<f4").tobytes(order="F")
    if any(dim > _MAX_DIM for dim in dims) or len(data) + 16 > _MAX_ENTRY:
        raise TakeFormatError.at(path, f"parameter {where} is too large for C3D (dimensions {dims})")
    return struct.pack("<bB", type_code, len(dims)) + bytes(dims) + data


def _int16_words(number: int) -> np.ndarray:
    """A frame number as C3D's two 16-bit words (low, high), stored as signed int16 values."""
    words = np.array([number & 0xFFFF, number >> 16])
    return np.where(words > 32767, words - 65536, words)
