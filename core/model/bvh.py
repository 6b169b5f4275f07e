"""Joint angles as BVH (Biovision hierarchy): write the 16-joint hand, read any BVH back.

Hierarchy: the wrist is the ROOT (6 channels: ``Xposition Yposition Zposition Zrotation Xrotation
Yrotation``), then per digit (thumb, index, middle, ring, little) its base, middle and distal joint
(3 channels ``Zrotation Xrotation Yrotation`` each) and an ``End Site`` at the digit tip. Names are
the model's joint names (``wrist``, ``thumb_cmc``, ``index_mcp``...) with an optional prefix (``R_``).

As BVH expects, every joint's rest orientation is the world axes (Z up, like the C3D data) and its
``OFFSET`` is the rest-pose vector from its parent in world axes, taken from the model's rest
skeleton (so a subject-calibrated model gives the subject's bone lengths). Each frame's rotation of a
joint is the change from its rest orientation relative to its parent: with ``W_j = R_j R_rest,jᵀ``
(world rotation of joint j posed, times the transpose of its rest frame), the local rotation is
``W_parentᵀ W_j``, written as Z-X-Y Euler angles in degrees (``R = Rz·Rx·Ry``), unwrapped over time.
The root's position channels are the wrist position. Lengths are in ``units`` (mm by default; "cm"
for tools that assume centimetres, "m" for Blender). Frames whose joint angles are NaN (not solved)
repeat the nearest solved frame (the rest pose when none is).

Up axis (``up``): "z" keeps the lab frame; "y" writes the same motion in a Y-up frame (the frame Blender's
BVH importer and MotionBuilder assume): with ``A`` the rotation of :mod:`core.io.axes`, positions and
offsets become ``A p`` and every rotation ``A R Aᵀ`` before the Euler angles are taken, so the rest
orientations stay the world axes and the channels keep their Z-X-Y order. Blender: ``--units m --up y``
(imported with its defaults, scale 1, forward -Z, up Y); MotionBuilder: ``--units cm --up y``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.axes import axes_rotation, check_units
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.model.kinematics import KinematicChain
from handmocap.core.model.skeleton import JOINT_NAMES, JOINT_PARENTS, N_JOINTS, N_PARAMS, Skeleton

ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
JOINT_CHANNELS = ["Zrotation", "Xrotation", "Yrotation"]


def euler_zxy(rotations: np.ndarray) -> np.ndarray:
    """Z-X-Y Euler angles ``(..., 3)`` rad (z, x, y) of rotation matrices ``(..., 3, 3)``, R = Rz·Rx·Ry."""
    x = np.arcsin(np.clip(rotations[..., 2, 1], -1.0, 1.0))
    y = np.arctan2(-rotations[..., 2, 0], rotations[..., 2, 2])
    z = np.arctan2(-rotations[..., 0, 1], rotations[..., 1, 1])
    return np.stack([z, x, y], axis=-1)


def _axis_rotation(axis: str, angles: np.ndarray) -> np.ndarray:
    """Rotations ``(N, 3, 3)`` about X, Y or Z by ``angles (N,)`` rad."""
    c, s = np.cos(angles), np.sin(angles)
    one, zero = np.ones_like(angles), np.zeros_like(angles)
    rows = {"X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]]}[axis]
    return np.moveaxis(np.array(rows), [0, 1], [-2, -1])


def _held(joint_angles: np.ndarray) -> np.ndarray:
    """Joint angles with unsolved (non-finite) frames replaced by the nearest solved frame."""
    angles = np.array(joint_angles, dtype=np.float64)
    solved = np.isfinite(angles).all(axis=1)
    if not solved.any():
        return np.zeros_like(angles)
    index = np.arange(len(angles))
    previous = np.maximum.accumulate(np.where(solved, index, -1))
    following = np.minimum.accumulate(np.where(solved, index, len(angles))[::-1])[::-1]
    use_previous = (previous >= 0) & ((following >= len(angles)) | (index - previous <= following - index))
    source = np.where(use_previous, previous, following)
    return angles[source]


def local_rotations(skeleton: Skeleton, joint_angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame BVH local rotations ``(F, 16, 3, 3)`` and wrist positions ``(F, 3)`` mm of
    ``joint_angles (F, 26)`` on ``skeleton`` (module docstring)."""
    chain = KinematicChain.from_skeleton(skeleton)
    frames = len(joint_angles)
    world = np.empty((frames, N_JOINTS, 3, 3))
    wrist = np.empty((frames, 3))
    rest_transposed = np.transpose(skeleton.rest_rotations, (0, 2, 1))
    for frame in range(frames):
        rotations, positions = chain.joint_transforms(joint_angles[frame])
        world[frame] = rotations @ rest_transposed
        wrist[frame] = positions[0]
    local = world.copy()
    parents = JOINT_PARENTS[1:]
    local[:, 1:] = np.transpose(world[:, parents], (0, 1, 3, 2)) @ world[:, 1:]
    return local, wrist


