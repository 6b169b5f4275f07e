"""A skinned hand: skeleton + closed triangle mesh + LBS weights + landmarks; posing and mirroring."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np
from numba import njit

from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_stream, verify_zip
from handmocap.core.io.npz import load_npz
from handmocap.core.model.kinematics import KinematicChain
from handmocap.core.model.skeleton import N_JOINTS, Skeleton

MAX_INFLUENCES = 4


@dataclass(frozen=True, eq=False)
class HandModel:
    """A rigged hand in its rest pose (mm, world frame of :mod:`core.model.skeleton`).

    ``vertices (V,3)``, ``faces (T,3)`` (counter-clockwise seen from outside), ``skin_joints (V,4)``
    and ``skin_weights (V,4)`` (rows sum to 1; mid-segment vertices have a single weight 1),
    ``landmarks``: the 20 named landmark vertex indices used by scan calibration,
    ``back_direction (3,)``: unit normal of the back of the hand ``h``, ``hand_length``: ``L`` (mm).
    """

    skeleton: Skeleton
    vertices: np.ndarray
    faces: np.ndarray
    skin_joints: np.ndarray
    skin_weights: np.ndarray
    landmarks: dict[str, int] = field(default_factory=dict)
    back_direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    hand_length: float = 190.0
    name: str = "template"

    def __post_init__(self) -> None:
        for array in (self.vertices, self.faces, self.skin_joints, self.skin_weights):
            array.setflags(write=False)   # shared by every user of the model: never edited in place

    @property
    def side(self) -> str:
        return self.skeleton.side

    @cached_property
    def chain(self) -> KinematicChain:
        return KinematicChain.from_skeleton(self.skeleton)

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """Unit outward normals (V,3) of the rest mesh (area-weighted face normals)."""
        return mesh_vertex_normals(self.vertices, self.faces)

    def mirrored(self) -> HandModel:
        """The mirror-image hand (right ↔ left): X negated, face winding flipped."""
        mirror = np.array([-1.0, 1.0, 1.0])
        return replace(
            self,
            skeleton=self.skeleton.mirrored(),
            vertices=self.vertices * mirror,
            faces=self.faces[:, ::-1].copy(),
            back_direction=self.back_direction * mirror,
            name=f"{self.name} (mirrored)",
        )

    def save(self, path: str | Path) -> None:
        """Store as ``.npz`` through :mod:`core.io.durable` (WriteError naming the file on failure)."""
        with durable_stream(path, verify=verify_zip) as stream:
            np.savez_compressed(
                stream,
                rest_positions=self.skeleton.rest_positions, rest_rotations=self.skeleton.rest_rotations,
                tip_positions=self.skeleton.tip_positions, side=self.skeleton.side,
                vertices=self.vertices, faces=self.faces, skin_joints=self.skin_joints,
                skin_weights=self.skin_weights, landmark_names=np.array(list(self.landmarks)),
                landmark_vertices=np.array(list(self.landmarks.values()), dtype=np.int64),
                back_direction=self.back_direction, hand_length=self.hand_length, name=self.name,
            )

    @classmethod
    def load(cls, path: str | Path) -> HandModel:
        """Read a model written by :meth:`save`."""
        data = load_npz(path, "a hand model file")
        try:
            skeleton = Skeleton(data["rest_positions"], data["rest_rotations"], data["tip_positions"],
                                str(data["side"]))
            model = cls(
                skeleton=skeleton, vertices=np.asarray(data["vertices"], dtype=np.float64),
                faces=np.asarray(data["faces"], dtype=np.int64),
                skin_joints=np.asarray(data["skin_joints"], dtype=np.int64),
                skin_weights=np.asarray(data["skin_weights"], dtype=np.float64),
                landmarks={str(n): int(v) for n, v in zip(data["landmark_names"],
                                                          data["landmark_vertices"], strict=True)},
                back_direction=data["back_direction"], hand_length=float(data["hand_length"]),
                name=str(data["name"]),
            )
        except (KeyError, ValueError, TypeError) as error:
            raise InputError(f"{Path(path).name}: not a hand model file ({error})") from error
        model.validate()
        return model

    def validate(self) -> None:
        """Raise :class:`InputError` when the arrays are inconsistent."""
        count = len(self.vertices) if self.vertices.ndim else 0
        problems = []
        if self.vertices.shape != (count, 3) or count == 0:
            problems.append("vertices must be (V,3)")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or self.faces.max(initial=0) >= count:
            problems.append("faces must be (T,3) indices into the vertices")
        if self.skin_joints.shape != (count, MAX_INFLUENCES) or self.skin_weights.shape != (count, MAX_INFLUENCES):
            problems.append("skin weights must be (V,4)")
        elif self.skin_joints.max(initial=0) >= N_JOINTS:
            problems.append("skin joints must index the 16 joints")
        elif not np.allclose(self.skin_weights.sum(axis=1), 1.0, atol=1e-6):
            problems.append("skin weights must sum to 1 per vertex")
        if problems:
            raise InputError(f"hand model '{self.name}': " + "; ".join(problems))


def mesh_vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (V,3) of a triangle mesh ``vertices (V,3)``, ``faces (T,3)``."""
    return _vertex_normals_kernel(np.ascontiguousarray(vertices, dtype=np.float64),
                                  np.ascontiguousarray(faces, dtype=np.int64))


