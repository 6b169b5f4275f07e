"""Hand scans: a point cloud (mm) with optional normals, colours and faces; PLY and OBJ input/output.

The parsers are written with numpy only. PLY: ascii and binary little-endian, ``vertex`` element with
x/y/z, optional nx/ny/nz and red/green/blue, optional ``face`` element (polygons are fan-triangulated).
OBJ: ``v x y z [r g b]``, ``vn``, ``f``. Scans whose bounding box diagonal is below
:data:`METRE_DIAGONAL_LIMIT` are taken to be in metres and converted to mm (recorded in ``Scan.notes``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_stream
from handmocap.core.model.hand_model import mesh_vertex_normals

METRE_DIAGONAL_LIMIT = 2.0   # a hand scan with a bounding-box diagonal below this is in metres

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


@dataclass
class Scan:
    """A scanned point cloud in mm: ``points (N,3)``, ``normals (N,3)`` unit or None,
    ``colors (N,3) uint8`` or None, ``faces (T,3)`` vertex indices or None, ``notes``: what loading changed."""

    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    faces: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, keep: np.ndarray) -> Scan:
        """The scan restricted to the points where ``keep (N,)`` is True; faces are dropped."""
        return Scan(
            points=self.points[keep],
            normals=None if self.normals is None else self.normals[keep],
            colors=None if self.colors is None else self.colors[keep],
            faces=None,
            notes=list(self.notes),
        )


# --------------------------------------------------------------------------- common


def _finish(path: Path, points: np.ndarray, normals: np.ndarray | None, colors: np.ndarray | None,
            faces: np.ndarray | None) -> Scan:
    """Validate parsed arrays, estimate normals from faces, convert metres to mm."""
    if len(points) == 0:
        raise InputError(f"{path.name}: the scan has no points")
    if not np.all(np.isfinite(points)):
        raise InputError(f"{path.name}: the scan has non-finite coordinates")
    notes: list[str] = []
    if faces is not None and len(faces) == 0:
        faces = None
    if faces is not None and (faces.min() < 0 or faces.max() >= len(points)):
        raise InputError(f"{path.name}: a face refers to a vertex that does not exist")
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    if 0.0 < diagonal < METRE_DIAGONAL_LIMIT:
        points = points * 1000.0
        notes.append(f"coordinates look like metres (bounding box diagonal {diagonal:.3f}); converted to mm")
    if normals is not None:
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = normals / np.where(length > 0, length, 1.0)
    elif faces is not None:
        normals = mesh_vertex_normals(points, faces)
        notes.append("normals estimated from the faces")
    return Scan(points=points, normals=normals, colors=colors, faces=faces, notes=notes)


def _colors_uint8(values: np.ndarray) -> np.ndarray:
    """Colours (N,3) as uint8: floats in 0..1 are scaled to 0..255."""
    if np.issubdtype(values.dtype, np.floating) and values.size and values.max() <= 1.0:
        values = values * 255.0
    return np.clip(np.rint(values), 0, 255).astype(np.uint8)


def _fan_triangles(polygons: np.ndarray) -> np.ndarray:
    """Triangles (T,3) from polygons (P,k) with the same number of corners, by fans around corner 0."""
    if polygons.shape[1] < 3:
        raise InputError("faces need at least 3 corners")
    k = polygons.shape[1]
    first = np.repeat(polygons[:, :1], k - 2, axis=1)
    return np.stack([first, polygons[:, 1:-1], polygons[:, 2:]], axis=2).reshape(-1, 3)


def load_scan(path: str | Path) -> Scan:
    """Read a scan from a ``.ply`` or ``.obj`` file (mm, or metres converted to mm)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"scan file not found: {path}")
    suffix = path.suffix.lower()
    if suffix == ".ply":
        return _load_ply(path)
    if suffix == ".obj":
        return _load_obj(path)
    raise InputError(f"{path.name}: unsupported scan format '{suffix}' (use .ply or .obj)")


# --------------------------------------------------------------------------- PLY


@dataclass
class _PlyElement:
    name: str
    count: int
    properties: list[tuple[str, str]]           # (name, numpy type) of scalar properties
    list_property: tuple[str, str, str] | None  # (name, count type, item type)


