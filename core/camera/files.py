"""Camera files: our JSON and OpenCV's YAML/XML calibration files, read and written.

JSON layout: ``{"format": "handmocap-camera", "version": 1, "name", "image_size": [w, h],
"camera_matrix": 3×3, "distortion": [...], "registered": bool, "rotation": 3×3 (mocap → camera),
"translation_mm": [3], "time_offset_s", "rate_ratio", "report": {...}}``. OpenCV files are those its
calibration sample writes (``camera_matrix``, ``distortion_coefficients``, ``image_width``,
``image_height``), with the common alternative key names and optional ``R``/``rvec`` and ``T``/``tvec``
(and ``time_offset_s``, ``rate_ratio``, which we write too). They are read by our own bounded reader
(:mod:`core.camera.opencv_storage`), never by ``cv2.FileStorage``, and written in OpenCV's format, so that
OpenCV reads our files.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

from handmocap.core.camera.model import Camera, CameraClock
from handmocap.core.camera.opencv_storage import read_storage, storage_text
from handmocap.core.errors import InputError
from handmocap.core.io.documents import check_document, read_document, read_limited
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.input_schemas import CAMERA

FORMAT = "handmocap-camera"
VERSION = 1
#: a camera file is a few kB; anything larger is not one
MAX_FILE_BYTES = 1_000_000
OPENCV_SUFFIXES = (".yaml", ".yml", ".xml")

_MATRIX_KEYS = ("camera_matrix", "cameraMatrix", "K", "intrinsic_matrix", "M")
_DISTORTION_KEYS = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "distortion", "D")
_ROTATION_KEYS = ("R", "rotation", "rvec")
_TRANSLATION_KEYS = ("T", "translation", "tvec")


def camera_to_json(camera: Camera, report: dict | None = None) -> dict:
    """The JSON object of ``camera`` (and a calibration ``report`` of plain numbers, if any)."""
    data = {
        "format": FORMAT, "version": VERSION, "name": camera.name, "image_size": list(camera.size),
        "camera_matrix": camera.matrix.tolist(), "distortion": camera.distortion.tolist(),
        "registered": camera.registered, "rotation": camera.rotation.tolist(),
        "translation_mm": camera.translation.tolist(), "time_offset_s": camera.clock.offset_s,
        "rate_ratio": camera.clock.rate_ratio,
    }
    if report:
        data["report"] = report
    return data


def save_camera(camera: Camera, path: str | Path, report: dict | None = None) -> None:
    """Write ``camera`` (durable write): as OpenCV's YAML or XML for a ``.yaml``/``.yml``/``.xml`` path (the
    calibration sample's keys, plus ``R``, ``T`` and the clock when registered; no report), else as JSON."""
    path = Path(path)
    if path.suffix.lower() in OPENCV_SUFFIXES:
        write_text_atomic(path, camera_storage_text(camera, xml=path.suffix.lower() == ".xml"))
    else:
        write_text_atomic(path, json.dumps(camera_to_json(camera, report), indent=1) + "\n")


def camera_storage_text(camera: Camera, xml: bool = False) -> str:
    """``camera`` as the text of an OpenCV FileStorage file (YAML, or XML when ``xml``)."""
    entries: dict[str, object] = {
        "image_width": int(camera.size[0]), "image_height": int(camera.size[1]),
        "camera_matrix": camera.matrix, "distortion_coefficients": camera.distortion.reshape(1, -1)}
    if camera.registered:
        entries |= {"R": camera.rotation, "T": camera.translation.reshape(3, 1),
                    "time_offset_s": float(camera.clock.offset_s), "rate_ratio": float(camera.clock.rate_ratio)}
    return storage_text(entries, xml)


def load_camera(path: str | Path) -> Camera:
    """Read a camera from our JSON or an OpenCV YAML/XML calibration file; :class:`InputError` (one line)
    when the file is missing, too large or not a camera file."""
    path = Path(path)
    if path.suffix.lower() in OPENCV_SUFFIXES:
        data = read_limited(path, "camera file", MAX_FILE_BYTES)
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as error:
            raise InputError(f"{path.name}: not an OpenCV calibration file (not UTF-8 text: byte "
                             f"{error.start})") from None
        return _load_opencv(path, read_storage(path, text))
    return camera_from_json(read_document(path, "camera file", max_bytes=MAX_FILE_BYTES), path.name)


