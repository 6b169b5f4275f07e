"""The generated template hand: implicit surface around the rest skeleton, meshed and rigged.

Pipeline of :func:`build_template`:

1. A signed distance field (mm, negative inside) built from the rest skeleton: one tapered tube per
   digit (elliptical cross-section, flattened dorsal-palmar, knuckle bumps, fleshy fingertip pad,
   flattened nail side, rounded tip), a rounded slab for the palm that continues into a capped
   forearm stub, thenar and hypothenar pads, knuckle bumps and inter-digital webs, joined with a
   polynomial smooth minimum. Adjacent fingers are joined with a hard minimum and their lateral radii
   are reduced where needed, so that they stay separated at rest.
2. ``skimage.measure.marching_cubes`` on a grid whose voxel size is tuned to give about
   ``target_vertices`` vertices, the largest connected component, outward orientation, Taubin
   smoothing, then tangential relaxation with re-projection onto the implicit surface (even
   triangles, no voxel steps); the result is checked to be a closed genus-0 2-manifold.
3. Linear blend skinning weights: each vertex is owned by its nearest bone segment (rigid core,
   weight exactly 1) and blends with a smooth step between a joint's parent and the joint inside
   ±0.25 segment length around it; ownership seams (thenar / palm, between finger bases) are relaxed
   by a short harmonic diffusion.
4. 20 landmarks, the back-of-hand direction and the hand length.

Regenerate the stored template with ``handmocap template build`` (:func:`write_default_template`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:   # scipy.sparse and scikit-image are imported when a template is built, not at start-up
    from scipy import sparse

from handmocap.core.io.resources import resource_path
from handmocap.core.model.hand_model import MAX_INFLUENCES, HandModel, mesh_vertex_normals
from handmocap.core.model.skeleton import JOINT_PARENTS, N_JOINTS, HandProportions, Skeleton, build_skeleton

DEFAULT_TEMPLATE_PATH = resource_path("template", "right_hand.npz")

LANDMARK_NAMES: tuple[str, ...] = (
    "thumb_tip", "thumb_ip", "thumb_mcp",
    "index_tip", "index_dip", "index_pip", "index_mcp",
    "middle_tip", "middle_dip", "middle_pip", "middle_mcp",
    "ring_tip", "ring_dip", "ring_pip", "ring_mcp",
    "little_tip", "little_dip", "little_pip", "little_mcp",
    "wrist",
)

_JOINT_WORDS = {"mcp": "MCP knuckle", "pip": "PIP knuckle", "dip": "DIP knuckle", "ip": "IP knuckle"}
LANDMARK_DESCRIPTIONS: dict[str, str] = {
    name: (f"tip of the {name.split('_')[0]} (most distal point of the fingertip)"
           if name.endswith("_tip") else
           "dorsal point over the wrist joint centre (back of the wrist, between the forearm bones)"
           if name == "wrist" else
           f"dorsal point over the {name.split('_')[0]} {_JOINT_WORDS[name.split('_')[1]]}")
    for name in LANDMARK_NAMES
}

FOREARM_LENGTH = 56.0          # mm of forearm proximal of the wrist joint
_FOREARM_TAPER = 0.96          # radius at the cut end / radius at the wrist
_FOREARM_DOME = 0.008         # 1/mm, curvature of the dorsal and palmar forearm surfaces
_WRIST_HALF_THICKNESS = 0.45   # half-thickness of the wrist skin at the joint / wrist_thickness
_FINGER_GAP = 3.0              # mm, minimum lateral gap between adjacent fingers at rest
_FLATTEN_DORSAL = 0.86         # dorsal radius / lateral radius of a finger shaft
_FLATTEN_PALMAR = 0.90         # palmar radius / lateral radius of a finger shaft
_SMIN_FINGER_PALM = 7.0        # mm, blend radius fingers <-> palm
_PALM_OVERHANG = 6.0          # mm the palm slab reaches beyond the finger MCP joints (webs)
_SMIN_PALM = 15.0              # mm, blend radius palm <-> thenar, hypothenar
_SMOOTH_ITERATIONS = 8         # Taubin iterations
_RELAX_ITERATIONS = 6          # tangential relaxation + projection iterations
_BLEND_FRACTION = 0.25         # joint blend zone half-width / segment length
_SEAM_RINGS = 8                # rings around an ownership seam relaxed by diffusion
_SEAM_ITERATIONS = 150


# --------------------------------------------------------------------------- implicit primitives


def _smoothstep(x: np.ndarray) -> np.ndarray:
    """Cubic smooth step, 0 below 0 and 1 above 1."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _smin(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum of two distance fields (blend radius ``k`` mm)."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - h * h * k * 0.25