@njit(cache=True)
def _vertex_normals_kernel(vertices, faces):
    normals = np.zeros_like(vertices)
    for face in range(faces.shape[0]):
        a, b, c = faces[face, 0], faces[face, 1], faces[face, 2]
        ux, uy, uz = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
        vx, vy, vz = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        for corner in (a, b, c):
            normals[corner, 0] += nx
            normals[corner, 1] += ny
            normals[corner, 2] += nz
    for vertex in range(normals.shape[0]):
        length = np.sqrt(normals[vertex, 0] ** 2 + normals[vertex, 1] ** 2 + normals[vertex, 2] ** 2)
        if length > 0.0:
            normals[vertex] /= length
    return normals


def skin_vertices(model: HandModel, theta: np.ndarray) -> np.ndarray:
    """Posed mesh vertices (V,3) in mm by linear blend skinning at ``theta (26,)``."""
    linear, translation = model.chain.skinning_matrices(theta)
    return _skin_kernel(np.ascontiguousarray(linear), np.ascontiguousarray(translation), model.skin_joints,
                        model.skin_weights, model.vertices)


@njit(cache=True)
def _skin_kernel(linear, translation, joints, weights, vertices):
    """Σ_k w_vk (A_j v + b_j) per vertex ``vertices (V,3)`` with joints ``(V,4)``, weights ``(V,4)`` and
    the joints' skinning matrices ``linear (16,3,3)``, ``translation (16,3)``."""
    posed = np.zeros_like(vertices)
    for vertex in range(vertices.shape[0]):
        x, y, z = vertices[vertex, 0], vertices[vertex, 1], vertices[vertex, 2]
        for k in range(joints.shape[1]):
            weight = weights[vertex, k]
            if weight == 0.0:
                continue
            joint = joints[vertex, k]
            for row in range(3):
                posed[vertex, row] += weight * (linear[joint, row, 0] * x + linear[joint, row, 1] * y
                                                + linear[joint, row, 2] * z + translation[joint, row])
    return posed


def mean_vertex_error(model: HandModel, estimated: np.ndarray, truth: np.ndarray, step: int = 5) -> tuple[float, float]:
    """Mean and max over frames of the per-frame mean vertex distance (mm) between two poses sets
    ``(F,26)``, every ``step``-th frame."""
    errors = []
    for frame in range(0, len(truth), step):
        if not np.isfinite(estimated[frame]).all():
            continue
        difference = skin_vertices(model, estimated[frame]) - skin_vertices(model, truth[frame])
        errors.append(float(np.linalg.norm(difference, axis=1).mean()))
    return float(np.mean(errors)), float(np.max(errors))