def write_bvh(path: str | PathLike[str], skeleton: Skeleton, joint_angles: np.ndarray, frame_rate: float,
              prefix: str = "", units: str = "mm", up: str = "z") -> None:
    """Write ``joint_angles (F, 26)`` (rad, mm) of a hand with rest ``skeleton`` as BVH at ``frame_rate``
    Hz in ``units`` ("mm", "cm", "m") with ``up`` ("z" lab frame, "y") (scheme in the module docstring),
    atomically. InputError on bad input."""
    joint_angles = np.asarray(joint_angles, dtype=np.float64)
    if joint_angles.ndim != 2 or joint_angles.shape[1] != N_PARAMS or not len(joint_angles):
        raise InputError(f"BVH export needs joint angles (F, 26) with F > 0, got {joint_angles.shape}")
    scale = check_units(units)
    axes = axes_rotation(up)
    if not (math.isfinite(frame_rate) and frame_rate > 0):
        raise InputError(f"frame rate must be positive, got {frame_rate}")
    local, wrist = local_rotations(skeleton, _held(joint_angles))
    local = axes @ local @ axes.T
    euler = np.degrees(np.unwrap(euler_zxy(local), axis=0))  # (F, 16, 3) z, x, y
    motion = np.concatenate([wrist @ axes.T * scale, euler.reshape(len(euler), -1)], axis=1)

    lines = ["HIERARCHY"]
    rest = skeleton.rest_positions

    def offset(vector: np.ndarray) -> str:
        return "OFFSET " + " ".join(f"{value * scale:.6f}" for value in axes @ vector)

    lines += [f"ROOT {prefix}{JOINT_NAMES[0]}", "{", "  OFFSET 0.000000 0.000000 0.000000",
              "  CHANNELS 6 " + " ".join(ROOT_CHANNELS)]
    for digit in range(5):
        depth = 1
        for segment in range(3):
            joint = 1 + 3 * digit + segment
            indent = "  " * depth
            lines += [f"{indent}JOINT {prefix}{JOINT_NAMES[joint]}", f"{indent}{{",
                      f"{indent}  {offset(rest[joint] - rest[JOINT_PARENTS[joint]])}",
                      f"{indent}  CHANNELS 3 " + " ".join(JOINT_CHANNELS)]
            depth += 1
        indent = "  " * depth
        lines += [f"{indent}End Site", f"{indent}{{",
                  f"{indent}  {offset(skeleton.tip_positions[digit] - rest[3 + 3 * digit])}", f"{indent}}}"]
        for level in range(depth - 1, 0, -1):
            lines.append("  " * level + "}")
    lines += ["}", "MOTION", f"Frames: {len(motion)}", f"Frame Time: {1.0 / frame_rate:.8f}"]
    body = "\n".join(" ".join(f"{value:.6f}" for value in row) for row in motion)
    text = "\n".join(lines) + "\n" + body + "\n"
    write_text_atomic(path, text)


