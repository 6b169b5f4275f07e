"""C3D takes: a vectorised numpy reader for every C3D flavour (the writer is :mod:`core.io.c3d_writer`).

Reading parses the 512-byte header and the parameter section here, with a bounds check on every
entry, then takes the whole point block with one `np.frombuffer`. It handles Intel, DEC (VAX float)
and MIPS (big-endian) processor types, integer and float point formats, analog samples interleaved
with the points, labels past 255 (`POINT:LABELS2`...), frame numbers past 65535
(`TRIAL:ACTUAL_START_FIELD`/`ACTUAL_END_FIELD`), and stops cleanly at a damaged parameter entry.
ezc3d and the `c3d` package are deliberately not used to read: ezc3d can abort the process on
malformed files and silently returns fewer frames from a truncated file, and neither reads all the
vendor files this reader reads (ezc3d has no MIPS support, `c3d` fails on some parameter shapes);
the tests compare this reader with both of them on every file they can read.

Conversions at this boundary: POINT:UNITS to mm (guessed from the data when absent), residual < 0
or exactly (0, 0, 0) to NaN, the file's first frame number to `Take.first_frame`.
"""

import logging
import math
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.take import Take, chosen_frame_rate, mm_per_unit, unique_marker_names, zeros_to_nan

_log = logging.getLogger(__name__)

_BLOCK = 512
_KEY = 0x50
_INTEL, _DEC, _MIPS = 84, 85, 86
_CHAR, _BYTE, _INT, _FLOAT = -1, 1, 2, 4
_DATA_GROUPS = frozenset({"POINT", "ANALOG", "FORCE_PLATFORM", "ROTATION"})  # written from the take itself
_LIBRARY_GROUPS = frozenset({"EZC3D"})  # stamped by the writing library
_MAX_DIMS = 7  # the C3D limit for a parameter's dimensions
_VENDOR_KEYWORDS = (
    ("qualisys", "Qualisys"),
    ("vicon", "Vicon"),
    ("oxford metrics", "Vicon"),
    ("motion analysis", "Motion Analysis"),
    ("cortex", "Motion Analysis"),
    ("evart", "Motion Analysis"),
    ("phasespace", "PhaseSpace"),
    ("advanced realtime tracking", "ART"),
    ("art-human", "ART"),
    ("dtrack", "ART"),
    ("optitrack", "OptiTrack"),
    ("naturalpoint", "OptiTrack"),
    ("codamotion", "Codamotion"),
    ("handmocap", "handmocap"),
)

ParameterValue = str | list[str] | int | float | np.ndarray


@dataclass
class _Parameter:
    type_code: int  # -1 char, 1 byte, 2 int16, 4 float32
    dims: tuple[int, ...]  # C3D order: first dimension varies fastest
    raw: bytes


@dataclass
class _C3DFile:
    """Header and parameters of a C3D file; `groups` maps upper-case GROUP -> NAME -> parameter."""

    processor: int
    parameter_block: int
    n_points: int
    analog_words_per_frame: int
    first_frame: int
    last_frame: int
    scale: float
    frame_rate: float
    data_block: int
    groups: dict[str, dict[str, _Parameter]]
    group_descriptions: list[str]


