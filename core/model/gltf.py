"""glTF 2.0 skinned hands: import a user's rigged hand as a :class:`HandModel`, export a calibrated one.

Written with ``json`` + numpy only (``.glb`` binary and ``.gltf`` with embedded or external buffers).

Import (:func:`load_gltf_hand`):

* the first mesh primitive with a skin (triangles, ``POSITION``, ``JOINTS_0``, ``WEIGHTS_0``); the bind
  pose joint positions come from the inverse bind matrices; duplicated vertices (UV/normal seams) are
  welded so the surface is one connected mesh; metres are converted to mm;
* joints are mapped onto the 16-joint skeleton by name (digit words thumb/index/middle/ring/little or
  pinky, with numbers or the words metacarpal/proximal/intermediate/distal/tip, Mixamo/Unreal/WebXR
  styles) and by geometry: within a digit the joints are ordered by their distance from the wrist;
  a finger with a metacarpal bone drops it (our wrist carries the palm); a missing tip is placed on the
  surface along the last bone;
* the hand side comes from the names (left/right, l_/r_, _l/_r) or the ``side`` argument;
* the model is expressed in the rest frame of :mod:`core.model.skeleton` (wrist at the origin, fingers
  +Y, back +Z, thumb on -X for a right hand) and joint frames are rebuilt from the bones;
* skin weights of unmapped or metacarpal joints go to the wrist, tip weights to the distal joint;
* the 20 landmarks are transferred by geometry (dorsal surface points over the knuckles, the most
  distal point of each fingertip, the back of the wrist).

Export (:func:`save_gltf_hand`): mesh + normals, a 21-node joint hierarchy (16 joints + 5 tips) in
metres with the rest frames as node rotations, inverse bind matrices, 4 weights per vertex (normalised,
zero-weight slots on joint 0), and the model's landmarks, side and name in ``extras.handmocap`` so that
re-importing is exact. With a :class:`HandAnimation` it also holds the take's motion as one animation
(wrist translation, one rotation sampler per joint, times in seconds), metres and Y up as the glTF
specification requires; the file passes the Khronos glTF validator without errors or warnings.
"""

from __future__ import annotations

import base64
import json
import os
import re
import stat
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, TypeGuard
from urllib.parse import unquote

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.axes import Y_UP
from handmocap.core.io.durable import durable_stream, write_text_atomic
from handmocap.core.model.hand_model import MAX_INFLUENCES, HandModel
from handmocap.core.model.skeleton import DIGITS, JOINT_NAMES, JOINT_PARENTS, N_JOINTS, Skeleton
from handmocap.core.model.template_mesh import LANDMARK_NAMES

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
THUMB_PALMAR_HINT = np.array([0.65, 0.25, -0.72])     # thumb pad direction in the rest frame (template's)
_DIGIT_WORDS = {"thumb": 0, "index": 1, "middle": 2, "ring": 3, "little": 4, "pinky": 4, "pinkie": 4}
_PART_ORDER = {"metacarpal": 0, "cmc": 0, "proximal": 1, "mcp": 1, "intermediate": 2, "pip": 2, "middle": 2,
               "distal": 3, "dip": 3, "ip": 3, "tip": 4, "end": 4}


# --------------------------------------------------------------------------- reading


