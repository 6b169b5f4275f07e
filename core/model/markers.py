"""Marker layouts (JSON) and markers resolved onto a hand model's skinned surface.

A layout names where each marker sits in a way that carries over to any hand model (template,
re-proportioned subject, calibrated scan, imported glTF) with the 16-joint skeleton:

* ``{"name": "index_tip", "between": ["index_dip", "index_tip"], "along": 0.75, "side": "dorsal",
  "offset_mm": 4.0}`` — the surface point reached from the bone axis point
  ``lerp(rest(a), rest(b), along)`` in the ``side`` direction of the first joint's rest frame
  (``dorsal``, ``palmar``, ``radial``, ``ulnar``, ``distal``, ``proximal``, or a vector in that frame);
  joint names are :data:`core.model.skeleton.JOINT_NAMES` plus ``<digit>_tip``;
* ``{"name": "m3", "vertex": 1234, "offset_mm": 4.0}`` — a mesh vertex (optimised layouts).

``offset_mm`` lifts the marker centre off the skin along the surface normal (marker radius + base).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.documents import read_document
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.input_schemas import LAYOUT
from handmocap.core.io.resources import resource_path
from handmocap.core.model.hand_model import HandModel
from handmocap.core.model.kinematics import ANCESTOR, points_and_jacobian_kernel, skinned_points_kernel
from handmocap.core.model.skeleton import DIGITS, JOINT_NAMES

LAYOUT_DIR = resource_path("layouts")
#: largest layout or lab template file (bytes; a two-hand template with its statistics is about 100 kB)
MAX_LAYOUT_BYTES = 16_000_000

#: direction names in a joint's rest frame (x = radial-pointing flexion axis, y = bone, z = palmar)
SIDE_DIRECTIONS = {
    "dorsal": (0.0, 0.0, -1.0), "palmar": (0.0, 0.0, 1.0), "radial": (1.0, 0.0, 0.0),
    "ulnar": (-1.0, 0.0, 0.0), "distal": (0.0, 1.0, 0.0), "proximal": (0.0, -1.0, 0.0),
}


@dataclass(frozen=True)
class MarkerSpec:
    """Where one marker sits; see the module docstring for the two forms."""

    name: str
    between: tuple[str, str] | None = None
    along: float = 0.5
    side: str | tuple[float, float, float] = "dorsal"
    vertex: int | None = None
    offset_mm: float = 4.0

    @property
    def joints(self) -> tuple[str, str]:
        """The two joints a ray-placed marker sits between (ValueError for a marker on a vertex)."""
        if self.between is None:
            raise ValueError(f"marker '{self.name}' sits on a vertex, not between two joints")
        return self.between

    def to_json(self) -> dict:
        if self.vertex is not None:
            return {"name": self.name, "vertex": int(self.vertex), "offset_mm": self.offset_mm}
        return {"name": self.name, "between": list(self.joints), "along": self.along,
                "side": self.side if isinstance(self.side, str) else list(self.side),
                "offset_mm": self.offset_mm}


@dataclass(frozen=True)
class MarkerLayout:
    """A named set of markers."""

    name: str
    markers: tuple[MarkerSpec, ...]
    description: str = ""

    @property
    def names(self) -> list[str]:
        return [marker.name for marker in self.markers]

    def to_json(self) -> dict:
        return {"name": self.name, "description": self.description,
                "markers": [marker.to_json() for marker in self.markers]}

    @classmethod
    def from_json(cls, data: dict, source: str = "layout") -> MarkerLayout:
        """Parse and validate a layout dictionary; raises :class:`InputError` with one clear line."""
        try:
            markers = tuple(_spec_from_json(entry) for entry in data["markers"])
            layout = cls(name=str(data.get("name", source)), markers=markers,
                         description=str(data.get("description", "")))
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(f"{source}: not a marker layout ({error})") from error
        if not markers:
            raise InputError(f"{source}: the layout has no markers")
        if len(set(layout.names)) != len(markers):
            raise InputError(f"{source}: marker names must be unique")
        return layout


def _spec_from_json(entry: dict) -> MarkerSpec:
    if "vertex" in entry:
        return MarkerSpec(name=str(entry["name"]), vertex=int(entry["vertex"]),
                          offset_mm=float(entry.get("offset_mm", 4.0)))
    between = tuple(entry["between"])
    for joint in between:
        if joint not in JOINT_NAMES and joint not in {f"{d}_tip" for d in DIGITS}:
            raise ValueError(f"unknown joint '{joint}' in marker '{entry['name']}'")
    side = entry.get("side", "dorsal")
    if isinstance(side, str) and side not in SIDE_DIRECTIONS:
        raise ValueError(f"unknown side '{side}' in marker '{entry['name']}'")
    direction = side if isinstance(side, str) else tuple(float(v) for v in side)
    if not isinstance(direction, str) and len(direction) != 3:
        raise ValueError(f"the side of marker '{entry['name']}' must be a name or 3 numbers")
    return MarkerSpec(name=str(entry["name"]), between=(between[0], between[1]),
                      along=float(entry.get("along", 0.5)), side=direction,
                      offset_mm=float(entry.get("offset_mm", 4.0)))


_EXTRA_LAYOUT_DIRS: list[Path] = []


def add_layout_folder(folder: str | Path) -> None:
    """Also find layouts by name in ``folder`` (e.g. an open session's ``layouts``); searched before
    the shipped layouts, most recently added first."""
    folder = Path(folder)
    if folder in _EXTRA_LAYOUT_DIRS:
        _EXTRA_LAYOUT_DIRS.remove(folder)
    _EXTRA_LAYOUT_DIRS.insert(0, folder)


def remove_layout_folder(folder: str | Path) -> None:
    """Stop finding layouts in ``folder``."""
    if Path(folder) in _EXTRA_LAYOUT_DIRS:
        _EXTRA_LAYOUT_DIRS.remove(Path(folder))


def layout_folders() -> list[Path]:
    """Where layouts are looked for by name: the added folders, most recent first, then the shipped ones."""
    return [*_EXTRA_LAYOUT_DIRS, LAYOUT_DIR]


def layout_names() -> list[str]:
    """Names of the layouts shipped in ``resources/layouts`` and in the added folders."""
    return sorted({path.stem for folder in layout_folders() for path in folder.glob("*.json")})


def marker_columns(available: list[str], wanted: list[str]) -> np.ndarray:
    """Index in ``available`` of each name in ``wanted`` (case- and space-insensitive), -1 where
    missing, ``(len(wanted),)``: how take columns are matched to layout markers everywhere."""
    lookup = {name.strip().lower(): index for index, name in enumerate(available)}
    return np.array([lookup.get(name.strip().lower(), -1) for name in wanted], dtype=np.int64)


def best_layout_for(marker_names: list[str], minimum_matches: int = 3) -> str | None:
    """The shipped layout sharing the most marker names with a take (case-insensitive), or None when
    none shares at least ``minimum_matches``."""
    matches = {layout: int((marker_columns(marker_names, load_layout(layout).names) >= 0).sum())
               for layout in layout_names()}
    best = max(matches, key=lambda layout: matches[layout], default=None)
    return best if best is not None and matches[best] >= minimum_matches else None


def load_layout(name_or_path: str | Path) -> MarkerLayout:
    """A shipped layout by name (``dense``, ``glove-13``, ``grasp-4``) or a layout JSON file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = next((folder / f"{name_or_path}.json" for folder in layout_folders()
                     if (folder / f"{name_or_path}.json").exists()), LAYOUT_DIR / f"{name_or_path}.json")
        if not path.exists():
            raise InputError(f"unknown layout '{name_or_path}' (available: {', '.join(layout_names())})")
    data = read_document(path, "marker layout", LAYOUT, max_bytes=MAX_LAYOUT_BYTES)
    return MarkerLayout.from_json(data, source=path.name)


def save_layout(layout: MarkerLayout, path: str | Path) -> None:
    """Write a layout JSON file durably (:mod:`core.io.durable`; WriteError naming the file on failure)."""
    write_text_atomic(path, json.dumps(layout.to_json(), indent=2))


@dataclass(frozen=True, eq=False)
class MarkerSet:
    """A layout resolved on one hand model: everything the IK needs per marker.

    ``vertex (M,)`` anchor vertex, ``rest_positions (M,3)`` mm, ``influence_joints (M,4)``,
    ``influence_weights (M,4)`` (the anchor vertex's skin weights), ``local_points (M,4,3)``: the rest
    position in each influence joint's rest frame.
    """

    names: list[str]
    vertex: np.ndarray
    rest_positions: np.ndarray
    influence_joints: np.ndarray
    influence_weights: np.ndarray
    local_points: np.ndarray
    offsets_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def subset(self, indices: np.ndarray) -> MarkerSet:
        """The markers at ``indices`` (e.g. the ones observed in a frame)."""
        return MarkerSet([self.names[i] for i in indices], self.vertex[indices],
                         self.rest_positions[indices], self.influence_joints[indices],
                         self.influence_weights[indices], self.local_points[indices],
                         self.offsets_mm[indices])


def joint_rest_point(model: HandModel, joint: str) -> np.ndarray:
    """Rest position ``(3,)`` mm of the skeleton joint named ``joint``, or of a digit tip (``"<digit>_tip"``)."""
    if joint.endswith("_tip"):
        return model.skeleton.tip_positions[DIGITS.index(joint[:-4])]
    return model.skeleton.rest_positions[JOINT_NAMES.index(joint)]


def frame_joint_of(joint: str) -> int:
    """Joint whose rest frame orients the ``side`` of a marker placed from ``joint``: the distal
    joint for a tip, the middle finger's MCP for the wrist (the palm's frame), else the joint itself."""
    if joint.endswith("_tip"):
        return 3 + 3 * DIGITS.index(joint[:-4])
    if joint == "wrist":
        return JOINT_NAMES.index("middle_mcp")
    return JOINT_NAMES.index(joint)


def _surface_vertex(model: HandModel, spec: MarkerSpec) -> int:
    """The vertex where the ray from the bone axis point in the ``side`` direction leaves the skin."""
    first, second = spec.joints
    frame = model.skeleton.rest_rotations[frame_joint_of(first)]
    origin = (1.0 - spec.along) * joint_rest_point(model, first) + spec.along * joint_rest_point(model, second)
    local = np.array(SIDE_DIRECTIONS[spec.side] if isinstance(spec.side, str) else spec.side, float)
    if model.side == "left":
        local[0] = -local[0]  # mirrored frames keep x on the right hand's radial side: flip it back
    direction = frame @ (local / np.linalg.norm(local))
    relative = model.vertices - origin
    depth = relative @ direction
    lateral = np.linalg.norm(relative - depth[:, None] * direction, axis=1)
    facing = model.vertex_normals @ direction > 0.3
    # nearest to the ray, in front of the axis point, on the side facing the ray; the outermost wins
    score = np.where((depth > 0) & facing, lateral - 0.05 * depth, np.inf)
    if not np.isfinite(score).any():
        # the axis point lies outside the skin (e.g. beyond a fingertip): nearest skin facing that way
        score = np.where(facing, np.linalg.norm(relative, axis=1), np.inf)
    if not np.isfinite(score).any():
        raise InputError(f"marker '{spec.name}': no skin in that direction on model '{model.name}'")
    return int(np.argmin(score))


def resolve_layout(model: HandModel, layout: MarkerLayout) -> MarkerSet:
    """Place the layout's markers on ``model``'s surface (rest pose)."""
    vertices = np.array([spec.vertex if spec.vertex is not None else _surface_vertex(model, spec)
                         for spec in layout.markers], dtype=np.int64)
    if vertices.max() >= len(model.vertices) or vertices.min() < 0:
        raise InputError(f"layout '{layout.name}': vertex index outside model '{model.name}'")
    offsets = np.array([spec.offset_mm for spec in layout.markers])
    rest = model.vertices[vertices] + model.vertex_normals[vertices] * offsets[:, None]
    joints = np.ascontiguousarray(model.skin_joints[vertices])
    weights = np.ascontiguousarray(model.skin_weights[vertices], dtype=np.float64)
    return MarkerSet(layout.names, vertices, rest, joints, weights,
                     model.chain.local_coordinates(rest, joints), offsets)


def marker_positions(model: HandModel, markers: MarkerSet, theta: np.ndarray) -> np.ndarray:
    """Marker centres (M,3) in mm at ``theta (26,)``."""
    rotations, positions = model.chain.joint_transforms(theta)
    return skinned_points_kernel(rotations, positions, markers.influence_joints,
                                 markers.influence_weights, markers.local_points)


def marker_positions_batch(model: HandModel, markers: MarkerSet, thetas: np.ndarray) -> np.ndarray:
    """Marker centres (F,M,3) in mm for ``thetas (F,26)``."""
    return np.stack([marker_positions(model, markers, theta) for theta in np.atleast_2d(thetas)])


def marker_jacobian(model: HandModel, markers: MarkerSet, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Marker centres (M,3) and their Jacobian (M,3,26) at ``theta`` (convention: kinematics module)."""
    chain = model.chain
    return points_and_jacobian_kernel(np.ascontiguousarray(theta, dtype=np.float64), chain.relative_rest,
                                      chain.offsets, chain.abduction_sign, ANCESTOR,
                                      markers.influence_joints, markers.influence_weights,
                                      markers.local_points)