def read_c3d(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read a C3D file into a Take (mm, NaN for missing) at POINT:RATE, or at ``frame_rate`` (Hz) when given;
    raises TakeFormatError with a one-line reason."""
    data = Path(path).read_bytes()
    c3d = _parse(data, path)

    def value(group: str, name: str) -> ParameterValue | None:
        parameter = c3d.groups.get(group, {}).get(name)
        return None if parameter is None else _decode(parameter, c3d.processor)

    n_points = c3d.n_points
    if n_points == 0:
        raise TakeFormatError.at(path, "contains no 3D points (header point count 0)")
    scale = _number(value("POINT", "SCALE"))
    if scale is None or scale == 0.0:
        scale = c3d.scale
    if scale == 0.0 or not math.isfinite(scale):
        raise TakeFormatError.at(path, f"invalid point scale factor {scale} (POINT:SCALE)")
    word_bytes = 4 if scale < 0 else 2

    data_block = c3d.data_block
    if data_block <= c3d.parameter_block:
        data_block = int(_number(value("POINT", "DATA_START")) or 0)
    if data_block <= c3d.parameter_block:
        raise TakeFormatError.at(
            path,
            f"invalid data section pointer {c3d.data_block} "
            f"(the parameter section starts at block {c3d.parameter_block})",
        )
    data_offset = (data_block - 1) * _BLOCK
    if data_offset > len(data):
        raise TakeFormatError.at(
            path, f"truncated: the data section (block {data_block}) starts past the end"
        )

    # The 16-bit header frame numbers stop at 65535; TRIAL:ACTUAL_START/END_FIELD (two words) go further.
    first, last = c3d.first_frame, c3d.last_frame
    trial_start = _frame_number(value("TRIAL", "ACTUAL_START_FIELD"))
    trial_end = _frame_number(value("TRIAL", "ACTUAL_END_FIELD"))
    use_trial = False
    if (trial_start is not None and trial_end is not None and trial_end >= trial_start
            and (last == 0xFFFF or trial_end > 0xFFFF)):
        first, last, use_trial = trial_start, trial_end, True
    n_frames = last - first + 1
    if n_frames <= 0:
        raise TakeFormatError.at(path, f"contains no frames (first frame {first}, last frame {last})")
    words_per_frame = 4 * n_points + c3d.analog_words_per_frame
    available = (len(data) - data_offset) // (words_per_frame * word_bytes)
    if not use_trial and last == 0xFFFF and available > n_frames:
        _log.warning(
            "%s: frame count saturated at 65535 in the header, reading all %d frames present",
            Path(path).name,
            available,
        )
        n_frames = available
    if available < n_frames:
        raise TakeFormatError.at(path, f"truncated: the data section holds {available} of {n_frames} frames")

    positions, invalid = _read_points(
        data, data_offset, n_frames, n_points, words_per_frame, scale, c3d.processor
    )
    if invalid.all() and ((positions != 0) & np.isfinite(positions)).any():
        _log.warning(
            "%s: every sample is flagged invalid (residual < 0) but holds coordinates; "
            "ignoring the residual flags",
            Path(path).name,
        )
        invalid = ~np.isfinite(positions).all(axis=2)
    positions[invalid] = np.nan
    zeros_to_nan(positions)

    units = _text_value(value("POINT", "UNITS"))
    if not units:
        units = _guess_units(positions)
        _log.warning("%s: POINT:UNITS is missing, the data look like %s", Path(path).name, units)
    positions *= mm_per_unit(units, path)

    rate = _number(value("POINT", "RATE"))
    if rate is None or not (math.isfinite(rate) and rate > 0):
        rate = c3d.frame_rate
    in_file = float(str(np.float32(rate))) if math.isfinite(rate) and rate > 0 else None  # shortest decimal
    # of the stored float32 (e.g. 25.000002)

    return Take(
        marker_names=_labels(c3d, n_points, path),
        marker_positions=positions,
        frame_rate=chosen_frame_rate(path, in_file, frame_rate, f"no valid point frame rate (POINT:RATE {rate})"),
        frame_rate_given=frame_rate is not None,
        first_frame=first,
        vendor=_vendor(c3d, value("MANUFACTURER", "COMPANY")),
        source_units=units,
        source_path=str(path),
        parameters={
            group: {name: _decode(parameter, c3d.processor) for name, parameter in parameters.items()}
            for group, parameters in c3d.groups.items()
            if group not in _DATA_GROUPS | _LIBRARY_GROUPS
        },
    )


def _parse(data: bytes, path: str | PathLike[str]) -> _C3DFile:
    """Validate and decode the header and the parameter section (never reads out of bounds)."""
    if len(data) < _BLOCK:
        raise TakeFormatError.at(path, f"not a C3D file (only {len(data)} bytes, a header is 512)")
    if data[1] != _KEY:
        raise TakeFormatError.at(path, f"not a C3D file (header key byte {data[1]}, expected 80)")
    if data[0] < 2:
        raise TakeFormatError.at(path, f"not a C3D file (parameter section pointer {data[0]})")
    parameter_start = (data[0] - 1) * _BLOCK
    if parameter_start + 4 > len(data):
        raise TakeFormatError.at(path, f"truncated: parameter section (block {data[0]}) is past the end")
    processor = data[parameter_start + 3]
    if processor not in (_INTEL, _DEC, _MIPS):
        raise TakeFormatError.at(
            path,
            f"parameter section (block {data[0]}) has unknown processor type "
            f"{processor} (expected 84 Intel, 85 DEC or 86 MIPS)",
        )

    words = np.frombuffer(data, dtype=_endian(processor) + "u2", count=12)
    scale, frame_rate = _floats(data[12:16] + data[20:24], processor)
    data_block = int(words[8])
    section_end = len(data) if data_block <= data[0] else min(len(data), (data_block - 1) * _BLOCK)
    groups, descriptions = _parse_parameters(data, parameter_start + 4, section_end, processor, path)
    return _C3DFile(
        processor=processor,
        parameter_block=data[0],
        n_points=int(words[1]),
        analog_words_per_frame=int(words[2]),
        first_frame=int(words[3]),
        last_frame=int(words[4]),
        scale=float(scale),
        frame_rate=float(frame_rate),
        data_block=data_block,
        groups=groups,
        group_descriptions=descriptions,
    )


def _parse_parameters(
    data: bytes, position: int, end: int, processor: int, path: str | PathLike[str]
) -> tuple[dict[str, dict[str, _Parameter]], list[str]]:
    """Walk the parameter entries from `position` to `end` (bytes); stop at the first damaged entry."""
    endian = _endian(processor)
    group_names: dict[int, str] = {}
    descriptions: list[str] = []
    entries: list[tuple[int, str, _Parameter]] = []
    last_good = "start of the parameter section"
    while position + 2 <= end:
        name_length, entry_id = abs(_int8(data[position])), _int8(data[position + 1])
        if name_length == 0 or entry_id == 0:
            break
        name_end = position + 2 + name_length
        name = data[position + 2 : name_end]
        if name_end + 2 > end or not all(0x21 <= byte <= 0x7E for byte in name):
            _log.warning(
                "%s: damaged parameter section after %s; keeping what precedes", Path(path).name, last_good
            )
            break
        offset = int(np.frombuffer(data, endian + "i2", count=1, offset=name_end)[0])
        body = name_end + 2
        name_text = name.decode("ascii").upper()
        if entry_id < 0:
            description_end = body + 1 + (data[body] if body < end else 0)
            group_names.setdefault(-entry_id, name_text)
            descriptions.append(_text(data[body + 1 : min(description_end, end)]))
            last_good = f"group {name_text}"
        else:
            where = f"{group_names.get(entry_id, '?')}:{name_text}"
            parameter = _read_parameter(data, body, end)
            if parameter is None:
                _log.warning(
                    "%s: damaged parameter %s after %s; keeping what precedes",
                    Path(path).name,
                    where,
                    last_good,
                )
                break
            entries.append((entry_id, name_text, parameter))
            last_good = f"parameter {where}"
        if offset == 0:
            break
        if offset < 2:
            _log.warning(
                "%s: damaged parameter pointer after %s; keeping what precedes", Path(path).name, last_good
            )
            break
        position = name_end + offset

    groups: dict[str, dict[str, _Parameter]] = {name: {} for name in group_names.values()}
    for group_id, parameter_name, parameter in entries:
        if group_id in group_names:
            groups[group_names[group_id]].setdefault(parameter_name, parameter)
    return groups, descriptions


def _read_parameter(data: bytes, body: int, end: int) -> _Parameter | None:
    """The parameter whose type byte is at `body`, or None if it is malformed or runs past `end`."""
    if body + 2 > end:
        return None
    type_code, n_dims = _int8(data[body]), data[body + 1]
    if type_code not in (_CHAR, _BYTE, _INT, _FLOAT) or n_dims > _MAX_DIMS or body + 2 + n_dims > end:
        return None
    dims = tuple(data[body + 2 : body + 2 + n_dims])
    start = body + 2 + n_dims
    size = abs(type_code) * math.prod(dims)
    if start + size > end:
        return None
    if type_code == _CHAR and math.prod(dims[1:]) > len(data):
        return None  # strings of width 0 take no bytes: more of them than the file has bytes is a crafted count
    return _Parameter(type_code, dims, data[start : start + size])


def _decode(parameter: _Parameter, processor: int) -> ParameterValue:
    """Python value of a parameter: str (one string), list[str], int/float (one number) or ndarray.

    Arrays have the C3D dims as shape (Fortran order, as ezc3d returns them).
    """
    if parameter.type_code == _CHAR:
        width = parameter.dims[0] if parameter.dims else 1
        count = math.prod(parameter.dims[1:])
        strings = [_text(parameter.raw[i * width : (i + 1) * width]) for i in range(count)]
        return strings[0] if len(strings) == 1 else strings
    if parameter.type_code == _FLOAT:
        array = _floats(parameter.raw, processor)
    elif parameter.type_code == _INT:
        array = np.frombuffer(parameter.raw, _endian(processor) + "i2").astype(np.int64)
    else:
        array = np.frombuffer(parameter.raw, np.int8).astype(np.int64)
    if array.size == 1 and len(parameter.dims) <= 1:
        return array[0].item()
    return array.reshape(parameter.dims, order="F")


def _read_points(
    data: bytes, offset: int, n_frames: int, n_points: int, words_per_frame: int, scale: float, processor: int
) -> tuple[np.ndarray, np.ndarray]:
    """(F, M, 3) float64 coordinates in file units and (F, M) bool invalid (residual < 0 or not finite)."""
    if scale >= 0:
        dtype = _endian(processor) + "i2"
    elif processor == _DEC:
        dtype = "<u4"
    else:
        dtype = _endian(processor) + "f4"
    block = np.frombuffer(data, dtype=dtype, count=n_frames * words_per_frame, offset=offset)
    block = block.reshape(n_frames, words_per_frame)[:, : 4 * n_points]
    if scale < 0 and processor == _DEC:
        block = _dec_to_ieee(block)
    points = block.reshape(n_frames, n_points, 4)
    with np.errstate(invalid="ignore"):  # signalling NaNs in damaged float data
        positions = points[..., :3].astype(np.float64)
    if scale > 0:
        positions *= scale
    invalid = (points[..., 3] < 0) | ~np.isfinite(positions).all(axis=2)
    return positions, invalid


def _labels(c3d: _C3DFile, n_points: int, path: str | PathLike[str]) -> list[str]:
    """POINT:LABELS, LABELS2, ... cut or padded to `n_points`, made unique."""
    point = c3d.groups.get("POINT", {})
    labels: list[str] = []
    for key in ["LABELS"] + [f"LABELS{i}" for i in range(2, 100)]:
        if key not in point:
            break
        value = _decode(point[key], c3d.processor)
        if isinstance(value, str):
            labels.append(value)
        elif isinstance(value, list):
            labels.extend(value)
    if len(labels) < n_points:
        _log.warning(
            "%s: %d labels for %d points; naming the others by number", Path(path).name, len(labels), n_points
        )
    labels = (labels + [""] * n_points)[:n_points]
    return unique_marker_names(labels)


def _vendor(c3d: _C3DFile, company: ParameterValue | None) -> str:
    """Vendor from MANUFACTURER:COMPANY, else from keywords in the text parameters, else "unknown"."""
    company_text = _text_value(company)
    if company_text:
        return _vendor_from_text(company_text) or company_text
    texts = list(c3d.group_descriptions)
    for parameters in c3d.groups.values():
        for parameter in parameters.values():
            if parameter.type_code == _CHAR:
                texts.append(_text(parameter.raw))
    return _vendor_from_text(" ".join(texts)) or "unknown"


def _vendor_from_text(text: str) -> str | None:
    lowered = text.lower()
    return next((vendor for keyword, vendor in _VENDOR_KEYWORDS if keyword in lowered), None)


def _guess_units(positions: np.ndarray) -> str:
    """Units when POINT:UNITS is absent: "m" if 99 % of |coordinates| are below 20 (metres), else "mm"."""
    valid = positions[np.isfinite(positions)]
    return "m" if valid.size and np.percentile(np.abs(valid), 99) < 20 else "mm"


def _frame_number(value: ParameterValue | None) -> int | None:
    """A frame number stored as two 16-bit words (low, high), or None."""
    if value is None or isinstance(value, str | list):
        return None
    words = np.asarray(value).ravel().astype(np.int64) & 0xFFFF
    if words.size == 0:
        return None
    return int(words[0] + (words[1] << 16 if words.size > 1 else 0))


def _number(value: ParameterValue | None) -> float | None:
    """A single numeric parameter value as float, else None."""
    if isinstance(value, int | float):
        return float(value)
    return None


def _text_value(value: ParameterValue | None) -> str:
    """A text parameter (first string of a list) stripped, "" when absent or not text."""
    if isinstance(value, list):
        value = value[0] if value and isinstance(value[0], str) else ""
    return value.strip() if isinstance(value, str) else ""


def _text(raw: bytes) -> str:
    stripped = raw.rstrip(b" \x00")
    try:
        return stripped.decode("utf-8")
    except UnicodeDecodeError:
        return stripped.decode("latin-1")


def _floats(raw: bytes, processor: int) -> np.ndarray:
    """float64 values of the float32 numbers in `raw`, in the processor's float format."""
    values = (
        _dec_to_ieee(np.frombuffer(raw, "<u4"))
        if processor == _DEC
        else np.frombuffer(raw, _endian(processor) + "f4")
    )
    with np.errstate(invalid="ignore"):  # signalling NaNs in damaged files
        return values.astype(np.float64)


def _dec_to_ieee(words: np.ndarray) -> np.ndarray:
    """DEC (VAX F) floats given as little-endian uint32 -> IEEE float32: swap 16-bit halves, divide by 4."""
    swapped = (words << np.uint32(16)) | (words >> np.uint32(16))
    with np.errstate(invalid="ignore", over="ignore"):
        return swapped.view(np.float32) / np.float32(4)


def _endian(processor: int) -> str:
    return ">" if processor == _MIPS else "<"


def _int8(byte: int) -> int:
    return byte - 256 if byte > 127 else byte