class _Document:
    """A parsed glTF: the JSON (its nodes checked) and its binary buffers.

    Buffers come only from the GLB's own binary chunk, ``data:`` URIs, or regular files in the glTF's folder
    (relative paths without ``..`` that stay inside the folder once links are resolved), and each is read
    only up to its declared ``byteLength``, which must fit in the data it names.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        data = path.read_bytes()
        if path.suffix.lower() == ".glb" or data[:4] == b"glTF":
            document, chunk = _parse_glb(path, data)
            buffers = [chunk]
        else:
            document = _parse_json(path, data)
            buffers = []
        if not isinstance(document, dict):
            raise self.error("the glTF JSON is not an object")
        self.json = document
        self.nodes = [self.item("nodes", index) for index in range(len(self.items("nodes")))]
        for index, node in enumerate(self.nodes):
            self.check_node(index, node)
        for index in range(len(self.items("buffers"))):
            buffer = self.item("buffers", index)
            uri = buffer.get("uri")
            if uri is None:
                if index >= len(buffers):
                    raise self.error(f"buffer {index} has no data")
                continue
            if not isinstance(uri, str):
                raise self.error(f"buffer {index} has a URI that is not text")
            length = self.integer(buffer, "byteLength", f"buffer {index}")
            blob = _data_uri(uri) if uri.startswith("data:") else self.external(uri, length)
            if blob is None:
                raise self.error(f"buffer {index} has a data URI that is not base64")
            if len(blob) < length:
                raise self.error(f"buffer {index} holds fewer bytes than its byteLength {length}")
            buffers.append(blob[:length])
        self.buffers = buffers

    def error(self, problem: str) -> InputError:
        """InputError ``"<file name>: <problem>"`` on one line."""
        return InputError(" ".join(f"{self.path.name}: {problem}".split()))

    def items(self, key: str) -> list:
        """The top-level array ``key`` (empty when absent)."""
        value = self.json.get(key, [])
        if not isinstance(value, list):
            raise self.error(f"'{key}' is not an array")
        return value

    def item(self, key: str, index: object) -> dict:
        """Object ``index`` of the top-level array ``key``, after checking the index is in range."""
        array = self.items(key)
        if not _is_int(index) or not 0 <= index < len(array):
            raise self.error(f"{key} index {str(index)[:20]} is out of range (0..{len(array) - 1})")
        if not isinstance(array[index], dict):
            raise self.error(f"{key} {index} is not an object")
        return array[index]

    def integer(self, holder: dict, key: str, where: str, default: int | None = None, least: int = 0) -> int:
        """``holder[key]`` as an integer >= ``least`` (``default`` when absent and not None)."""
        value = holder.get(key, default)
        if not _is_int(value) or value < least:
            raise self.error(f"{where} has an invalid {key} ({str(value)[:20]})")
        return value

    def check_node(self, index: int, node: dict) -> None:
        """Check the fields of a node this reader uses: name, children, mesh, skin, transform."""
        if not isinstance(node.get("name", ""), str):
            raise self.error(f"node {index} has a name that is not text")
        children = node.get("children", [])
        if not isinstance(children, list) or not all(_is_int(c) and 0 <= c < len(self.nodes) for c in children):
            raise self.error(f"node {index} has children that are not node indices")
        for key, length in (("matrix", 16), ("rotation", 4), ("scale", 3), ("translation", 3)):
            value = node.get(key)
            if value is not None and not (isinstance(value, list) and len(value) == length
                                          and all(_is_number(v) and np.isfinite(v) for v in value)):
                raise self.error(f"node {index} has an invalid {key}")
        for key in ("mesh", "skin"):
            if key in node:
                self.item(key + "es" if key == "mesh" else key + "s", node[key])

    def external(self, uri: str, length: int) -> bytes:
        """The first ``length`` bytes of a buffer file next to the glTF (see the class docstring)."""
        relative = PurePosixPath(unquote(uri))
        folder = self.path.parent.resolve()
        if (not relative.parts or relative.is_absolute() or ".." in relative.parts or ":" in relative.parts[0]
                or "\\" in uri or "\0" in str(relative)):
            raise self.error(f"external buffer '{uri[:80]}' is not a file in the glTF's folder")
        target = (folder / relative).resolve()
        if not target.is_relative_to(folder):
            raise self.error(f"external buffer '{uri[:80]}' leads out of the glTF's folder")
        try:  # non-blocking, so that a FIFO does not wait for a writer
            descriptor = os.open(target, os.O_RDONLY | os.O_NONBLOCK)
        except OSError:
            raise self.error(f"external buffer '{uri[:80]}' not found") from None
        status = os.fstat(descriptor)
        if not stat.S_ISREG(status.st_mode) or status.st_size < length:
            os.close(descriptor)
            problem = "is not a regular file" if not stat.S_ISREG(status.st_mode) else (
                f"holds {status.st_size} bytes, fewer than its byteLength {length}")
            raise self.error(f"external buffer '{uri[:80]}' {problem}")
        with os.fdopen(descriptor, "rb") as stream:
            return stream.read(length)

    def accessor(self, index: object, kinds: tuple[str, ...]) -> np.ndarray:
        """The accessor's data as a float64/int array ``(count, width)`` (normalised integers scaled).

        Its type must be one of ``kinds``; count, offsets and stride are checked against the buffer view and
        the buffer before anything is read.
        """
        accessor = self.item("accessors", index)
        where = f"accessor {index}"
        component, kind = accessor.get("componentType"), accessor.get("type")
        if not (_is_int(component) and component in _COMPONENTS and isinstance(kind, str) and kind in kinds):
            raise self.error(f"{where} has type {str(kind)[:20]} of component {str(component)[:20]} "
                             f"(expected {' or '.join(kinds)})")
        dtype = np.dtype(_COMPONENTS[component]).newbyteorder("<")
        width = _WIDTHS[kind]
        count = self.integer(accessor, "count", where, least=1)
        view = self.item("bufferViews", accessor.get("bufferView"))
        buffer_index = view.get("buffer")
        if not _is_int(buffer_index) or not 0 <= buffer_index < len(self.buffers):
            raise self.error(f"{where}: its buffer view names no buffer")
        buffer = self.buffers[buffer_index]
        view_offset = self.integer(view, "byteOffset", where, default=0)
        view_length = self.integer(view, "byteLength", where, least=1)
        offset = self.integer(accessor, "byteOffset", where, default=0)
        element = dtype.itemsize * width
        stride = self.integer(view, "byteStride", where, default=element, least=element)
        if view_offset + view_length > len(buffer) or offset + stride * (count - 1) + element > view_length:
            raise self.error(f"{where} runs past the end of its buffer view or buffer")
        raw = np.ndarray((count, width), dtype=dtype, buffer=buffer, offset=view_offset + offset,
                         strides=(stride, dtype.itemsize)).copy()
        if accessor.get("normalized") is True and np.issubdtype(dtype, np.integer):
            return raw.astype(np.float64) / np.iinfo(dtype.str).max
        return raw if np.issubdtype(dtype, np.integer) else raw.astype(np.float64)


def _is_int(value: object) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _parse_json(path: Path, text: bytes) -> object:
    """The JSON document in ``text``; nesting deep enough to exhaust the parser is refused like bad JSON."""
    try:
        return json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise InputError(f"{path.name}: not a glTF file ({' '.join(str(error).split())[:120]})") from None


def _data_uri(uri: str) -> bytes | None:
    """The bytes of a base64 ``data:`` URI, or None when it is not one."""
    head, _, payload = uri.partition(",")
    if not head.endswith(";base64"):
        return None
    try:
        return base64.b64decode(payload, validate=True)
    except ValueError:
        return None


def _parse_glb(path: Path, data: bytes) -> tuple[object, bytes]:
    if len(data) < 20:
        raise InputError(f"{path.name}: not a glTF binary file (too short)")
    magic, version, _ = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC or version != 2:
        raise InputError(f"{path.name}: not a glTF 2.0 binary file")
    offset, document, binary = 12, None, b""
    while offset + 8 <= len(data):
        length, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8:offset + 8 + length]
        if kind == _JSON_CHUNK and document is None:
            document = _parse_json(path, chunk)
        elif kind == _BIN_CHUNK:
            binary = chunk
        offset += 8 + length
    if document is None:
        raise InputError(f"{path.name}: the glTF binary has no JSON chunk")
    return document, binary


def _node_matrix(node: dict) -> np.ndarray:
    """Local 4×4 transform of a node (matrix, or translation × rotation × scale)."""
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    matrix = np.eye(4)
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    matrix[:3, :3] = rotation * np.array(node.get("scale", [1.0, 1.0, 1.0]))
    matrix[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return matrix


def _world_matrices(document: _Document) -> list[np.ndarray]:
    """World 4×4 transform of every node, without recursion; a node with two parents or a cycle is refused."""
    nodes = document.nodes
    parent: dict[int, int] = {}
    for index, node in enumerate(nodes):
        for child in node.get("children", []):
            if child in parent or child == index:
                raise document.error(f"node {child} has two parents or is its own child")
            parent[child] = index
    world: list[np.ndarray | None] = [None] * len(nodes)
    for index in range(len(nodes)):
        chain: list[int] = []
        current: int | None = index
        while current is not None and world[current] is None:
            chain.append(current)
            if len(chain) > len(nodes):
                raise document.error("the node hierarchy has a cycle")
            current = parent.get(current)
        above = None if current is None else world[current]
        matrix = np.eye(4) if above is None else above
        for member in reversed(chain):
            matrix = matrix @ _node_matrix(nodes[member])
            world[member] = matrix
    filled = [matrix for matrix in world if matrix is not None]
    assert len(filled) == len(world), "every node's chain ends at a root or a node already placed"
    return filled


# --------------------------------------------------------------------------- joint names


def classify_joint_name(name: str) -> tuple[int | None, int | None, str | None]:
    """``(digit 0..4 or None, part or None, side 'left'/'right' or None)`` read from a bone name.

    Parts: 0 metacarpal, 1 proximal, 2 intermediate, 3 distal, 4 tip; numbered bones (``Index1``,
    ``index_02_r``) give their number as a rank to be ordered by geometry (part None)."""
    words = [w.lower() for w in re.findall(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])", name.replace("mixamorig", ""))]
    side = "left" if {"left", "l"} & set(words) else "right" if {"right", "r"} & set(words) else None
    digit = next((_DIGIT_WORDS[w] for w in words if w in _DIGIT_WORDS and w != "middle"), None)
    if digit is None and "middle" in words:
        digit = 2
    part = None
    for word in words:
        if word in _PART_ORDER and not (word == "middle" and digit == 2 and words.count("middle") == 1):
            part = _PART_ORDER[word]
    return digit, part, side


def map_joints(names: list[str], positions: np.ndarray) -> tuple[int, dict[int, list[int]], str | None]:
    """The wrist joint index and, per digit, the glTF joint indices from proximal to distal."""
    digits: dict[int, list[int]] = {}
    sides = []
    wrist = None
    for index, name in enumerate(names):
        digit, _, side = classify_joint_name(name)
        if side:
            sides.append(side)
        if digit is not None:
            digits.setdefault(digit, []).append(index)
        elif wrist is None and re.search(r"wrist|hand", name.lower()):
            wrist = index
    if len(digits) < 5:
        missing = [DIGITS[d] for d in range(5) if d not in digits]
        raise InputError(f"cannot find the joints of the {', '.join(missing)} in the glTF skin "
                         f"(joint names: {', '.join(names[:8])}...)")
    if wrist is None:
        # the joint nearest to the centroid of the digit bases, among the non-digit joints
        others = [i for i in range(len(names)) if all(i not in chain for chain in digits.values())]
        bases = np.array([positions[min(chain, key=lambda i: np.linalg.norm(positions[i]))] for chain in
                          digits.values()])
        if not others:
            raise InputError("the glTF skin has no wrist/hand joint")
        wrist = min(others, key=lambda i: np.linalg.norm(positions[i] - bases.mean(axis=0)))
    for digit, chain in digits.items():
        digits[digit] = sorted(chain, key=lambda i: np.linalg.norm(positions[i] - positions[wrist]))
    side = max(set(sides), key=sides.count) if sides else None
    return wrist, digits, side


# --------------------------------------------------------------------------- import


def _weld(vertices: np.ndarray, faces: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge vertices closer than ``tolerance``: returns unique vertices, remapped faces, and for each
    unique vertex one original index."""
    keys = np.round(vertices / tolerance).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    faces = inverse[faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    return vertices[first], faces, first


def _frame(y_axis: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    y_axis = y_axis / np.linalg.norm(y_axis)
    z_axis = z_hint - (z_hint @ y_axis) * y_axis
    z_axis /= np.linalg.norm(z_axis)
    return np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])


