"""Rigid objects of a labelling scene and the object spec JSON format.

A scene spec lists the rigid objects tracked next to the hands (Maycock et al. 2015 §III-A "Load
Models": cubes, spheres, cylinders with fixed marker positions, or rigid bodies made on the fly from
selected markers)::

    {"objects": [
        {"name": "cup", "type": "cylinder", "radius_mm": 40, "height_mm": 100,
         "markers": {"cup1": [40, 0, 30], "cup2": [0, 40, 10], "cup3": [-40, 0, -20]}},
        {"name": "block", "type": "box", "size_mm": [80, 60, 40],
         "markers": {"block1": [40, 0, 20], ...}},
        {"name": "ball", "type": "sphere", "radius_mm": 35, "markers": {...}},
        {"name": "tool", "type": "rigid", "markers": {"tool1": [0, 0, 0], "tool2": [52, 3, 0], ...}}
    ]}

Marker positions are mm in the object's own frame. Primitives are centred on the origin of that
frame: a box spans ``±size/2`` along its axes, a sphere has its centre at the origin, a cylinder's
axis is Z from ``-height/2`` to ``+height/2``. A primitive's markers must sit on (or just off, at most
:data:`SURFACE_TOLERANCE_MM`) its surface; the shape gives the oriented bounding box used to scale
the model during initialisation and is what viewers draw. A ``rigid`` object has no shape: its
markers alone define it (e.g. taken from markers an operator selected in one frame, see
:func:`rigid_body_from_points`). Every object needs at least 3 markers that are not collinear;
marker names must be unique over the whole scene.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.documents import read_document
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.input_schemas import SCENE_SPEC

OBJECT_TYPES = ("box", "sphere", "cylinder", "rigid")
#: largest distance (mm) of a primitive's marker centre from its surface (marker radius + base + slack)
SURFACE_TOLERANCE_MM = 25.0
#: smallest spread (mm) of an object's markers off their best line (collinear sets cannot be tracked)
MIN_SPREAD_MM = 2.0


@dataclass(frozen=True, eq=False)
class ObjectSpec:
    """One rigid object: ``marker_names (K,)``, ``marker_positions (K,3)`` mm in the object frame,
    ``kind`` one of :data:`OBJECT_TYPES`, ``dimensions`` the primitive's sizes in mm
    (``size_mm`` (3,) for a box, ``radius_mm`` for a sphere, ``radius_mm`` + ``height_mm`` for a cylinder)."""

    name: str
    kind: str
    marker_names: tuple[str, ...]
    marker_positions: np.ndarray
    dimensions: dict[str, float | list[float]] = field(default_factory=dict)

    def _length(self, key: str) -> float:
        """The single-number dimension ``key`` (mm): ``radius_mm`` or ``height_mm``."""
        value = self.dimensions[key]
        if isinstance(value, list):
            raise TypeError(f"object '{self.name}': '{key}' is not one number")
        return float(value)

    def surface_distance(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance (N,) mm of object-frame ``points (N,3)`` from the primitive's surface
        (zeros for a ``rigid`` object)."""
        points = np.asarray(points, dtype=float)
        if self.kind == "sphere":
            return np.abs(np.linalg.norm(points, axis=1) - self._length("radius_mm"))
        if self.kind == "box":
            half = 0.5 * np.asarray(self.dimensions["size_mm"], dtype=float)
            outside = np.maximum(np.abs(points) - half, 0.0)
            inside_depth = np.min(half - np.abs(points), axis=1)
            return np.where((outside > 0).any(axis=1), np.linalg.norm(outside, axis=1), inside_depth)
        if self.kind == "cylinder":
            radius, half_height = self._length("radius_mm"), 0.5 * self._length("height_mm")
            radial = np.linalg.norm(points[:, :2], axis=1) - radius
            axial = np.abs(points[:, 2]) - half_height
            outside = np.linalg.norm(np.stack([np.maximum(radial, 0.0), np.maximum(axial, 0.0)], axis=1), axis=1)
            return np.where((radial > 0) | (axial > 0), outside, np.minimum(-radial, -axial))
        return np.zeros(len(points))

    def box_extents(self) -> np.ndarray:
        """Full extents (3,) mm of the object's bounding box in its own frame (markers for ``rigid``)."""
        if self.kind == "box":
            return np.asarray(self.dimensions["size_mm"], dtype=float)
        if self.kind == "sphere":
            return np.full(3, 2.0 * self._length("radius_mm"))
        if self.kind == "cylinder":
            radius = self._length("radius_mm")
            return np.array([2.0 * radius, 2.0 * radius, self._length("height_mm")])
        return np.ptp(self.marker_positions, axis=0)

    def to_json(self) -> dict:
        entry: dict[str, object] = {"name": self.name, "type": self.kind}
        entry.update({key: ([float(v) for v in value] if isinstance(value, list) else float(value))
                      for key, value in self.dimensions.items()})
        entry["markers"] = {name: [round(float(v), 4) for v in position]
                            for name, position in zip(self.marker_names, self.marker_positions, strict=True)}
        return entry


def _positive(entry: dict, key: str, source: str, name: str) -> float:
    try:
        value = float(entry[key])
    except KeyError:
        raise InputError(f"{source}: object '{name}' needs '{key}'") from None
    except (TypeError, ValueError):
        raise InputError(f"{source}: object '{name}': '{key}' must be a number") from None
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{source}: object '{name}': '{key}' must be positive, got {entry[key]}")
    return value