def _parse_ply_header(path: Path, data: bytes) -> tuple[str, list[_PlyElement], int]:
    """Format, elements and byte offset of the body of a PLY file."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0 or data.find(b"\n", end) < 0:
        raise InputError(f"{path.name}: not a PLY file (missing 'ply' magic or 'end_header' line)")
    body_start = data.index(b"\n", end) + 1
    file_format = ""
    elements: list[_PlyElement] = []
    for line in data[:end].decode("ascii", errors="replace").splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                file_format = words[1]
            elif words[0] == "element":
                count = int(words[2])
                if not 0 <= count <= len(data):  # an element takes at least a byte (ascii: a line end)
                    raise ValueError(count)
                elements.append(_PlyElement(words[1], count, [], None))
            elif words[0] == "property" and words[1] == "list":
                elements[-1].list_property = (words[4], _PLY_TYPES[words[2]], _PLY_TYPES[words[3]])
            elif words[0] == "property":
                elements[-1].properties.append((words[2], _PLY_TYPES[words[1]]))
        except (IndexError, KeyError, ValueError):
            raise InputError(f"{path.name}: malformed PLY header line {ascii(line.strip()[:80])}") from None
    if file_format not in ("ascii", "binary_little_endian"):
        raise InputError(f"{path.name}: unsupported PLY format '{file_format}' "
                         "(ascii and binary_little_endian are supported)")
    if not any(element.name == "vertex" for element in elements):
        raise InputError(f"{path.name}: the PLY file has no vertex element")
    return file_format, elements, body_start


def _vertex_arrays(path: Path, table: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Points, normals and colours from the named columns of the vertex element."""
    if not {"x", "y", "z"} <= table.keys():
        raise InputError(f"{path.name}: the PLY vertex element lacks x/y/z")
    points = np.column_stack([table[a] for a in "xyz"]).astype(np.float64)
    normals = (np.column_stack([table[a] for a in ("nx", "ny", "nz")]).astype(np.float64)
               if {"nx", "ny", "nz"} <= table.keys() else None)
    colors = (_colors_uint8(np.column_stack([table[a] for a in ("red", "green", "blue")]))
              if {"red", "green", "blue"} <= table.keys() else None)
    return points, normals, colors


def _load_ply(path: Path) -> Scan:
    data = path.read_bytes()
    file_format, elements, offset = _parse_ply_header(path, data)
    if file_format == "ascii":
        return _read_ply_ascii(path, data[offset:], elements)
    return _read_ply_binary(path, data, offset, elements)


def _read_ply_ascii(path: Path, body: bytes, elements: list[_PlyElement]) -> Scan:
    lines = body.decode("ascii", errors="replace").splitlines()
    points = normals = colors = faces = None
    start = 0
    for element in elements:
        rows = lines[start:start + element.count]
        start += element.count
        if len(rows) < element.count:
            raise InputError(f"{path.name}: the PLY file ends inside the '{element.name}' element")
        if element.name == "vertex":
            try:
                values = np.array(" ".join(rows).split(), dtype=np.float64).reshape(element.count, -1)
            except ValueError:
                raise InputError(f"{path.name}: malformed PLY vertex data") from None
            if values.shape[1] != len(element.properties):
                raise InputError(f"{path.name}: PLY vertex rows do not match the header properties")
            table = {name: values[:, i] for i, (name, _) in enumerate(element.properties)}
            points, normals, colors = _vertex_arrays(path, table)
        elif element.name == "face" and element.list_property is not None:
            faces = _ascii_faces(path, rows)
    if points is None:
        raise InputError(f"{path.name}: the PLY file has no readable vertex element")
    return _finish(path, points, normals, colors, faces)