def transfer_landmarks(vertices: np.ndarray, skeleton: Skeleton, skin_joints: np.ndarray,
                       skin_weights: np.ndarray) -> dict[str, int]:
    """The 20 landmark vertices of a rest-pose hand (definitions of ``LANDMARK_DESCRIPTIONS``)."""
    positions, rotations = skeleton.rest_positions, skeleton.rest_rotations
    dominant = skin_joints[np.arange(len(vertices)), np.argmax(skin_weights, axis=1)]
    found: dict[str, int] = {}
    for name in LANDMARK_NAMES:
        if name == "wrist":
            origin, direction = positions[0], np.array([0.0, 0.0, 1.0])
        else:
            digit_name, joint_name = name.split("_")
            digit = DIGITS.index(digit_name)
            if joint_name == "tip":
                distal = 3 + 3 * digit
                members = np.flatnonzero(dominant == distal)
                if len(members) == 0:
                    members = np.arange(len(vertices))
                along = (vertices[members] - positions[distal]) @ rotations[distal][:, 1]
                found[name] = int(members[np.argmax(along)])
                continue
            names = ("cmc", "mcp", "ip") if digit == 0 else ("mcp", "pip", "dip")
            joint = 1 + 3 * digit + names.index(joint_name)
            origin, direction = positions[joint], -rotations[joint][:, 2]
        relative = vertices - origin
        depth = relative @ direction
        lateral = np.linalg.norm(relative - depth[:, None] * direction, axis=1)
        score = np.where(depth > 0, lateral, np.inf)
        near = score < max(3.0, np.nanmin(score) + 1.5)
        found[name] = int(np.flatnonzero(near)[np.argmax(depth[near])]) if np.any(near) else int(np.argmin(score))
    return found