@dataclass
class BVHMotion:
    """A parsed BVH file: ``joint_names``, ``parents`` (-1 root), ``offsets (J, 3)``, ``channels`` per
    joint, ``end_sites`` {joint index: offset (3,)}, ``frame_time`` s, ``motion (F, C)``."""

    joint_names: list[str]
    parents: list[int]
    offsets: np.ndarray
    channels: list[list[str]]
    frame_time: float
    motion: np.ndarray
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(self.motion)

    def joint_values(self, joint: int) -> np.ndarray:
        """The channel values of ``joint`` over all frames, ``(F, len(channels[joint]))``."""
        start = sum(len(channels) for channels in self.channels[:joint])
        return self.motion[:, start:start + len(self.channels[joint])]

    def world_positions(self) -> np.ndarray:
        """Joint positions ``(F, J, 3)`` by forward kinematics of the channels (BVH convention:
        rotations applied in channel order, each joint at parent position + parent rotation · offset)."""
        frames, count = self.n_frames, len(self.joint_names)
        rotations = np.zeros((frames, count, 3, 3))
        positions = np.zeros((frames, count, 3))
        for joint in range(count):
            values = self.joint_values(joint)
            local = np.tile(np.eye(3), (frames, 1, 1))
            translation = np.zeros((frames, 3))
            for index, channel in enumerate(self.channels[joint]):
                axis, kind = channel[0].upper(), channel[1:].lower()
                if kind == "rotation":
                    local = local @ _axis_rotation(axis, np.radians(values[:, index]))
                elif kind == "position":
                    translation[:, "XYZ".index(axis)] = values[:, index]
            parent = self.parents[joint]
            if parent < 0:
                rotations[:, joint] = local
                positions[:, joint] = self.offsets[joint] + translation
            else:
                rotations[:, joint] = rotations[:, parent] @ local
                positions[:, joint] = positions[:, parent] + rotations[:, parent] @ self.offsets[joint] + translation
        return positions


def read_bvh(path: str | PathLike[str]) -> BVHMotion:
    """Parse a BVH file (one or more roots); InputError with the line number when malformed."""
    try:
        tokens_by_line = [line.split() for line in Path(path).read_text(encoding="utf-8", errors="replace")
                          .splitlines()]
    except OSError as error:
        raise InputError(f"cannot read {Path(path).name} ({error.strerror or error})") from None
    name = Path(path).name
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[list[str]] = []
    end_sites: dict[int, np.ndarray] = {}
    stack: list[int] = []
    in_end_site = False
    line_number = 0
    try:
        while line_number < len(tokens_by_line):
            tokens = tokens_by_line[line_number]
            line_number += 1
            if not tokens or tokens[0].upper() == "HIERARCHY":
                continue
            keyword = tokens[0].upper()
            if keyword in ("ROOT", "JOINT"):
                names.append(" ".join(tokens[1:]))
                parents.append(stack[-1] if stack and keyword == "JOINT" else -1)
                offsets.append([0.0, 0.0, 0.0])
                channels.append([])
            elif keyword == "END":
                in_end_site = True
            elif keyword == "{":
                if not in_end_site:
                    stack.append(len(names) - 1)
            elif keyword == "}":
                if in_end_site:
                    in_end_site = False
                else:
                    stack.pop()
            elif keyword == "OFFSET":
                values = [float(value) for value in tokens[1:4]]
                if len(values) != 3:
                    raise ValueError("OFFSET needs 3 numbers")
                if in_end_site:
                    end_sites[len(names) - 1] = np.array(values)
                else:
                    offsets[-1] = values
            elif keyword == "CHANNELS":
                count = int(tokens[1])
                channels[-1] = tokens[2:2 + count]
                if len(channels[-1]) != count:
                    raise ValueError(f"CHANNELS announces {count} channels")
            elif keyword == "MOTION":
                break
            else:
                raise ValueError(f"unexpected '{tokens[0]}'")
        frames = int(tokens_by_line[line_number][-1])
        frame_time = float(tokens_by_line[line_number + 1][-1])
        rows = [[float(value) for value in tokens] for tokens in tokens_by_line[line_number + 2:] if tokens]
    except (ValueError, IndexError) as error:
        raise InputError(f"{name}: malformed BVH at line {line_number} ({error})") from None
    width = sum(len(c) for c in channels)
    if not names or len(rows) != frames or any(len(row) != width for row in rows):
        raise InputError(f"{name}: malformed BVH ({len(rows)} motion rows for {frames} frames of {width} channels)")
    return BVHMotion(names, parents, np.array(offsets, dtype=float).reshape(-1, 3), channels, frame_time,
                     np.array(rows, dtype=float).reshape(frames, width), end_sites)