def object_from_json(entry: dict, source: str = "scene spec") -> ObjectSpec:
    """Parse and validate one object entry (module docstring); :class:`InputError` with one clear line."""
    if not isinstance(entry, dict):
        raise InputError(f"{source}: every object must be a JSON object, got {type(entry).__name__}")
    name = str(entry.get("name", "")).strip()
    if not name:
        raise InputError(f"{source}: an object has no name")
    kind = str(entry.get("type", "rigid")).strip().lower()
    if kind not in OBJECT_TYPES:
        raise InputError(f"{source}: object '{name}' has unknown type '{kind}' (use {', '.join(OBJECT_TYPES)})")
    markers = entry.get("markers")
    if not isinstance(markers, dict) or len(markers) < 3:
        raise InputError(f"{source}: object '{name}' needs at least 3 markers as {{\"name\": [x, y, z]}}")
    try:
        positions = np.array([[float(v) for v in value] for value in markers.values()], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{source}: object '{name}': marker positions must be [x, y, z] numbers (mm)") from None
    if positions.shape != (len(markers), 3) or not np.isfinite(positions).all():
        raise InputError(f"{source}: object '{name}': marker positions must be finite [x, y, z] (mm)")
    centred = positions - positions.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    if singular[1] / np.sqrt(len(positions)) < MIN_SPREAD_MM:
        raise InputError(f"{source}: object '{name}': its markers are (nearly) collinear; a rigid pose "
                         "needs 3 markers off one line")
    dimensions: dict[str, float | list[float]] = {}
    if kind == "box":
        try:
            size = [float(v) for v in entry["size_mm"]]
        except KeyError:
            raise InputError(f"{source}: object '{name}' needs 'size_mm': [x, y, z]") from None
        except (TypeError, ValueError):
            raise InputError(f"{source}: object '{name}': 'size_mm' must be three numbers") from None
        if len(size) != 3 or not all(np.isfinite(v) and v > 0 for v in size):
            raise InputError(f"{source}: object '{name}': 'size_mm' must be three positive numbers")
        dimensions["size_mm"] = size
    elif kind == "sphere":
        dimensions["radius_mm"] = _positive(entry, "radius_mm", source, name)
    elif kind == "cylinder":
        dimensions["radius_mm"] = _positive(entry, "radius_mm", source, name)
        dimensions["height_mm"] = _positive(entry, "height_mm", source, name)
    spec = ObjectSpec(name, kind, tuple(str(key) for key in markers), positions, dimensions)
    distance = spec.surface_distance(positions)
    if distance.max(initial=0.0) > SURFACE_TOLERANCE_MM:
        worst = int(np.argmax(distance))
        raise InputError(f"{source}: object '{name}': marker '{spec.marker_names[worst]}' is "
                         f"{distance[worst]:.0f} mm from the {kind}'s surface (markers are given in the "
                         "object frame, primitives centred on its origin)")
    return spec


def scene_spec_from_json(data: object, source: str = "scene spec") -> list[ObjectSpec]:
    """The objects of a parsed scene spec ``{"objects": [...]}``; :class:`InputError` when malformed."""
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise InputError(f"{source}: a scene spec is a JSON object with an \"objects\" list")
    objects = [object_from_json(entry, source) for entry in data["objects"]]
    check_unique_names(objects, source)
    return objects


def check_unique_names(objects: list[ObjectSpec], source: str = "scene", reserved: Sequence[str] = ()) -> None:
    """Raise :class:`InputError` when two objects share a name or a marker name (or one is ``reserved``)."""
    names = [spec.name for spec in objects]
    duplicate = next((name for name in names if names.count(name) > 1), None)
    if duplicate:
        raise InputError(f"{source}: two objects are named '{duplicate}'")
    seen = {name.lower() for name in reserved}
    for spec in objects:
        for marker in spec.marker_names:
            if marker.lower() in seen:
                raise InputError(f"{source}: marker name '{marker}' of object '{spec.name}' is used twice "
                                 "in the scene")
            seen.add(marker.lower())


def load_scene_spec(path: str | Path) -> list[ObjectSpec]:
    """Read a scene spec JSON file (module docstring) into its objects."""
    path = Path(path)
    return scene_spec_from_json(read_document(path, "scene spec", SCENE_SPEC), path.name)


def save_scene_spec(objects: list[ObjectSpec], path: str | Path) -> None:
    """Write a scene spec JSON file durably (:mod:`core.io.durable`; WriteError naming the file on failure)."""
    write_text_atomic(path, json.dumps({"objects": [spec.to_json() for spec in objects]}, indent=2))


def rigid_body_from_points(name: str, marker_names: list[str], positions: np.ndarray) -> ObjectSpec:
    """A ``rigid`` object from markers selected in one frame: ``positions (K,3)`` mm world, K ≥ 3.
    Its frame is at the markers' centroid with the world's axes."""
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 2 or positions.shape[1] != 3 or len(positions) != len(marker_names):
        raise InputError(f"rigid body '{name}': give one [x, y, z] per marker")
    if not np.isfinite(positions).all():
        raise InputError(f"rigid body '{name}': every selected marker must be present in the frame")
    centred = positions - positions.mean(axis=0)
    return object_from_json({"name": name, "type": "rigid",
                             "markers": dict(zip(marker_names, centred.tolist(), strict=True))},
                            source=f"rigid body '{name}'")