@dataclass(frozen=True)
class _SkinnedMesh:
    """The first skinned triangle mesh of a glTF file, in file units: ``vertices (V, 3)``, ``faces (T, 3)``,
    ``joints_of``/``weights_of (V, 4)`` skin joint indices and weights, ``bind (J, 4, 4)`` the joints' bind
    matrices (world, column vectors) and ``names`` the J joint names."""

    vertices: np.ndarray
    faces: np.ndarray
    joints_of: np.ndarray
    weights_of: np.ndarray
    bind: np.ndarray
    names: list[str]


def _read_skinned_mesh(document: _Document) -> _SkinnedMesh:
    """The first mesh primitive with a skin, checked (:class:`InputError` when unusable)."""
    path, nodes = document.path, document.nodes
    holder = next((i for i, node in enumerate(nodes) if "mesh" in node and "skin" in node), None)
    if holder is None:
        raise InputError(f"{path.name}: no skinned mesh in the glTF file")
    skin = document.item("skins", nodes[holder]["skin"])
    primitives = document.item("meshes", nodes[holder]["mesh"]).get("primitives")
    if not isinstance(primitives, list) or not primitives or not isinstance(primitives[0], dict):
        raise document.error("the skinned mesh has no primitives")
    primitive = primitives[0]
    attributes = primitive.get("attributes", {})
    if (primitive.get("mode", 4) != 4 or not isinstance(attributes, dict)
            or not {"POSITION", "JOINTS_0", "WEIGHTS_0"} <= attributes.keys()):
        raise InputError(f"{path.name}: the skinned mesh needs triangles with POSITION, JOINTS_0 and WEIGHTS_0")
    vertices = document.accessor(attributes["POSITION"], ("VEC3",))
    faces = (document.accessor(primitive["indices"], ("SCALAR",)).astype(np.int64) if "indices" in primitive
             else np.arange(len(vertices)))
    if len(faces) % 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise document.error("the triangle indices are not triples of vertex indices")
    joints_of = document.accessor(attributes["JOINTS_0"], ("VEC4",)).astype(np.int64)
    weights_of = document.accessor(attributes["WEIGHTS_0"], ("VEC4",))
    if len(joints_of) != len(vertices) or len(weights_of) != len(vertices):
        raise document.error("JOINTS_0 and WEIGHTS_0 must have one entry per vertex")
    joint_nodes = skin.get("joints")
    if not isinstance(joint_nodes, list) or not joint_nodes:
        raise document.error("the skin has no joints")
    for node in joint_nodes:
        document.item("nodes", node)
    if joints_of.min() < 0 or joints_of.max() >= len(joint_nodes):
        raise document.error("JOINTS_0 refers to a joint the skin does not have")
    bind = _bind_matrices(document, skin, joint_nodes)
    if not (np.isfinite(vertices).all() and np.isfinite(weights_of).all() and np.isfinite(bind).all()):
        raise document.error("the skinned mesh has non-finite positions, weights or bind matrices")
    names = [nodes[node].get("name", f"joint{i}") for i, node in enumerate(joint_nodes)]
    return _SkinnedMesh(vertices, faces.reshape(-1, 3), joints_of, weights_of, bind, names)


def _bind_matrices(document: _Document, skin: dict, joint_nodes: list) -> np.ndarray:
    """``(J, 4, 4)`` bind matrices of the skin's joints: the inverted inverse bind matrices, or the joints'
    world matrices when the skin has none."""
    if "inverseBindMatrices" not in skin:
        worlds = _world_matrices(document)
        return np.array([worlds[node] for node in joint_nodes])
    inverse_bind = document.accessor(skin["inverseBindMatrices"], ("MAT4",)).reshape(-1, 4, 4).transpose(0, 2, 1)
    if len(inverse_bind) < len(joint_nodes):
        raise document.error("the skin has fewer inverse bind matrices than joints")
    try:
        return np.linalg.inv(inverse_bind[:len(joint_nodes)])
    except np.linalg.LinAlgError:
        raise document.error("an inverse bind matrix is singular") from None