def _ellipsoid_distance(local: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Approximate signed distance (N,) of local points (N,3) to ellipsoids with per-point radii (N,3)."""
    k0 = np.linalg.norm(local / radii, axis=1)
    k1 = np.maximum(np.linalg.norm(local / (radii * radii), axis=1), 1e-9)
    return k0 * (k0 - 1.0) / k1


def _ellipsoid(points: np.ndarray, centre: np.ndarray, frame: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Signed distance (N,) to an ellipsoid with semi-axes ``radii (3,)`` along the columns of ``frame``."""
    local = (points - centre) @ frame
    return _ellipsoid_distance(local, np.broadcast_to(radii, local.shape))


@dataclass(frozen=True)
class _Tube:
    """A straight tapered limb: axis ``origin + t * frame[:, 1]``, ``t`` in ``[start, end]`` (mm).

    Cross-section radii (mm) are piecewise linear in ``t`` over ``stations``: ``lateral`` along
    ``frame[:, 0]``, ``dorsal`` / ``palmar`` along ``-frame[:, 2]`` / ``+frame[:, 2]``; both ends are
    closed by half-ellipsoid caps of axial length ``cap_start`` / ``cap_end``.
    """

    origin: np.ndarray
    frame: np.ndarray
    stations: np.ndarray
    lateral: np.ndarray
    dorsal: np.ndarray
    palmar: np.ndarray
    cap_start: float
    cap_end: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Approximate signed distance (N,) of points (N,3)."""
        local = (points - self.origin) @ self.frame
        low, high = self.stations[0], self.stations[-1]
        axial = np.clip(local[:, 1], low, high)
        radii = np.empty_like(local)
        radii[:, 0] = np.interp(axial, self.stations, self.lateral)
        radii[:, 1] = np.where(local[:, 1] < low, self.cap_start, self.cap_end)
        radii[:, 2] = np.where(local[:, 2] < 0.0, np.interp(axial, self.stations, self.dorsal),
                               np.interp(axial, self.stations, self.palmar))
        local[:, 1] -= axial
        return _ellipsoid_distance(local, radii)

    def lateral_at(self, t: np.ndarray) -> np.ndarray:
        """Lateral radius (mm) at axial positions ``t``."""
        return np.interp(t, self.stations, self.lateral)


def _digit_tube(skeleton: Skeleton, proportions: HandProportions, digit: int) -> _Tube:
    """Tube of one digit from its base joint to its tip, with joint bumps and a fingertip pad."""
    base = 1 + 3 * digit
    lengths = skeleton.bone_lengths()[digit]
    r0, r1, r2 = proportions.finger_radii[digit]
    joints = np.concatenate([[0.0], np.cumsum(lengths)])      # base, middle, distal joint, tip
    cap = 0.85 * r2
    stations = np.array([
        joints[0], joints[0] + 0.5 * lengths[0], joints[1], joints[1] + 0.5 * lengths[1],
        joints[2], joints[2] + 0.55 * lengths[2], joints[3] - cap,
    ])
    # lateral radius: joints at the nominal radius, shafts slightly waisted, a tapering fingertip
    lateral = np.array([r0, 0.94 * (r0 + r1) / 2, r1, 0.93 * (r1 + r2) / 2, r2, 0.98 * r2, 0.86 * r2])
    # dorsal: knuckle bumps over the joints, a flat nail over the distal phalanx
    dorsal = lateral * np.array([0.9, _FLATTEN_DORSAL, 0.96, _FLATTEN_DORSAL, 0.90, 0.66, 0.62])
    # palmar: flatter shafts, a fleshy fingertip pad
    palmar = lateral * np.array([0.95, _FLATTEN_PALMAR, 0.86, _FLATTEN_PALMAR, 0.88, 1.0, 0.95])
    return _Tube(skeleton.rest_positions[base], skeleton.rest_rotations[base], stations, lateral, dorsal,
                 palmar, cap_start=(1.0 if digit else 0.8) * r0, cap_end=cap)


def _separate_fingers(tubes: list[_Tube]) -> list[_Tube]:
    """Shrink the lateral radii of adjacent fingers (index..little) so they keep ``_FINGER_GAP`` apart
    beyond the web (from 30 % of the proximal phalanx on); returns tubes resampled at 1 mm stations."""
    grids = [np.append(np.arange(tube.stations[0], tube.stations[-1], 1.0), tube.stations[-1]) for tube in tubes]
    scales = [np.ones(len(grid)) for grid in grids]
    for a in range(1, 5):
        for b in (a - 1, a + 1):
            if not 1 <= b <= 4:
                continue
            tube_a, tube_b = tubes[a], tubes[b]
            axis_a = tube_a.origin + grids[a][:, None] * tube_a.frame[:, 1]
            along_b = np.clip((axis_a - tube_b.origin) @ tube_b.frame[:, 1], tube_b.stations[0],
                              tube_b.stations[-1])
            axis_b = tube_b.origin + along_b[:, None] * tube_b.frame[:, 1]
            spacing = np.linalg.norm(axis_a - axis_b, axis=1)
            need = (spacing - _FINGER_GAP) / (tube_a.lateral_at(grids[a]) + tube_b.lateral_at(along_b))
            # fade the constraint in over the web, from 15 % to 30 % of the proximal phalanx
            web = tube_a.stations[2] - tube_a.stations[0]                      # proximal phalanx
            fade = _smoothstep((grids[a] - 0.15 * web) / (0.15 * web))
            scales[a] = np.minimum(scales[a], 1.0 - fade * (1.0 - np.minimum(need, 1.0)))
    result = []
    for tube, grid, scale in zip(tubes, grids, scales, strict=True):
        lateral, dorsal, palmar = (np.interp(grid, tube.stations, values)
                                   for values in (tube.lateral, tube.dorsal, tube.palmar))
        result.append(_Tube(tube.origin, tube.frame, grid, lateral * scale, dorsal, palmar, tube.cap_start,
                            tube.cap_end))
    return result


def _polygon_distance(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Signed distance (N,) of 2-D points (N,2) to a simple closed polygon (M,2) (negative inside)."""
    start = polygon
    edge = np.roll(polygon, -1, axis=0) - polygon
    relative = points[:, None, :] - start[None]                                   # (N,M,2)
    along = np.clip(np.einsum("nmk,mk->nm", relative, edge) / np.einsum("mk,mk->m", edge, edge), 0, 1)
    distance = np.linalg.norm(relative - along[..., None] * edge[None], axis=2).min(axis=1)
    # even-odd rule for the inside test
    y = points[:, 1:2]
    y0, y1 = start[None, :, 1], start[None, :, 1] + edge[None, :, 1]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = start[None, :, 0] + (y - y0) / (y1 - y0) * edge[None, :, 0]
    inside = np.sum(crosses & (points[:, 0:1] < x_cross), axis=1) % 2 == 1
    return np.where(inside, -distance, distance)


@dataclass(frozen=True)
class _Palm:
    """Rounded slab in the rest frame spanning the forearm stub, the wrist and the knuckles.

    ``outline (M,2)``: polygon in XY, inflated by ``corner`` mm. Dorsal and palmar surfaces ``top`` /
    ``bottom`` (mm, at the wrist ``y = 0`` and at the knuckle line ``knuckle_y``) follow a smooth step
    in between; proximal of the wrist the forearm section scales linearly to ``taper`` at ``y = -length``.
    """

    outline: np.ndarray
    corner: float
    knuckle_y: float
    top: tuple[float, float]
    bottom: tuple[float, float]
    dome: float
    length: float
    taper: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Approximate signed distance (N,) of points (N,3)."""
        planar = _polygon_distance(points[:, :2], self.outline) - self.corner
        v = _smoothstep(points[:, 1] / self.knuckle_y)
        proximal = np.clip(-points[:, 1] / self.length, 0.0, 1.0)
        scale = 1.0 + (self.taper - 1.0) * proximal
        # the dorsal dome of the palm becomes an oval forearm section within 20 mm of the wrist
        oval = _smoothstep(-points[:, 1] / 20.0)
        dome = (self.dome + (_FOREARM_DOME - self.dome) * oval) * points[:, 0] ** 2
        top = (self.top[0] + (self.top[1] - self.top[0]) * v) * scale - dome
        bottom = (self.bottom[0] + (self.bottom[1] - self.bottom[0]) * v) * scale + _FOREARM_DOME * oval \
            * points[:, 0] ** 2
        centre, half = (top + bottom) / 2, (top - bottom) / 2
        round_radius = 0.85 * half
        qx = planar + round_radius
        qz = np.abs(points[:, 2] - centre) - half + round_radius
        outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qz, 0.0))
        return outside + np.minimum(np.maximum(qx, qz), 0.0) - round_radius


def _palm(skeleton: Skeleton, proportions: HandProportions) -> _Palm:
    """Palm slab from the forearm cut over the wrist to the knuckles of the four fingers."""
    mcp = skeleton.rest_positions[[4, 7, 10, 13]]                   # index, middle, ring, little
    radii = proportions.finger_radii[1:, 0]
    corner = 9.0
    half_wrist = 0.5 * proportions.wrist_width
    half_cut = _FOREARM_TAPER * half_wrist
    outline = np.array([
        [-half_cut + corner, -FOREARM_LENGTH + corner],
        [half_cut - corner, -FOREARM_LENGTH + corner],
        [half_wrist - corner, 0.0],
        [mcp[3, 0] + radii[3] + 1.5 - corner, mcp[3, 1] - 14.0],
        [mcp[3, 0] + 0.3 * radii[3], mcp[3, 1] + _PALM_OVERHANG - corner],
        [mcp[2, 0], mcp[2, 1] + _PALM_OVERHANG - corner],
        [mcp[1, 0], mcp[1, 1] + _PALM_OVERHANG - corner],
        [mcp[0, 0] - 0.3 * radii[0], mcp[0, 1] + _PALM_OVERHANG - corner],
        [mcp[0, 0] - radii[0] - 1.0 + corner, mcp[0, 1] - 16.0],
        [-half_wrist + corner, 0.0],
    ])
    thickness, wrist_thickness = proportions.palm_thickness, proportions.wrist_thickness
    return _Palm(outline=outline, corner=corner, knuckle_y=float(mcp[:, 1].mean()),
                 top=(_WRIST_HALF_THICKNESS * wrist_thickness, 0.30 * thickness),
                 bottom=(-_WRIST_HALF_THICKNESS * wrist_thickness, -0.55 * thickness), dome=0.003,
                 length=FOREARM_LENGTH, taper=_FOREARM_TAPER)


def _frame_from_axes(y_axis: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """Orthonormal frame (3,3), columns x, y, z with y along ``y_axis`` and z close to ``z_hint``."""
    y_axis = y_axis / np.linalg.norm(y_axis)
    z_axis = z_hint - (z_hint @ y_axis) * y_axis
    z_axis /= np.linalg.norm(z_axis)
    return np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])


@dataclass(frozen=True)
class _HandShape:
    """All primitives of one hand; :meth:`distance` is the blended signed distance field."""

    digits: list[_Tube]
    palm: _Palm
    pads: list[tuple[np.ndarray, np.ndarray, np.ndarray]]       # (centre, frame, radii) ellipsoids
    webs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    knuckles: list[tuple[np.ndarray, np.ndarray, np.ndarray]]

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (N,) in mm of points (N,3), negative inside the hand."""
        body = self.palm.distance(points)
        for centre, frame, radii in self.knuckles:
            body = _smin(body, _ellipsoid(points, centre, frame, radii), 6.0)
        for centre, frame, radii in self.pads:
            body = _smin(body, _ellipsoid(points, centre, frame, radii), _SMIN_PALM)
        fingers = np.minimum.reduce([tube.distance(points) for tube in self.digits[1:]])
        webs = np.minimum.reduce([_ellipsoid(points, *web) for web in self.webs])
        body = _smin(body, webs, 5.0)
        body = _smin(body, fingers, _SMIN_FINGER_PALM)
        return _smin(body, self.digits[0].distance(points), 10.0)


def _hand_shape(skeleton: Skeleton, proportions: HandProportions) -> _HandShape:
    """Primitives of the hand for a rest skeleton."""
    digits = _separate_fingers([_digit_tube(skeleton, proportions, d) for d in range(5)])
    positions, rotations = skeleton.rest_positions, skeleton.rest_rotations
    cmc, thumb_mcp = positions[1], positions[2]
    thumb_axis = thumb_mcp - cmc
    # thenar eminence: along the thumb metacarpal, towards the palm centre and the palmar side
    thenar_centre = cmc + 0.45 * thumb_axis + np.array([9.0, -4.0, -3.0])
    thenar = (thenar_centre, _frame_from_axes(thumb_axis, np.array([0.0, 0.0, -1.0])),
              np.array([13.0, 0.5 * np.linalg.norm(thumb_axis), 10.0]))
    little = positions[13]
    hypothenar = (np.array([little[0] - 4.0, 0.45 * little[1], -9.0]), np.eye(3),
                  np.array([11.0, 0.38 * little[1], 10.0]))
    pads = [thenar, hypothenar]
    # webs: flat ellipsoids between adjacent finger bases, on the palmar half
    webs = []
    for a, b in ((4, 7), (7, 10), (10, 13)):
        centre = 0.5 * (positions[a] + positions[b]) + np.array([0.0, 5.0, -3.0])
        half_span = 0.5 * np.linalg.norm(positions[b] - positions[a])
        webs.append((centre, _frame_from_axes(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, -1.0])),
                     np.array([half_span, 9.0, 5.0])))
    # first web space between thumb and index: a sheet from the thumb MCP to the index metacarpal head
    index_mcp = positions[4]
    span = index_mcp - thumb_mcp
    centre = thumb_mcp + 0.45 * span + np.array([0.0, -10.0, 0.0])
    webs.append((centre, _frame_from_axes(span, np.array([0.0, 0.0, -1.0]) - 0.3 * rotations[2][:, 2]),
                 np.array([6.0, 0.45 * np.linalg.norm(span), 6.0])))
    knuckles = [(positions[j] + np.array([0.0, -3.0, 1.5]), np.eye(3),
                 np.array([0.75, 0.9, 0.7]) * proportions.finger_radii[(j - 1) // 3, 0])
                for j in (4, 7, 10, 13)]
    return _HandShape(digits, _palm(skeleton, proportions), pads, webs, knuckles)


# --------------------------------------------------------------------------- meshing


def _mesh_at(shape: _HandShape, lower: np.ndarray, upper: np.ndarray, voxel: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Marching cubes of the zero level of ``shape`` on a grid of ``voxel`` mm over [lower, upper]."""
    from skimage.measure import marching_cubes

    axes = [np.arange(lo, hi + voxel, voxel) for lo, hi in zip(lower, upper, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    # evaluated in chunks of ~100k points to bound the memory of the (N, primitives) temporaries
    chunks = np.array_split(grid, max(1, len(grid) // 100_000))
    volume = np.concatenate([shape.distance(chunk) for chunk in chunks]).reshape([len(a) for a in axes])
    vertices, faces, _, _ = marching_cubes(volume, 0.0, spacing=(voxel, voxel, voxel), method="lewiner")
    return vertices + lower, faces.astype(np.int64)


def _largest_component(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep the connected component with the most faces; drop unused vertices."""
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    count = len(vertices)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(count, count))
    _, labels = connected_components(graph, directed=False)
    face_labels = labels[faces[:, 0]]
    keep_faces = faces[face_labels == np.bincount(face_labels).argmax()]
    used = np.unique(keep_faces)
    remap = np.full(count, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[keep_faces]


def _adjacency(faces: np.ndarray, count: int) -> sparse.csr_matrix:
    """Symmetric vertex adjacency (V,V) with unit entries."""
    from scipy import sparse

    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    directed = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(count, count))
    graph = (directed + directed.T).tocsr()
    graph.data[:] = 1.0
    return graph


def _taubin(vertices: np.ndarray, faces: np.ndarray, iterations: int, lam: float = 0.5,
            mu: float = -0.53) -> np.ndarray:
    """Taubin λ|μ smoothing with the uniform Laplacian (keeps the volume, removes voxel steps)."""
    from scipy import sparse

    adjacency = _adjacency(faces, len(vertices))
    averaging = sparse.diags(1.0 / np.asarray(adjacency.sum(axis=1)).ravel()) @ adjacency
    result = vertices.copy()
    for _ in range(iterations):
        result += lam * (averaging @ result - result)
        result += mu * (averaging @ result - result)
    return result


def _project(shape: _HandShape, points: np.ndarray, steps: int = 2, step: float = 0.2) -> np.ndarray:
    """Newton steps of points (N,3) onto the zero level of ``shape`` (central-difference gradient)."""
    offsets = np.vstack([np.zeros(3), step * np.eye(3), -step * np.eye(3)])
    for _ in range(steps):
        values = shape.distance((points[None] + offsets[:, None, :]).reshape(-1, 3)).reshape(7, -1)
        gradient = (values[1:4] - values[4:7]).T / (2.0 * step)
        points = points - (values[0] / np.maximum(np.einsum("ij,ij->i", gradient, gradient), 1e-6))[:, None] \
            * gradient
    return points


def _relax_on_surface(shape: _HandShape, vertices: np.ndarray, faces: np.ndarray, iterations: int
                      ) -> np.ndarray:
    """Tangential Laplacian relaxation (even triangle sizes) with re-projection onto the implicit surface."""
    from scipy import sparse

    adjacency = _adjacency(faces, len(vertices))
    averaging = sparse.diags(1.0 / np.asarray(adjacency.sum(axis=1)).ravel()) @ adjacency
    for _ in range(iterations):
        normals = mesh_vertex_normals(vertices, faces)
        delta = averaging @ vertices - vertices
        delta -= np.einsum("ij,ij->i", delta, normals)[:, None] * normals
        vertices = _project(shape, vertices + 0.5 * delta)
    return vertices


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (mm³) of a closed mesh; positive when faces are counter-clockwise from outside."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def edge_face_counts(faces: np.ndarray) -> np.ndarray:
    """Number of faces using each undirected edge of a triangle mesh (one entry per unique edge)."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return counts


def _check_closed(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Raise ``RuntimeError`` unless the mesh is a closed, oriented 2-manifold of genus 0."""
    counts = edge_face_counts(faces)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    unique_directed = len(np.unique(directed, axis=0))
    euler = len(vertices) - len(counts) + len(faces)
    if np.any(counts != 2) or unique_directed != len(directed) or euler != 2:
        raise RuntimeError(f"template mesh is not a closed sphere-like manifold (Euler {euler})")


def _mesh(shape: _HandShape, skeleton: Skeleton, target_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed outward-oriented smooth mesh of ``shape`` with about ``target_vertices`` vertices."""
    points = np.vstack([skeleton.rest_positions, skeleton.tip_positions, [[0.0, -FOREARM_LENGTH, 0.0]]])
    lower, upper = points.min(axis=0) - 25.0, points.max(axis=0) + 25.0
    voxel = 2.6
    for _ in range(3):
        vertices, faces = _mesh_at(shape, lower, upper, voxel)
        ratio = len(vertices) / target_vertices
        if abs(ratio - 1.0) < 0.03:
            break
        voxel *= np.sqrt(ratio)
    vertices, faces = _largest_component(vertices, faces)
    if signed_volume(vertices, faces) < 0:
        faces = faces[:, ::-1].copy()
    vertices = _taubin(vertices, faces, _SMOOTH_ITERATIONS)
    vertices = _relax_on_surface(shape, vertices, faces, _RELAX_ITERATIONS)
    _check_closed(vertices, faces)
    return vertices, faces


# --------------------------------------------------------------------------- skinning


def _segments(skeleton: Skeleton, proportions: HandProportions
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bone segments: owner joints (S,), starts (S,3), ends (S,3), flesh radii (S,) in mm.

    The wrist owns the forearm axis and the four metacarpals of the fingers; every digit joint owns
    the segment to its child joint (or to the tip).
    """
    positions = skeleton.rest_positions
    owners, starts, ends = [0], [np.array([0.0, -FOREARM_LENGTH, 0.0])], [np.zeros(3)]
    radii = [0.5 * proportions.wrist_thickness]
    for mcp in (4, 7, 10, 13):
        owners.append(0)
        starts.append(np.zeros(3))
        ends.append(positions[mcp])
        radii.append(0.4 * proportions.palm_thickness)
    for joint in range(1, N_JOINTS):
        digit, segment = divmod(joint - 1, 3)
        owners.append(joint)
        starts.append(positions[joint])
        ends.append(positions[joint + 1] if segment < 2 else skeleton.tip_positions[digit])
        radii.append(proportions.finger_radii[digit, segment])
    return np.array(owners), np.array(starts), np.array(ends), np.array(radii)


def _segment_distances(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distances (N,S) of points (N,3) to segments (S,3)-(S,3)."""
    axis = ends - starts
    relative = points[:, None, :] - starts[None]
    along = np.clip(np.einsum("nsk,sk->ns", relative, axis) / np.einsum("sk,sk->s", axis, axis), 0.0, 1.0)
    return np.linalg.norm(relative - along[..., None] * axis[None], axis=2)


def _initial_weights(vertices: np.ndarray, skeleton: Skeleton, proportions: HandProportions
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense weights (V,16) from nearest-segment ownership with smooth-step blends around the joints,
    whether each vertex is owned by the palm (wrist joint) (V,) int, and the rigid digit cores (V,) bool
    (digit-owned vertices outside every blend zone)."""
    owners, starts, ends, radii = _segments(skeleton, proportions)
    distances = _segment_distances(vertices, starts, ends) - radii
    owner = owners[distances.argmin(axis=1)]
    lengths = skeleton.bone_lengths()                                        # (5,3)
    positions, rotations = skeleton.rest_positions, skeleton.rest_rotations
    # half-width of the blend zone of each digit joint: a quarter of the shorter adjacent segment
    half_width = np.zeros(N_JOINTS)
    for digit in range(5):
        for segment in range(3):
            adjacent = lengths[digit, segment - 1:segment + 1] if segment else lengths[digit, :1]
            half_width[1 + 3 * digit + segment] = _BLEND_FRACTION * adjacent.min()
    # axial coordinate of every vertex relative to every joint (V,16), along the joint's bone
    axial = np.einsum("vjk,jk->vj", vertices[:, None, :] - positions[None], rotations[:, :, 1])
    blend = _smoothstep((axial + half_width) / np.maximum(2.0 * half_width, 1e-9))   # weight of the joint
    # palm vertices blend with the digit whose base segment is nearest
    base_distances = distances[:, [5 + 3 * d for d in range(5)]]
    palm_zone = 1 + 3 * base_distances.argmin(axis=1)
    child = np.where((owner - 1) % 3 < 2, owner + 1, -1)
    rows = np.arange(len(vertices))
    in_proximal = (owner > 0) & (axial[rows, owner] < half_width[owner])
    in_distal = (owner > 0) & ~in_proximal & (child > 0) & (axial[rows, np.maximum(child, 0)]
                                                            > -half_width[np.maximum(child, 0)])
    zone = np.select([owner == 0, in_proximal, in_distal], [palm_zone, owner, child], -1)
    weights = np.zeros((len(vertices), N_JOINTS))
    has_zone = zone > 0
    zone_weight = blend[rows[has_zone], zone[has_zone]]
    # palm-owned vertices do not follow the thumb metacarpal, which lies inside the palm (that seam is
    # relaxed by diffusion)
    zone_weight = np.where((owner[has_zone] == 0) & (zone[has_zone] == 1), 0.0, zone_weight)
    weights[rows[has_zone], zone[has_zone]] = zone_weight
    weights[rows[has_zone], JOINT_PARENTS[zone[has_zone]]] += 1.0 - zone_weight
    weights[rows[~has_zone], owner[~has_zone]] = 1.0
    return weights, (owner == 0).astype(np.int64), (owner > 0) & ~has_zone


def _relax_seams(weights: np.ndarray, palm_owned: np.ndarray, core: np.ndarray, faces: np.ndarray
                 ) -> np.ndarray:
    """Harmonic diffusion of the weights (V,16) around ownership seams.

    A seam is an edge whose ends differ in their set of influences or in palm ownership and whose
    weights jump by more than 0.5 (L1); the vertices within ``_SEAM_RINGS`` rings of a seam are relaxed
    unless they belong to a rigid digit ``core`` (V,) bool; all other vertices stay fixed.
    """
    from scipy import sparse

    adjacency = _adjacency(faces, len(weights))
    rows, cols = adjacency.nonzero()
    label = (weights > 0) @ (2 ** np.arange(N_JOINTS)) + (palm_owned << N_JOINTS)
    seam = (label[rows] != label[cols]) & (np.abs(weights[rows] - weights[cols]).sum(axis=1) > 0.5)
    free = np.zeros(len(weights), dtype=bool)
    free[rows[seam]] = True
    for _ in range(_SEAM_RINGS):
        free |= (adjacency @ free.astype(float)) > 0
    free &= ~core
    averaging = sparse.diags(1.0 / np.asarray(adjacency.sum(axis=1)).ravel()) @ adjacency
    result = weights.copy()
    for _ in range(_SEAM_ITERATIONS):
        result[free] = (averaging @ result)[free]
    return result


def _sparse_weights(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dense (V,16) weights to the 4 largest influences (V,4) joints and weights, rows summing to 1."""
    order = np.argsort(-weights, axis=1, kind="stable")[:, :MAX_INFLUENCES]
    top = np.take_along_axis(weights, order, axis=1)
    top = np.where(top > 1e-3, top, 0.0)
    top /= top.sum(axis=1, keepdims=True)
    joints = np.where(top > 0.0, order, order[:, :1])
    return joints.astype(np.int64), top


# --------------------------------------------------------------------------- landmarks


def ray_surface_point(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, direction: np.ndarray
                      ) -> tuple[int, np.ndarray] | None:
    """First crossing (t > 0) of the ray ``origin + t direction`` with the mesh: ``(face, barycentric (3,))``,
    or None when the ray misses (Möller–Trumbore, vectorised over the faces)."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    e1, e2 = b - a, c - a
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    safe = np.where(np.abs(det) > 1e-12, det, 1.0)
    s = origin - a
    u = np.einsum("ij,ij->i", s, p) / safe
    q = np.cross(s, e1)
    v = (q @ direction) / safe
    t = np.einsum("ij,ij->i", e2, q) / safe
    hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    if not np.any(hit):
        return None
    face = int(np.flatnonzero(hit)[np.argmin(t[hit])])
    return face, np.array([1.0 - u[face] - v[face], u[face], v[face]])


def _ray_hit_vertex(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray,
                    direction: np.ndarray) -> int:
    """Vertex nearest to the first intersection of the ray ``origin + t direction`` (t > 0) with the mesh."""
    hit = ray_surface_point(vertices, faces, origin, direction)
    if hit is None:
        raise ValueError("a landmark ray misses the template surface")
    face, barycentric = hit
    corners = faces[face]
    point = barycentric @ vertices[corners]
    return int(corners[np.argmin(np.linalg.norm(vertices[corners] - point, axis=1))])


def _landmarks(vertices: np.ndarray, faces: np.ndarray, skin_joints: np.ndarray, skin_weights: np.ndarray,
               skeleton: Skeleton) -> dict[str, int]:
    """The 20 named landmark vertices (see :data:`LANDMARK_NAMES`)."""
    positions, rotations = skeleton.rest_positions, skeleton.rest_rotations
    found: dict[str, int] = {}
    for name in LANDMARK_NAMES:
        if name == "wrist":
            found[name] = _ray_hit_vertex(vertices, faces, positions[0], np.array([0.0, 0.0, 1.0]))
            continue
        digit_name, joint_name = name.split("_")
        digit = ("thumb", "index", "middle", "ring", "little").index(digit_name)
        if joint_name == "tip":
            distal = 3 + 3 * digit
            members = np.flatnonzero((skin_joints[:, 0] == distal) & (skin_weights[:, 0] == 1.0))
            along = (vertices[members] - positions[distal]) @ rotations[distal][:, 1]
            found[name] = int(members[np.argmax(along)])
            continue
        names = ("cmc", "mcp", "ip") if digit == 0 else ("mcp", "pip", "dip")
        joint = 1 + 3 * digit + names.index(joint_name)
        found[name] = _ray_hit_vertex(vertices, faces, positions[joint], -rotations[joint][:, 2])
    return found


# --------------------------------------------------------------------------- public API


def build_template(proportions: HandProportions | None = None, target_vertices: int = 12_000) -> HandModel:
    """Generate the rigged rest-pose right hand for ``proportions`` (default adult hand, mm)."""
    proportions = proportions or HandProportions()
    skeleton = build_skeleton(proportions)
    shape = _hand_shape(skeleton, proportions)
    vertices, faces = _mesh(shape, skeleton, target_vertices)
    weights, palm_owned, core = _initial_weights(vertices, skeleton, proportions)
    skin_joints, skin_weights = _sparse_weights(_relax_seams(weights, palm_owned, core, faces))
    back = -skeleton.rest_rotations[7][:, 2]
    return HandModel(
        skeleton=skeleton, vertices=vertices, faces=faces, skin_joints=skin_joints,
        skin_weights=skin_weights,
        landmarks=_landmarks(vertices, faces, skin_joints, skin_weights, skeleton),
        back_direction=back / np.linalg.norm(back),
        hand_length=float(np.linalg.norm(skeleton.tip_positions[2] - skeleton.rest_positions[0])),
        name="generated template",
    )


def write_default_template(path: str | Path = DEFAULT_TEMPLATE_PATH) -> HandModel:
    """Build the default template and store it at ``path`` (``.npz``); returns the model."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    model = build_template()
    model.save(path)
    return model
