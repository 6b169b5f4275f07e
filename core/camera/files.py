"""Camera files: our JSON (read and written) and OpenCV's YAML/XML calibration files (read).

JSON layout: ``{"format": "handmocap-camera", "version": 1, "name", "image_size": [w, h],
"camera_matrix": 3×3, "distortion": [...], "registered": bool, "rotation": 3×3 (mocap → camera),
"translation_mm": [3], "time_offset_s", "rate_ratio", "report": {...}}``. OpenCV files are those its
calibration sample writes (``camera_matrix``, ``distortion_coefficients``, ``image_width``,
``image_height``), with the common alternative key names and optional ``R``/``rvec`` and ``T``/``tvec``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

from core.camera.model import Camera, CameraClock
from core.errors import InputError
from core.io.durable import write_text_atomic

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
    """Write ``camera`` as JSON (durable write)."""
    write_text_atomic(path, json.dumps(camera_to_json(camera, report), indent=1) + "\n")


def load_camera(path: str | Path) -> Camera:
    """Read a camera from our JSON or an OpenCV YAML/XML calibration file; :class:`InputError` (one line)
    when the file is missing, too large or not a camera file."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as error:
        raise InputError(f"cannot read camera file {path}: {error.strerror or error}") from None
    if not path.is_file():
        raise InputError(f"camera file {path} is not a file")
    if size > MAX_FILE_BYTES:
        raise InputError(f"{path.name}: {size} bytes is too large for a camera file (limit {MAX_FILE_BYTES})")
    if path.suffix.lower() in OPENCV_SUFFIXES:
        return _load_opencv(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as error:
        raise InputError(f"{path.name}: not a camera JSON file ({type(error).__name__}: {error})") from None
    return camera_from_json(data, path.name)


def camera_from_json(data: object, source: str = "camera JSON") -> Camera:
    """A camera from the JSON object written by :func:`camera_to_json`."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{source}: not a {FORMAT} file (no \"format\": \"{FORMAT}\")")
    if data.get("version") != VERSION:
        raise InputError(f"{source}: camera file version {data.get('version')!r} is not supported (expected 1)")
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


def _load_opencv(path: Path) -> Camera:
    """A camera from an OpenCV ``FileStorage`` file (YAML or XML)."""
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_FORMAT_AUTO)
    except cv2.error as error:
        raise InputError(f"{path.name}: OpenCV cannot parse this calibration file "
                         f"({str(error).strip().splitlines()[-1][:200]})") from None
    try:
        if not storage.isOpened():
            raise InputError(f"{path.name}: OpenCV cannot open this calibration file")
        matrix = _node_matrix(storage, _MATRIX_KEYS)
        if matrix is None:
            raise InputError(f"{path.name}: no camera matrix (expected one of {', '.join(_MATRIX_KEYS)})")
        distortion = _node_matrix(storage, _DISTORTION_KEYS)
        width, height = _node_number(storage, "image_width"), _node_number(storage, "image_height")
        if width is None or height is None:
            raise InputError(f"{path.name}: no image_width/image_height")
        rotation = _node_matrix(storage, _ROTATION_KEYS)
        translation = _node_matrix(storage, _TRANSLATION_KEYS)
        try:
            pose_rotation: np.ndarray = np.eye(3)
            pose_translation, registered = np.zeros(3), False
            if rotation is not None and translation is not None:
                pose_rotation = (cv2.Rodrigues(rotation.reshape(3, 1))[0] if rotation.size == 3
                                 else rotation.reshape(3, 3))
                pose_translation, registered = translation.ravel(), True
            return Camera(matrix=matrix.reshape(3, 3), size=(_integer(width), _integer(height)),
                          distortion=np.zeros(0) if distortion is None else distortion.ravel(),
                          rotation=pose_rotation, translation=pose_translation, registered=registered,
                          name=path.stem[:200])
        except (ValueError, cv2.error) as error:
            raise InputError(f"{path.name}: invalid calibration values ({error})") from None
    finally:
        storage.release()


def _node_matrix(storage: cv2.FileStorage, keys: tuple[str, ...]) -> np.ndarray | None:
    """The first of ``keys`` holding a matrix (or a sequence of numbers), as a float array; None if absent."""
    for key in keys:
        node = storage.getNode(key)
        if node.empty():
            continue
        if node.isSeq():
            values = [node.at(index).real() for index in range(min(node.size(), 16))]
            return np.asarray(values, dtype=float)
        matrix = node.mat()
        if matrix is not None:
            return np.asarray(matrix, dtype=float)
    return None


def _node_number(storage: cv2.FileStorage, key: str) -> float | None:
    node = storage.getNode(key)
    return None if node.empty() or not (node.isInt() or node.isReal()) else float(node.real())