def _finger_chains(digits: dict[int, list[int]], path: Path) -> dict[int, list[int]]:
    """Per digit, its 3 or 4 glTF joints from the base (a finger's metacarpal dropped, extra joints cut)."""
    chains = {}
    for digit, chain in digits.items():
        kept = chain[1:] if digit > 0 and len(chain) >= 5 else chain   # metacarpal: carried by our wrist
        if len(kept) < 3:
            raise InputError(f"{path.name}: the {DIGITS[digit]} has only {len(kept)} joints (3 needed)")
        chains[digit] = kept[:4]
    return chains


def _canonical_axes(bind_positions: np.ndarray, wrist: int, chains: dict[int, list[int]]) -> np.ndarray:
    """``(3, 3)`` columns x, y, z of the hand's frame: Y towards the middle finger's base, X from index to
    little finger (orthogonalised), Z = X × Y."""
    origin = bind_positions[wrist]
    y_axis = bind_positions[chains[2][0]] - origin
    y_axis /= np.linalg.norm(y_axis)
    x_axis = bind_positions[chains[4][0]] - bind_positions[chains[1][0]]
    x_axis -= (x_axis @ y_axis) * y_axis
    x_axis /= np.linalg.norm(x_axis)
    return np.column_stack([x_axis, y_axis, np.cross(x_axis, y_axis)])


def _rest_skeleton(joints: np.ndarray, chains: dict[int, list[int]], rest_vertices: np.ndarray
                   ) -> tuple[Skeleton, np.ndarray]:
    """The right-hand rest skeleton from the glTF ``joints (J, 3)`` (mm, canonical frame), and for each
    glTF joint our joint that takes its skin weights ``(J,)`` (the wrist when unmapped, the distal joint
    for a tip). A missing tip is placed on ``rest_vertices (V, 3)`` along the last bone."""
    positions = np.zeros((N_JOINTS, 3))
    tips = np.zeros((5, 3))
    owner = np.zeros(len(joints), dtype=np.int64)        # our joint for each glTF joint (default: wrist)
    for digit, chain in chains.items():
        for segment in range(3):
            positions[1 + 3 * digit + segment] = joints[chain[segment]]
            owner[chain[segment]] = 1 + 3 * digit + segment
        if len(chain) >= 4:
            tips[digit] = joints[chain[3]]
            owner[chain[3]] = 3 + 3 * digit
        else:
            direction = joints[chain[2]] - joints[chain[1]]
            direction /= np.linalg.norm(direction)
            reach = (rest_vertices - joints[chain[2]]) @ direction
            tips[digit] = joints[chain[2]] + direction * np.max(reach)
    rotations = np.tile(np.eye(3), (N_JOINTS, 1, 1))
    for joint in range(1, N_JOINTS):
        digit, segment = divmod(joint - 1, 3)
        child = positions[joint + 1] if segment < 2 else tips[digit]
        hint = THUMB_PALMAR_HINT if digit == 0 else np.array([0.0, 0.0, -1.0])
        rotations[joint] = _frame(child - positions[joint], hint)
    return Skeleton(positions, rotations, tips, "right"), owner