def _ascii_faces(path: Path, rows: list[str]) -> np.ndarray:
    """Triangles (T,3) from ascii PLY face rows ``k i0 .. ik-1`` (any polygon sizes)."""
    try:
        polygons = [np.array(row.split(), dtype=np.int64) for row in rows]
    except (ValueError, OverflowError):
        raise InputError(f"{path.name}: malformed PLY face data (indices must be integers below 2**63)") from None
    if any(len(p) == 0 or len(p) != p[0] + 1 for p in polygons):
        raise InputError(f"{path.name}: a PLY face row does not match its corner count")
    by_size: dict[int, list[np.ndarray]] = {}
    for polygon in polygons:
        by_size.setdefault(len(polygon) - 1, []).append(polygon[1:])
    triangles = [_fan_triangles(np.array(group)) for group in by_size.values()]
    return np.concatenate(triangles) if triangles else np.zeros((0, 3), dtype=np.int64)


def _read_ply_binary(path: Path, data: bytes, offset: int, elements: list[_PlyElement]) -> Scan:
    points = normals = colors = faces = None
    for element in elements:
        if element.list_property is None:
            try:
                dtype = np.dtype([(name, "<" + kind) for name, kind in element.properties])
            except ValueError:
                raise InputError(f"{path.name}: the PLY '{element.name[:40]}' element repeats a property name"
                                 ) from None
            size = dtype.itemsize * element.count
            if offset + size > len(data):
                raise InputError(f"{path.name}: the PLY file ends inside the '{element.name}' element")
            table = np.frombuffer(data, dtype=dtype, count=element.count, offset=offset)
            offset += size
            if element.name == "vertex":
                points, normals, colors = _vertex_arrays(path, {n: table[n] for n in table.dtype.names or ()})
        elif element.name == "face" and not element.properties:
            faces = _binary_faces(path, data, offset, element.count, element.list_property)
            break
        else:
            raise InputError(f"{path.name}: unsupported PLY element '{element.name}' with list properties")
    if points is None:
        raise InputError(f"{path.name}: the PLY file has no readable vertex element")
    return _finish(path, points, normals, colors, faces)


def _binary_faces(path: Path, data: bytes, offset: int, count: int, list_property: tuple[str, str, str]
                  ) -> np.ndarray:
    """Triangles (T,3) from a binary PLY face list of ``count`` polygons (``list_property``: name, count
    type, index type) in which every polygon has the same corner count."""
    if count == 0:
        return np.zeros((0, 3), dtype=np.int64)
    _, count_type, item_type = list_property
    if offset + np.dtype(count_type).itemsize > len(data):
        raise InputError(f"{path.name}: the PLY file ends inside the 'face' element")
    corners = int(np.frombuffer(data, dtype="<" + count_type, count=1, offset=offset)[0])
    if not 3 <= corners <= len(data):
        raise InputError(f"{path.name}: malformed PLY face data ({corners} corners)")
    dtype = np.dtype([("k", "<" + count_type), ("i", "<" + item_type, (corners,))])
    if offset + dtype.itemsize * count > len(data):
        raise InputError(f"{path.name}: the PLY file ends inside the 'face' element")
    table = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
    if np.any(table["k"] != corners):
        raise InputError(f"{path.name}: binary PLY faces with mixed polygon sizes are not supported")
    return _fan_triangles(table["i"].astype(np.int64))


# --------------------------------------------------------------------------- OBJ


def _obj_rows(path: Path, lines: list[str], width_options: tuple[int, ...]) -> np.ndarray:
    """Float rows (N,k) from OBJ lines whose keyword was stripped; all rows must have the same width."""
    widths = {len(line.split()) for line in lines}
    if len(widths) > 1 or not widths <= set(width_options):
        raise InputError(f"{path.name}: OBJ rows have inconsistent numbers of values")
    try:
        return np.array(" ".join(lines).split(), dtype=np.float64).reshape(len(lines), -1)
    except ValueError:
        raise InputError(f"{path.name}: malformed numbers in the OBJ file") from None