def camera_from_json(data: object, source: str = "camera JSON") -> Camera:
    """A camera from the JSON object written by :func:`camera_to_json`."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{source}: not a {FORMAT} file (no \"format\": \"{FORMAT}\")")
    if data.get("version") != VERSION:
        raise InputError(f"{source}: camera file version {str(data.get('version'))[:20]!r} is not supported "
                         "(expected 1)")
    check_document(data, CAMERA, source, "camera file")
    try:
        width, height = (_integer(v) for v in data["image_size"])
        clock = CameraClock(float(data.get("time_offset_s", 0.0)), float(data.get("rate_ratio", 1.0)))
        return Camera(
            matrix=_array(data["camera_matrix"], (3, 3)), distortion=_array(data.get("distortion", []), None),
            size=(width, height), rotation=_array(data.get("rotation", np.eye(3).tolist()), (3, 3)),
            translation=_array(data.get("translation_mm", [0.0, 0.0, 0.0]), (3,)), clock=clock,
            registered=bool(data.get("registered", False)), name=str(data.get("name", "camera"))[:200])
    except InputError as error:
        raise InputError(f"{source}: {error}") from None
    except (KeyError, TypeError, ValueError, OverflowError) as error:
        raise InputError(f"{source}: invalid camera file ({type(error).__name__}: {error})") from None


def _integer(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or value != int(value):
        raise ValueError(f"image size must be whole numbers, got {value!r}")
    return int(value)


def _array(value: object, shape: tuple[int, ...] | None) -> np.ndarray:
    """A finite float array of ``shape`` (any 1-D length when None) from nested lists."""
    array = np.asarray(value, dtype=float)
    if shape is None:
        array = array.ravel()
    elif array.shape != shape:
        raise ValueError(f"expected shape {shape}, got {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError("values must be finite numbers")
    return array


def _load_opencv(path: Path, storage: dict) -> Camera:
    """A camera from the top-level mapping of an OpenCV FileStorage file (YAML or XML)."""
    matrix = _node_matrix(storage, _MATRIX_KEYS, path.name, (9,))
    if matrix is None:
        raise InputError(f"{path.name}: no camera matrix (expected one of {', '.join(_MATRIX_KEYS)})")
    distortion = _node_matrix(storage, _DISTORTION_KEYS, path.name, (0, 4, 5, 8, 12, 14))
    width, height = _node_number(storage, "image_width", path.name), _node_number(storage, "image_height", path.name)
    if width is None or height is None:
        raise InputError(f"{path.name}: no image_width/image_height")
    rotation = _node_matrix(storage, _ROTATION_KEYS, path.name, (3, 9))
    translation = _node_matrix(storage, _TRANSLATION_KEYS, path.name, (3,))
    offset = _node_number(storage, "time_offset_s", path.name)
    ratio = _node_number(storage, "rate_ratio", path.name)
    try:
        pose_rotation: np.ndarray = np.eye(3)
        pose_translation, registered = np.zeros(3), False
        if rotation is not None and translation is not None:
            pose_rotation = (cv2.Rodrigues(rotation.reshape(3, 1))[0] if rotation.size == 3
                             else rotation.reshape(3, 3))
            pose_translation, registered = translation.ravel(), True
        clock = CameraClock(0.0 if offset is None else offset, 1.0 if ratio is None else ratio)
        return Camera(matrix=matrix.reshape(3, 3), size=(_integer(width), _integer(height)),
                      distortion=distortion.ravel() if distortion is not None else np.zeros(0),
                      rotation=pose_rotation, translation=pose_translation, registered=registered,
                      clock=clock, name=path.stem[:200])
    except InputError as error:
        raise InputError(f"{path.name}: {error}") from None
    except (ValueError, OverflowError, cv2.error) as error:
        raise InputError(f"{path.name}: invalid calibration values ({str(error).strip().splitlines()[-1][:160]})"
                         ) from None


def _node_matrix(storage: dict, keys: tuple[str, ...], source: str, sizes: tuple[int, ...]) -> np.ndarray | None:
    """The first of ``keys`` holding a matrix or a list of numbers, as a finite float array of one of
    ``sizes`` values; None if absent."""
    for key in keys:
        if key not in storage:
            continue
        value = storage[key]
        if isinstance(value, list) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            value = np.asarray(value, dtype=float)
        if not isinstance(value, np.ndarray):
            raise InputError(f"{source}: '{key}' must be a matrix or a list of numbers")
        if value.size not in sizes:
            raise InputError(f"{source}: '{key}' has {value.size} values (expected "
                             f"{' or '.join(str(size) for size in sizes)})")
        if not np.isfinite(value).all():
            raise InputError(f"{source}: '{key}' holds a value that is not a finite number")
        return value
    return None


def _node_number(storage: dict, key: str, source: str) -> float | None:
    value = storage.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{source}: '{key}' must be a finite number")
    return float(value)
