"""Landmark sets for scan calibration: the 20 named points picked on a scan, stored as JSON.

Format: ``{"units": "mm", "landmarks": {name: [x, y, z] or null}}`` with names from
:data:`core.model.template_mesh.LANDMARK_NAMES`; ``"units": "m"`` is accepted and converted to mm.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.documents import read_document
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.input_schemas import LANDMARKS
from handmocap.core.model.template_mesh import LANDMARK_NAMES

MIN_LANDMARKS = 6
_UNIT_SCALE = {"mm": 1.0, "m": 1000.0}


def validate_landmarks(landmarks: dict[str, np.ndarray | None], source: str = "landmarks"
                       ) -> dict[str, np.ndarray | None]:
    """All 20 names mapped to a position (3,) in mm or None; unknown names or fewer than
    :data:`MIN_LANDMARKS` given positions raise :class:`InputError`."""
    unknown = sorted(set(landmarks) - set(LANDMARK_NAMES))
    if unknown:
        raise InputError(f"{source}: unknown landmark names {', '.join(unknown)} "
                         f"(expected names such as {', '.join(LANDMARK_NAMES[:3])}, ...)")
    result: dict[str, np.ndarray | None] = {}
    for name in LANDMARK_NAMES:
        value = landmarks.get(name)
        if value is None:
            result[name] = None
            continue
        position = np.asarray(value, dtype=np.float64)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise InputError(f"{source}: landmark '{name}' must be three finite numbers or null")
        result[name] = position
    given = sum(position is not None for position in result.values())
    if given < MIN_LANDMARKS:
        raise InputError(f"{source}: only {given} landmarks given; at least {MIN_LANDMARKS} are needed")
    return result


def load_landmarks(path: str | Path) -> dict[str, np.ndarray | None]:
    """Read a landmark JSON file: every name of ``LANDMARK_NAMES`` -> position (3,) in mm or None."""
    path = Path(path)
    data = read_document(path, "landmark file", LANDMARKS)
    if not isinstance(data, dict) or not isinstance(data.get("landmarks"), dict):
        raise InputError(f"{path.name}: expected an object with a 'landmarks' object")
    units = data.get("units", "mm")
    if units not in _UNIT_SCALE:
        raise InputError(f"{path.name}: unsupported units '{units}' (use 'mm' or 'm')")
    try:
        scaled = {name: None if value is None else np.asarray(value, dtype=np.float64) * _UNIT_SCALE[units]
                  for name, value in data["landmarks"].items()}
    except (TypeError, ValueError):
        raise InputError(f"{path.name}: landmark positions must be [x, y, z] numbers or null") from None
    return validate_landmarks(scaled, path.name)


def save_landmarks(landmarks: dict[str, np.ndarray | None], path: str | Path) -> None:
    """Write a landmark set (positions in mm) as JSON through :mod:`core.io.durable`."""
    path = Path(path)
    checked = validate_landmarks(landmarks, path.name)
    positions = {name: None if value is None else [float(c) for c in value] for name, value in checked.items()}
    data = {"units": "mm", "landmarks": positions}
    write_text_atomic(path, json.dumps(data, indent=2))


def landmarks_from_truth(truth: dict) -> dict[str, np.ndarray | None]:
    """The exact landmark positions (mm) of a synthetic scan's ``truth`` (see ``synthetic_scan``)."""
    return {name: np.array(position) for name, position in zip(truth["landmark_names"], truth["landmarks"],
                                                               strict=True)}
