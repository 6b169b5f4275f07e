"""What a printed marker placement sheet shows, computed without any drawing library.

The sheet shows the hand in its rest pose from the back and from the thumb side, each marker as a
numbered dot, and a list of the markers: number, name and where it sits (the segment it moves with
and its distance from the joint at the segment's base, in mm). :func:`placement_sheet` projects the
template mesh orthographically for both views (back faces culled, triangles ordered far to near for
painting, Lambert shading), marks markers hidden behind the skin in a view, and leaves the drawing to
the GUI layer (``widgets/placement_sheet.py``), which paints it on an A4 page (PNG or PDF).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np

from handmocap.core.camera.render import fill_triangles
from handmocap.core.model import HandModel, MarkerLayout, resolve_layout
from handmocap.core.model.skeleton import DIGITS, JOINT_NAMES, JOINT_PARENTS

#: what moves with each joint, in the words a capture operator uses
SEGMENT_NAMES: dict[str, str] = {"wrist": "back of the hand", "thumb_cmc": "thumb metacarpal",
                                 "thumb_mcp": "thumb proximal phalanx", "thumb_ip": "thumb distal phalanx"}
for _digit in DIGITS[1:]:
    SEGMENT_NAMES.update({f"{_digit}_mcp": f"{_digit} proximal phalanx", f"{_digit}_pip": f"{_digit} middle phalanx",
                          f"{_digit}_dip": f"{_digit} distal phalanx"})
#: short marker names per segment, used to name optimised markers
SEGMENT_SHORT_NAMES: dict[str, str] = {"wrist": "hand_back", "thumb_cmc": "thumb_meta", "thumb_mcp": "thumb_prox",
                                       "thumb_ip": "thumb_dist"}
for _digit in DIGITS[1:]:
    SEGMENT_SHORT_NAMES.update({f"{_digit}_mcp": f"{_digit}_prox", f"{_digit}_pip": f"{_digit}_mid",
                                f"{_digit}_dip": f"{_digit}_dist"})
LIGHT_WEIGHT = 0.75      # share of Lambert shading in a triangle's brightness (the rest is ambient)


@dataclass(frozen=True)
class SheetView:
    """One orthographic view. ``points (V, 2)`` mm on the page plane (x right, y up), ``depth (V,)`` mm
    away from the viewer, ``shades (V,)`` brightness in [0, 1], ``faces (T, 3)`` the triangles facing
    the viewer; ``markers (k, 2)`` mm; ``visible (k,)`` whether each marker is unhidden in this view;
    ``bounds`` ``(xmin, ymin, xmax, ymax)`` mm."""

    title: str
    points: np.ndarray
    depth: np.ndarray
    shades: np.ndarray
    faces: np.ndarray
    markers: np.ndarray
    visible: np.ndarray
    bounds: tuple[float, float, float, float]


@dataclass(frozen=True)
class PlacementRow:
    """One marker in the list: ``number`` (1-based, as drawn), ``name``, ``segment`` it moves with and
    ``location`` in words."""

    number: int
    name: str
    segment: str
    location: str


@dataclass(frozen=True)
class PlacementSheet:
    """Everything printed: ``title``, ``subtitle`` (marker count, description), ``date`` (ISO),
    the ``views`` (back, thumb side) and the ``rows`` of the marker list."""

    title: str
    subtitle: str
    date: str
    views: tuple[SheetView, ...]
    rows: tuple[PlacementRow, ...]


def dominant_joints(model: HandModel, vertices: np.ndarray) -> np.ndarray:
    """The joint index ``(k,)`` with the largest skin weight of each vertex (the segment it rides on)."""
    vertices = np.asarray(vertices, dtype=np.int64)
    return model.skin_joints[vertices, np.argmax(model.skin_weights[vertices], axis=1)].astype(np.int64)


def segment_marker_names(model: HandModel, vertices: np.ndarray) -> list[str]:
    """Anatomical marker names for markers on ``vertices (k,)``: the segment's short name
    (``index_dist``, ``hand_back``...), numbered ``_2``, ``_3`` when a segment carries several."""
    names: list[str] = []
    for joint in dominant_joints(model, vertices):
        base = SEGMENT_SHORT_NAMES[JOINT_NAMES[joint]]
        count = sum(1 for name in names if name == base or name.startswith(base + "_"))
        names.append(base if count == 0 else f"{base}_{count + 1}")
    return names


def _surface_side(model: HandModel, vertex: int) -> str:
    """Which face of the hand a vertex is on: dorsal, palmar, or the thumb/little-finger side."""
    normal = model.vertex_normals[vertex]
    facing = float(normal @ model.back_direction)
    if facing > 0.5:
        return "dorsal"
    if facing < -0.5:
        return "palmar"
    thumb_side = np.sign(model.skeleton.tip_positions[0, 0] - model.skeleton.rest_positions[0, 0]) or -1.0
    return "thumb side" if normal[0] * thumb_side > 0 else "little-finger side"


def _location(model: HandModel, joint: int, vertex: int, point: np.ndarray) -> str:
    """Where ``point`` (rest pose, mm) on ``vertex`` sits on the segment of ``joint``, in words."""
    name = JOINT_NAMES[joint]
    side = _surface_side(model, vertex)
    if name == "wrist":
        knuckle = model.skeleton.rest_positions[JOINT_NAMES.index("middle_mcp")]
        thumb_side = np.sign(model.skeleton.tip_positions[0, 0] - model.skeleton.rest_positions[0, 0]) or -1.0
        offset = point - knuckle
        proximal = -float(offset[1])
        towards_thumb = float(offset[0] * thumb_side)
        lateral = (f"{abs(towards_thumb):.0f} mm to the {'thumb' if towards_thumb > 0 else 'little-finger'} side"
                   if abs(towards_thumb) >= 5 else "in line with the middle finger")
        return f"hand back: {proximal:.0f} mm proximal of the middle knuckle, {lateral}"
    origin = model.skeleton.rest_positions[joint]
    children = np.flatnonzero(joint == JOINT_PARENTS)
    end = (model.skeleton.rest_positions[children[0]] if len(children)
           else model.skeleton.tip_positions[DIGITS.index(name.split("_")[0])])
    axis = end - origin
    length = float(np.linalg.norm(axis))
    along = float((point - origin) @ axis / max(length, 1e-9))
    joint_label = name.split("_")[1].upper()
    return f"{SEGMENT_NAMES[name]}: {max(along, 0.0):.0f} mm distal of the {joint_label} joint, {side}"


def _view(model: HandModel, title: str, right: np.ndarray, up: np.ndarray, markers: np.ndarray) -> SheetView:
    """Orthographic view with page axes ``right`` and ``up`` (unit, world); the viewer looks along
    ``forward = up × right`` (from the side ``-forward``)."""
    forward = np.cross(up, right)               # into the page
    vertices = model.vertices
    corners = vertices[model.faces]                                  # (T, 3, 3)
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facing = face_normals @ forward < 0.0                            # towards the viewer
    light = -forward + 0.35 * up - 0.25 * right
    light /= np.linalg.norm(light)
    shades = (1.0 - LIGHT_WEIGHT) + LIGHT_WEIGHT * np.clip(model.vertex_normals @ light, 0.0, 1.0)
    project = np.stack([right, up], axis=1)                          # (3, 2)
    points = vertices @ project
    marker_points = markers @ project
    visible = _unhidden(corners[facing], marker_points, markers @ forward, project, forward)
    low, high = points.min(axis=0), points.max(axis=0)
    return SheetView(title, points, vertices @ forward, shades, np.ascontiguousarray(model.faces[facing]),
                     marker_points, visible, (float(low[0]), float(low[1]), float(high[0]), float(high[1])))


def rasterise_view(view: SheetView, pixels_per_mm: float, scale: float) -> tuple[np.ndarray, tuple[float, float]]:
    """The view's skin as a shade image ``(H, W)`` float32 in [0, 1] (NaN outside the hand), drawn at
    ``scale`` page mm per model mm and ``pixels_per_mm`` page pixels per page mm, and the page position
    (mm, relative to the image's top-left corner) of the model point ``(0, 0)``."""
    xmin, ymin, xmax, ymax = view.bounds
    factor = scale * pixels_per_mm                                   # pixels per model mm
    width = int(np.ceil((xmax - xmin) * factor)) + 2
    height = int(np.ceil((ymax - ymin) * factor)) + 2
    pixels = np.empty_like(view.points)
    pixels[:, 0] = (view.points[:, 0] - xmin) * factor + 1.0
    pixels[:, 1] = (ymax - view.points[:, 1]) * factor + 1.0
    image = np.full((height, width), np.nan, dtype=np.float32)      # Gouraud-shaded skin, NaN = background
    fill_triangles(pixels, view.depth, view.faces, False, 0.5, 1e-9, -np.inf, np.full((height, width), np.inf),
                   np.full((height, width), -1, dtype=np.int32), view.shades, image)
    origin = ((1.0 - xmin * factor) / pixels_per_mm, (1.0 + ymax * factor) / pixels_per_mm)
    return image, origin


def _unhidden(front: np.ndarray, points: np.ndarray, depths: np.ndarray, project: np.ndarray,
              forward: np.ndarray) -> np.ndarray:
    """Whether each marker ``points (k, 2)`` at ``depths (k,)`` lies in front of every front-facing
    triangle ``front (T, 3, 3)`` that covers it on the page, ``(k,)``."""
    flat = front @ project                                           # (T, 3, 2)
    tri_depth = front @ forward                                      # (T, 3)
    a, b, c = flat[:, 0], flat[:, 1], flat[:, 2]
    visible = np.ones(len(points), dtype=bool)
    v0, v1 = b - a, c - a
    denominator = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    valid = np.abs(denominator) > 1e-12
    for index, (point, depth) in enumerate(zip(points, depths, strict=True)):
        v2 = point - a
        u = np.where(valid, (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / np.where(valid, denominator, 1.0), -1.0)
        v = np.where(valid, (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / np.where(valid, denominator, 1.0), -1.0)
        inside = (u >= 0) & (v >= 0) & (u + v <= 1)
        surface = (1 - u - v) * tri_depth[:, 0] + u * tri_depth[:, 1] + v * tri_depth[:, 2]
        visible[index] = not np.any(inside & (surface < depth - 2.0))   # 2 mm: the marker's own skin
    return visible


def placement_sheet(model: HandModel, layout: MarkerLayout, date: _dt.date | None = None) -> PlacementSheet:
    """The placement sheet of ``layout`` on ``model`` (rest pose): back view, thumb-side view and the
    marker list. ``date`` defaults to today."""
    markers = resolve_layout(model, layout)
    skin_points = model.vertices[markers.vertex]                       # where the marker base sits
    thumb_side = np.sign(model.skeleton.tip_positions[0, 0] - model.skeleton.rest_positions[0, 0]) or -1.0
    up = np.array([0.0, 1.0, 0.0])                                   # fingers up on the page
    # page right = forward × up, so that neither view is a mirror image
    back_forward = -np.asarray(model.back_direction, dtype=float)      # the viewer faces the back
    back = _view(model, "Back of the hand", np.cross(back_forward, up), up, skin_points)
    side_forward = np.array([-thumb_side, 0.0, 0.0])                 # the viewer stands on the thumb side
    side = _view(model, "Thumb side", np.cross(side_forward, up), up, skin_points)
    joints = dominant_joints(model, markers.vertex)
    rows = tuple(PlacementRow(number + 1, name, SEGMENT_NAMES[JOINT_NAMES[joint]],
                              _location(model, int(joint), int(markers.vertex[number]), markers.rest_positions[number]))
                 for number, (name, joint) in enumerate(zip(markers.names, joints, strict=True)))
    when = (date or _dt.date.today()).isoformat()
    description = layout.description if len(layout.description) <= 170 else layout.description[:169] + "…"
    subtitle = f"{len(rows)} markers on the {model.side} hand" + (f" — {description}" if description else "")
    return PlacementSheet(f"Marker placement: {layout.name}", subtitle, when, (back, side), rows)