def _dense_weights(joints_of: np.ndarray, weights_of: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """``(V, 16)`` weight of each vertex on each of our joints, glTF joints summed through ``owner (J,)``."""
    dense = np.zeros((len(joints_of), N_JOINTS))
    for k in range(joints_of.shape[1]):
        np.add.at(dense, (np.arange(len(joints_of)), owner[np.clip(joints_of[:, k], 0, len(owner) - 1)]),
                  weights_of[:, k])
    return dense


def _top_influences(dense: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``MAX_INFLUENCES`` largest of ``dense (V, 16)`` weights per vertex, normalised: skin joints and
    weights ``(V, MAX_INFLUENCES)``; weights under 1e-4 are dropped (slot on the vertex's first joint) and a
    vertex without any goes wholly to the wrist."""
    order = np.argsort(-dense, axis=1, kind="stable")[:, :MAX_INFLUENCES]
    top = np.take_along_axis(dense, order, axis=1)
    top = np.where(top > 1e-4, top, 0.0)
    empty = top.sum(axis=1) == 0
    top[empty, 0] = 1.0
    order[empty, 0] = 0
    top /= top.sum(axis=1, keepdims=True)
    return np.where(top > 0, order, order[:, :1]).astype(np.int64), top


def load_gltf_hand(path: str | Path, side: str | None = None) -> HandModel:
    """Import a rigged glTF 2.0 hand (``.glb``/``.gltf``) as a :class:`HandModel` (see module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"glTF file not found: {path}")
    document = _Document(path)
    mesh = _read_skinned_mesh(document)
    gltf = document.json
    extras = gltf.get("extras", {}).get("handmocap") if isinstance(gltf.get("extras"), dict) else None
    if extras is not None and len(mesh.names) == N_JOINTS + 5:
        return _from_own_export(document, mesh.vertices, mesh.faces, mesh.joints_of, mesh.weights_of, mesh.bind,
                                extras)

    scale = 1000.0 if np.linalg.norm(np.ptp(mesh.vertices, axis=0)) < 2.0 else 1.0
    vertices, bind_positions = mesh.vertices * scale, mesh.bind[:, :3, 3] * scale
    wrist, digits, named_side = map_joints(mesh.names, bind_positions)
    side = side or named_side or _side_from_names(gltf, path) or "right"
    chains = _finger_chains(digits, path)
    # canonical frame: origin at the wrist; a left hand becomes its right mirror image
    origin, axes = bind_positions[wrist], _canonical_axes(bind_positions, wrist, chains)
    flip = np.array([1.0, 1.0, -1.0 if side == "left" else 1.0])
    rest_vertices = ((vertices - origin) @ axes) * flip
    skeleton, owner = _rest_skeleton(((bind_positions - origin) @ axes) * flip, chains, rest_vertices)
    dense = _dense_weights(mesh.joints_of, mesh.weights_of, owner)
    rest_vertices, faces, kept = _weld(rest_vertices, mesh.faces, tolerance=1e-3)
    skin_joints, skin_weights = _top_influences(dense[kept])
    if _signed_volume(rest_vertices, faces) < 0:
        faces = faces[:, ::-1].copy()
    back = -skeleton.rest_rotations[7][:, 2]
    hand_length = float(np.linalg.norm(skeleton.tip_positions[2] - skeleton.rest_positions[0]))
    model = HandModel(skeleton=skeleton, vertices=rest_vertices, faces=faces, skin_joints=skin_joints,
                      skin_weights=skin_weights,
                      landmarks=transfer_landmarks(rest_vertices, skeleton, skin_joints, skin_weights),
                      back_direction=back / np.linalg.norm(back), hand_length=hand_length, name=path.stem)
    model.validate()
    return model.mirrored() if side == "left" else model


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def _side_from_names(gltf: dict, path: Path) -> str | None:
    """'left'/'right' from the node, mesh and file names, or None."""
    texts = [node.get("name", "") for node in gltf.get("nodes", []) if "mesh" in node] + [path.stem]
    for text in texts:
        _, _, side = classify_joint_name(text)
        if side:
            return side
    return None


def _from_own_export(document: _Document, vertices: np.ndarray, faces: np.ndarray, joints_of: np.ndarray,
                     weights_of: np.ndarray, bind: np.ndarray, extras: object) -> HandModel:
    """Exact re-import of a file written by :func:`save_gltf_hand` (joints 0..15, then the 5 tips)."""
    if not isinstance(extras, dict):
        raise document.error("extras.handmocap is not an object")
    side = extras.get("side", "right")
    landmarks = extras.get("landmarks", {})
    back_direction = extras.get("back_direction", [0.0, 0.0, 1.0])
    hand_length = extras.get("hand_length", 190.0)
    direction_ok = isinstance(back_direction, list) and len(back_direction) == 3 and all(map(_is_number,
                                                                                              back_direction))
    if (side not in ("left", "right") or not isinstance(landmarks, dict) or not direction_ok
            or not all(_is_int(v) and 0 <= v < len(vertices) for v in landmarks.values())
            or not _is_number(hand_length)):
        raise document.error("extras.handmocap has an invalid side, landmarks, back_direction or hand_length")
    sums = weights_of.sum(axis=1, keepdims=True)
    if not (sums > 0).all():
        raise document.error("a vertex has no skin weight")
    positions = bind[:N_JOINTS, :3, 3] * 1000.0
    rotations = bind[:N_JOINTS, :3, :3]
    tips = bind[N_JOINTS:, :3, 3] * 1000.0
    owner = np.concatenate([np.arange(N_JOINTS), 3 + 3 * np.arange(5)])
    model = HandModel(skeleton=Skeleton(positions, rotations, tips, side), vertices=vertices * 1000.0,
                      faces=faces, skin_joints=owner[joints_of], skin_weights=weights_of / sums,
                      landmarks={str(k): v for k, v in landmarks.items()},
                      back_direction=np.asarray(back_direction, dtype=np.float64), hand_length=float(hand_length),
                      name=str(extras.get("name", document.path.stem)))
    model.validate()
    return model


# --------------------------------------------------------------------------- export


@dataclass(frozen=True)
class HandAnimation:
    """The motion of an exported hand: ``joint_angles (F, 26)`` rad / mm in the lab frame (Z up; NaN
    frames hold the nearest solved one) at ``frame_rate`` Hz."""

    joint_angles: np.ndarray
    frame_rate: float


def _quaternions(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` ``[x, y, z, w]`` of rotation matrices ``(..., 3, 3)`` (w >= 0 where
    the largest component allows; signs are made continuous over time by the caller)."""
    m = np.asarray(rotations, dtype=np.float64)
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    candidates = np.stack([
        np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1],
                  1.0 + trace], axis=-1),
        np.stack([1.0 + 2 * m[..., 0, 0] - trace, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0],
                  m[..., 2, 1] - m[..., 1, 2]], axis=-1),
        np.stack([m[..., 0, 1] + m[..., 1, 0], 1.0 + 2 * m[..., 1, 1] - trace, m[..., 1, 2] + m[..., 2, 1],
                  m[..., 0, 2] - m[..., 2, 0]], axis=-1),
        np.stack([m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1.0 + 2 * m[..., 2, 2] - trace,
                  m[..., 1, 0] - m[..., 0, 1]], axis=-1),
    ])  # (4, ..., 4): the four textbook forms, each stable where its diagonal term is largest
    choice = np.argmax(np.stack([trace, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]]), axis=0)
    q = np.take_along_axis(candidates, choice[None, ..., None], axis=0)[0]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _quaternion(rotation: np.ndarray) -> list[float]:
    """Unit quaternion ``[x, y, z, w]`` of a rotation matrix."""
    return [float(v) for v in _quaternions(rotation)]


def _continuous(quaternions: np.ndarray) -> np.ndarray:
    """``quaternions (F, 4)`` with signs flipped so consecutive ones have a non-negative dot product (the
    same rotations, interpolated the short way)."""
    result = quaternions.copy()
    for frame in range(1, len(result)):
        if np.dot(result[frame], result[frame - 1]) < 0:
            result[frame] = -result[frame]
    return result


def _rest_world(skeleton: Skeleton) -> np.ndarray:
    """Rest world matrices ``(21, 4, 4)`` in metres of the 16 joints and 5 tips (model frame)."""
    world = np.tile(np.eye(4), (N_JOINTS + 5, 1, 1))
    world[:N_JOINTS, :3, :3] = skeleton.rest_rotations
    world[:N_JOINTS, :3, 3] = skeleton.rest_positions / 1000.0
    for digit in range(5):
        world[N_JOINTS + digit, :3, :3] = skeleton.rest_rotations[3 + 3 * digit]
        world[N_JOINTS + digit, :3, 3] = skeleton.tip_positions[digit] / 1000.0
    return world


def _animation_locals(model: HandModel, animation: HandAnimation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame the wrist node's translation ``(F, 3)`` m and every joint node's local rotation
    ``(F, 16, 4)`` quaternions in the glTF frame (Y up: the lab's Z-up frame turned by
    :data:`core.io.axes.Y_UP`), and the times ``(F,)`` s from the first frame."""
    from handmocap.core.model.bvh import _held
    from handmocap.core.model.kinematics import KinematicChain

    angles = _held(animation.joint_angles)
    chain = KinematicChain.from_skeleton(model.skeleton)
    frames = len(angles)
    world = np.tile(np.eye(4), (frames, N_JOINTS, 1, 1))
    for frame in range(frames):
        rotations, positions = chain.joint_transforms(angles[frame])
        world[frame, :, :3, :3] = rotations
        world[frame, :, :3, 3] = positions / 1000.0
    turn = np.eye(4)
    turn[:3, :3] = Y_UP
    world = turn @ world
    local = world.copy()
    local[:, 1:] = np.linalg.inv(world[:, JOINT_PARENTS[1:]]) @ world[:, 1:]
    quaternions = np.stack([_continuous(_quaternions(local[:, joint, :3, :3])) for joint in range(N_JOINTS)], axis=1)
    times = np.arange(frames) / float(animation.frame_rate)
    return local[:, 0, :3, 3], quaternions, times


class _Binary:
    """The buffer of a glTF being written: bufferViews and accessors appended with 4-byte alignment."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, component: int, kind: str, target: int | None = None,
            bounds: bool = False) -> int:
        """Append ``array`` as one bufferView and accessor (with min/max when ``bounds``); its index."""
        data = np.ascontiguousarray(array).tobytes()
        self.data += b"\0" * ((-len(self.data)) % 4)
        view: dict = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(data)}
        if target:
            view["target"] = target
        self.views.append(view)
        self.data += data
        width = _WIDTHS[kind]
        accessor: dict = {"bufferView": len(self.views) - 1, "componentType": component,
                          "count": int(array.size // width), "type": kind}
        if bounds:
            rows = np.asarray(array, dtype=np.float64).reshape(-1, width)
            accessor["min"] = [float(v) for v in rows.min(axis=0)]
            accessor["max"] = [float(v) for v in rows.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _add_hand(document: dict[str, Any], binary: _Binary, model: HandModel, prefix: str) -> int:
    """Append ``model``'s joint and tip nodes (names prefixed ``prefix``), its skinned mesh, mesh node and skin to
    the glTF ``document``; returns the mesh node's index (the wrist node is the first one added)."""
    first = len(document["nodes"])
    skeleton = model.skeleton
    world = _rest_world(skeleton)
    parents = list(JOINT_PARENTS) + [3 + 3 * d for d in range(5)]
    names = list(JOINT_NAMES) + [f"{d}_tip" for d in DIGITS]
    for index in range(N_JOINTS + 5):
        parent = parents[index]
        local = world[index] if parent < 0 else np.linalg.inv(world[parent]) @ world[index]
        children = [first + c for c in range(N_JOINTS + 5) if parents[c] == index]
        node = {"name": prefix + names[index], "translation": [float(v) for v in local[:3, 3]],
                "rotation": _quaternion(local[:3, :3])}
        if children:
            node["children"] = children
        document["nodes"].append(node)
    mesh_node = len(document["nodes"])
    document["nodes"].append({"name": f"{model.side}_hand_mesh", "mesh": len(document["meshes"]),
                              "skin": len(document["skins"])})
    weights = model.skin_weights.astype(np.float32)
    weights /= weights.sum(axis=1, keepdims=True)
    joints = np.where(weights > 0, model.skin_joints, 0).astype(np.uint16)
    attributes = {"POSITION": binary.add((model.vertices / 1000.0).astype(np.float32), 5126, "VEC3", 34962, True),
                  "NORMAL": binary.add(model.vertex_normals.astype(np.float32), 5126, "VEC3", 34962),
                  "JOINTS_0": binary.add(joints, 5123, "VEC4", 34962),
                  "WEIGHTS_0": binary.add(weights, 5126, "VEC4", 34962)}
    indices = binary.add(model.faces.astype(np.uint32).ravel(), 5125, "SCALAR", 34963)
    inverse_bind = binary.add(np.linalg.inv(world).transpose(0, 2, 1).astype(np.float32), 5126, "MAT4")
    document["meshes"].append({"name": model.name, "primitives": [{"attributes": attributes, "indices": indices,
                                                                   "mode": 4}]})
    document["skins"].append({"name": f"{model.side}_hand", "joints": list(range(first, first + N_JOINTS + 5)),
                              "inverseBindMatrices": inverse_bind, "skeleton": first})
    return mesh_node


def save_gltf_hand(model: HandModel, path: str | os.PathLike[str], animation: HandAnimation | None = None) -> None:
    """Write ``model`` as glTF 2.0 (``.glb`` binary or ``.gltf`` with an embedded buffer), metres, atomically.

    With ``animation``, one glTF animation "motion": the wrist node's translation and a rotation
    sampler per joint node (16; the tips follow their distal joint), linear, keyed at every frame in
    seconds; the motion is in metres and Y up (the lab frame turned by :data:`core.io.axes.Y_UP`).
    Skin slots of zero weight point at joint 0 (the validator's ACCESSOR_JOINTS_USED_ZERO_WEIGHT)."""
    save_gltf_hands([(model, animation)], path)


def save_gltf_hands(hands: Sequence[tuple[HandModel, HandAnimation | None]], path: str | os.PathLike[str]) -> None:
    """Write one or two hands (``(model, animation or None)`` each, e.g. a right and a left one) into one glTF
    2.0 file as :func:`save_gltf_hand` writes one: per hand a skeleton (joint nodes prefixed ``R_``/``L_`` when
    there are two), a skinned mesh and its skin; the animations of all hands are the channels of one animation
    "motion" (same frame times). ``extras.handmocap`` describes the first hand (so :func:`load_gltf_hand`
    reads it back) and lists every hand's side under ``hands``."""
    path = Path(path)
    if path.suffix.lower() not in (".glb", ".gltf"):
        raise InputError(f"{path.name}: glTF export needs a .glb or .gltf file name")
    if not hands:
        raise InputError("glTF export needs at least one hand")
    for _, animation in hands:
        if animation is not None:
            angles = np.asarray(animation.joint_angles)
            if angles.ndim != 2 or angles.shape[1] != 26 or not len(angles):
                raise InputError(f"glTF animation needs joint angles (F, 26) with F > 0, got {angles.shape}")
            if not (np.isfinite(animation.frame_rate) and animation.frame_rate > 0):
                raise InputError(f"frame rate must be positive, got {animation.frame_rate}")
    binary = _Binary()
    document: dict[str, Any] = {"asset": {"version": "2.0", "generator": "Hand Mocap Studio"}, "scene": 0,
                                "nodes": [], "meshes": [], "skins": []}
    roots: list[int] = []
    samplers: list[dict] = []
    channels: list[dict] = []
    time_accessor: int | None = None
    for model, animation in hands:
        prefix = ("R_" if model.side == "right" else "L_") if len(hands) > 1 else ""
        first = len(document["nodes"])
        mesh_node = _add_hand(document, binary, model, prefix)
        roots += [first, mesh_node]
        if animation is None:
            continue
        translation, rotations, times = _animation_locals(model, animation)
        if time_accessor is None:
            time_accessor = binary.add(times.astype(np.float32), 5126, "SCALAR", bounds=True)
        samplers.append({"input": time_accessor, "output": binary.add(translation.astype(np.float32), 5126, "VEC3"),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": first, "path": "translation"}})
        for joint in range(N_JOINTS):
            samplers.append({"input": time_accessor, "output": binary.add(rotations[:, joint].astype(np.float32),
                                                                          5126, "VEC4"), "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": first + joint, "path": "rotation"}})
    document["scenes"] = [{"name": "Scene", "nodes": roots}]
    if channels:
        document["animations"] = [{"name": "motion", "samplers": samplers, "channels": channels}]
    model = hands[0][0]
    extras: dict[str, Any] = {"side": model.side, "landmarks": {k: int(v) for k, v in model.landmarks.items()},
                              "back_direction": [float(v) for v in model.back_direction],
                              "hand_length": float(model.hand_length), "name": model.name}
    if len(hands) > 1:
        extras["hands"] = [hand.side for hand, _ in hands]
    document.update({"accessors": binary.accessors, "bufferViews": binary.views,
                     "buffers": [{"byteLength": len(binary.data)}], "extras": {"handmocap": extras}})
    data = bytes(binary.data) + b"\0" * ((-len(binary.data)) % 4)
    document["buffers"][0]["byteLength"] = len(data)
    if path.suffix.lower() == ".gltf":
        document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
        write_text_atomic(path, json.dumps(document))
    else:
        text = json.dumps(document).encode("utf-8")
        text += b" " * ((-len(text)) % 4)
        total = 12 + 8 + len(text) + 8 + len(data)
        with durable_stream(path) as stream:
            stream.write(struct.pack("<III", _GLB_MAGIC, 2, total))
            stream.write(struct.pack("<II", len(text), _JSON_CHUNK) + text)
            stream.write(struct.pack("<II", len(data), _BIN_CHUNK) + data)