def _obj_faces(path: Path, lines: list[str], n_vertices: int, n_normals: int
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """Triangles (T,3) of 0-based vertex indices and the matching normal indices (T,3) or None."""
    vertex_groups: dict[int, list[list[int]]] = {}
    normal_groups: dict[int, list[list[int]]] = {}

    def index(text: str, count: int, what: str) -> int:
        """A 1-based (or negative, from the end) OBJ index, checked against the ``count`` items it refers to."""
        value = int(text)
        if not (1 <= value <= count or -count <= value <= -1):
            raise InputError(f"{path.name}: a face refers to a {what} that does not exist ({text[:20]})")
        return value

    try:
        for line in lines:
            corners = [corner.split("/") for corner in line.split()]
            vertex_groups.setdefault(len(corners), []).append([index(c[0], n_vertices, "vertex") for c in corners])
            if n_normals and all(len(c) == 3 and c[2] for c in corners):
                normal_groups.setdefault(len(corners), []).append([index(c[2], n_normals, "normal")
                                                                   for c in corners])
    except ValueError:
        raise InputError(f"{path.name}: malformed OBJ face") from None

    def triangles(groups: dict[int, list[list[int]]], count: int) -> np.ndarray:
        parts = []
        for polygons in groups.values():
            indices = np.array(polygons, dtype=np.int64)
            parts.append(_fan_triangles(np.where(indices < 0, indices + count, indices - 1)))
        return np.concatenate(parts)

    faces = triangles(vertex_groups, n_vertices)
    with_normals = sum(map(len, normal_groups.values())) == len(lines) and n_normals > 0
    return faces, triangles(normal_groups, n_normals) if with_normals else None


def _load_obj(path: Path) -> Scan:
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.splitlines()
    vertex_lines = [line[2:] for line in lines if line.startswith("v ")]
    normal_lines = [line[3:] for line in lines if line.startswith("vn ")]
    face_lines = [line[2:] for line in lines if line.startswith("f ")]
    if not vertex_lines:
        raise InputError(f"{path.name}: the OBJ file has no vertices")
    vertex_rows = _obj_rows(path, vertex_lines, (3, 4, 6))
    points = vertex_rows[:, :3]
    colors = _colors_uint8(vertex_rows[:, -3:]) if vertex_rows.shape[1] >= 6 else None
    vn = _obj_rows(path, normal_lines, (3,)) if normal_lines else None
    faces, normal_faces = (_obj_faces(path, face_lines, len(points), 0 if vn is None else len(vn))
                           if face_lines else (None, None))
    normals = None
    if vn is not None and faces is not None and normal_faces is not None:
        if normal_faces.min() < 0 or normal_faces.max() >= len(vn):
            raise InputError(f"{path.name}: a face refers to a normal that does not exist")
        normals = np.zeros_like(points)
        normals[faces.ravel()] = vn[normal_faces.ravel()]
    elif vn is not None and len(vn) == len(points):
        normals = vn
    return _finish(path, points, normals, colors, faces)


# --------------------------------------------------------------------------- writing


def save_ply(scan: Scan, path: str | Path) -> None:
    """Write ``scan`` as a binary little-endian PLY (float32 x/y/z and normals, uchar colours, int faces)."""
    path = Path(path)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if scan.normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    if scan.colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertices = np.empty(len(scan.points), dtype=np.dtype(fields))
    for i, axis in enumerate("xyz"):
        vertices[axis] = scan.points[:, i]
        if scan.normals is not None:
            vertices["n" + axis] = scan.normals[:, i]
    if scan.colors is not None:
        for i, channel in enumerate(("red", "green", "blue")):
            vertices[channel] = scan.colors[:, i]
    ply_names = {"<f4": "float", "u1": "uchar"}
    header = ["ply", "format binary_little_endian 1.0", "comment written by handmocap",
              f"element vertex {len(vertices)}"]
    header += [f"property {ply_names[kind]} {name}" for name, kind in fields]
    faces = scan.faces if scan.faces is not None else np.zeros((0, 3), dtype=np.int64)
    if len(faces):
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    header.append("end_header")
    face_records = np.empty(len(faces), dtype=np.dtype([("k", "u1"), ("i", "<i4", (3,))]))
    face_records["k"] = 3
    face_records["i"] = faces
    with durable_stream(path) as stream:
        stream.write(("\n".join(header) + "\n").encode("ascii"))
        stream.write(vertices.tobytes())
        stream.write(face_records.tobytes())
