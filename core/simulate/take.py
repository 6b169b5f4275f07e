"""Synthetic takes with ground truth: markers of a layout on a (re-proportioned) hand, moved by
:func:`core.simulate.motion.simulate_joint_angles`, with noise, occlusions, ghosts and an
unlabelled (per-frame shuffled) variant.

Occlusion model (cheap but geometric): eight cameras on a ring around and above the workspace
(:data:`CAMERA_POSITIONS`). Camera ``c`` sees marker ``m`` when the marker's skin normal faces it
(``n · direction > FACING_THRESHOLD``) and the line from the marker to the camera misses every
capsule of the hand (finger segments and a four-capsule palm) other than the marker's own segments.
A marker that lies inside another capsule (pressed between fingers, or a finger curled onto it) is
hidden. A marker is reconstructed when at least :data:`MIN_CAMERAS` cameras see it, as in a real
optical system. Curling fingers and turning the hand then hide markers for realistic stretches: on
the dense layout about 5 % of the samples are missing, gaps last a few frames to about a second
(median ≈ 17 frames, 90 % ≤ 80 frames at 100 Hz; the real DFKI glove take has thumb-tip gaps of
19-49 frames); the fingertips of curled fingers and the little finger are lost most. A frame never
loses every marker (the best-facing one is kept).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.durable import durable_stream, verify_zip
from handmocap.core.io.npz import load_npz
from handmocap.core.model import (
    HandModel,
    MarkerLayout,
    MarkerSet,
    load_layout,
    load_template,
    marker_positions_batch,
    resolve_layout,
)
from handmocap.core.model.hand_model import MAX_INFLUENCES
from handmocap.core.model.skeleton import HandProportions
from handmocap.core.model.template_mesh import build_template
from handmocap.core.simulate.motion import DEFAULT_FRAME_RATE, WORKSPACE_CENTRE, simulate_joint_angles

#: eight cameras (mm, world frame, Z up): a ring of radius 1.8 m around the workspace centre, at
#: alternating heights 0.5 m and 1.4 m above it
CAMERA_POSITIONS = WORKSPACE_CENTRE + np.array([
    [1800.0 * np.cos(angle), 1800.0 * np.sin(angle), 500.0 if index % 2 == 0 else 1400.0]
    for index, angle in enumerate(np.radians(np.arange(0.0, 360.0, 45.0)))
])
#: a camera sees a marker when the cosine between the marker's normal and the direction to it exceeds
#: this; slightly negative because a marker sphere stands off the skin and shows up to ~95° off its normal
FACING_THRESHOLD = -0.1
#: cameras needed to reconstruct a marker
MIN_CAMERAS = 2
#: capsules are shrunk by this factor for the line-of-sight test: they overestimate the fingers at
#: the joints, and grazing rays should not count as blocked
OCCLUDER_SHRINK = 0.85
#: a marker closer than this (mm) to the surface of another capsule is hidden (pressed/covered)
CONTACT_MARGIN = 1.0
#: a capsule whose joint has more than this skin weight at a marker's anchor is the marker's own segment
OWN_SEGMENT_WEIGHT = 0.1
#: ghost marker life (frames) and distance from the marker they appear next to (mm)
GHOST_LIFE = (1, 10)
GHOST_DISTANCE = (10.0, 60.0)
#: frames whose visibility is computed at once (the working memory is a few kB per frame)
VISIBILITY_BLOCK = 4096

REQUIRED_TRUTH = ("joint_angles", "marker_positions", "marker_names", "visible")


@dataclass
class SimulatedTake:
    """A synthetic take and its ground truth.

    ``truth``: ``joint_angles (F, 26)``, ``marker_positions (F, M, 3)`` mm noise-free (also where
    occluded), ``marker_names (M,)`` str, ``visible (F, M)`` bool, ``ghost_positions (F, G, 3)`` mm
    (NaN outside each ghost's life) and, for an unlabelled take, ``point_marker (F, P)``: the
    marker index each point column holds in each frame, -1 for a ghost or padding.
    """

    take: Take
    truth: dict[str, np.ndarray]


@njit(cache=True)
def _segment_distance(p0, p1, q0, q1):
    """Shortest distance (mm) between segments p0-p1 and q0-q1 (``(3,)`` each; Ericson 2005, 5.1.9)."""
    d1x, d1y, d1z = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    d2x, d2y, d2z = q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]
    rx, ry, rz = p0[0] - q0[0], p0[1] - q0[1], p0[2] - q0[2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denominator = a * e - b * b
    s = 0.0
    if denominator > 1e-12:
        s = min(1.0, max(0.0, (b * f - c * e) / denominator))
    t = (b * s + f) / e if e > 1e-12 else 0.0
    if t < 0.0:
        t = 0.0
        s = min(1.0, max(0.0, -c / a)) if a > 1e-12 else 0.0
    elif t > 1.0:
        t = 1.0
        s = min(1.0, max(0.0, (b - c) / a)) if a > 1e-12 else 0.0
    gx = rx + s * d1x - t * d2x
    gy = ry + s * d1y - t * d2y
    gz = rz + s * d1z - t * d2z
    return np.sqrt(gx * gx + gy * gy + gz * gz)


@njit(cache=True)
def _camera_counts(markers, normals, starts, ends, radii, may_occlude, cameras, facing_threshold,
                   shrink, contact_margin):
    """Per frame and marker: number of cameras that see it ``(F, M)`` and the best facing cosine.

    ``markers``/``normals (F, M, 3)``, capsules ``starts``/``ends (F, S, 3)``, ``radii (S,)``,
    ``may_occlude (M, S)`` bool, ``cameras (C, 3)``.
    """
    frames, count = markers.shape[0], markers.shape[1]
    segments = radii.shape[0]
    seen = np.zeros((frames, count), dtype=np.int64)
    facing = np.full((frames, count), -1.0)
    for f in range(frames):
        for m in range(count):
            point = markers[f, m]
            covered = False
            for s in range(segments):
                if may_occlude[m, s] and _segment_distance(point, point, starts[f, s], ends[f, s]) \
                        < radii[s] + contact_margin:
                    covered = True
                    break
            for c in range(cameras.shape[0]):
                dx, dy, dz = cameras[c, 0] - point[0], cameras[c, 1] - point[1], cameras[c, 2] - point[2]
                cosine = (normals[f, m, 0] * dx + normals[f, m, 1] * dy + normals[f, m, 2] * dz) \
                    / np.sqrt(dx * dx + dy * dy + dz * dz)
                facing[f, m] = max(facing[f, m], cosine)
                if covered or cosine <= facing_threshold:
                    continue
                blocked = False
                for s in range(segments):
                    if may_occlude[m, s] and _segment_distance(point, cameras[c], starts[f, s], ends[f, s]) \
                            < shrink * radii[s]:
                        blocked = True
                        break
                if not blocked:
                    seen[f, m] += 1
    return seen, facing


def _capsules(model: HandModel, proportions: HandProportions) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                        np.ndarray]:
    """Rest-pose capsules approximating the hand: starts, ends ``(S, 3)`` mm, radii ``(S,)`` mm and the
    joint each moves with ``(S,)``. Four palm capsules run from near the wrist to the finger knuckles."""
    skeleton = model.skeleton
    starts, ends, radii, joints = [], [], [], []
    for digit in range(1, 5):
        knuckle = skeleton.rest_positions[1 + 3 * digit]
        starts.append(knuckle * np.array([0.6, 0.15, 1.0]))
        ends.append(knuckle)
        radii.append(0.5 * proportions.palm_thickness)
        joints.append(0)
    for digit in range(5):
        for segment in range(3):
            joint = 1 + 3 * digit + segment
            starts.append(skeleton.rest_positions[joint])
            ends.append(skeleton.rest_positions[joint + 1] if segment < 2 else skeleton.tip_positions[digit])
            radii.append(proportions.finger_radii[digit, segment])
            joints.append(joint)
    return np.array(starts), np.array(ends), np.array(radii), np.array(joints)


def _visibility(model: HandModel, markers: MarkerSet, proportions: HandProportions, thetas: np.ndarray,
                marker_positions: np.ndarray) -> np.ndarray:
    """Which markers the cameras reconstruct, ``(F, M)`` bool (see the module docstring), computed
    :data:`VISIBILITY_BLOCK` frames at a time (each frame on its own) so the working memory stays small."""
    return np.concatenate([_visibility_block(model, markers, proportions, thetas[first:first + VISIBILITY_BLOCK],
                                             marker_positions[first:first + VISIBILITY_BLOCK])
                           for first in range(0, len(thetas), VISIBILITY_BLOCK)] or [np.zeros((0, len(markers.names)),
                                                                                              dtype=bool)])


def _visibility_block(model: HandModel, markers: MarkerSet, proportions: HandProportions, thetas: np.ndarray,
                      marker_positions: np.ndarray) -> np.ndarray:
    """:func:`_visibility` of a block of frames, ``(F, M)`` bool."""
    chain = model.chain
    transforms = [chain.skinning_matrices(theta) for theta in thetas]
    linear = np.stack([transform[0] for transform in transforms])            # (F, 16, 3, 3)
    translation = np.stack([transform[1] for transform in transforms])       # (F, 16, 3)
    rest_normals = model.vertex_normals[markers.vertex]                      # (M, 3)
    normals = np.zeros_like(marker_positions)
    for k in range(MAX_INFLUENCES):
        moved = np.einsum("fmab,mb->fma", linear[:, markers.influence_joints[:, k]], rest_normals)
        normals += markers.influence_weights[None, :, k, None] * moved
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    starts, ends, radii, joints = _capsules(model, proportions)
    posed_starts = np.einsum("fsab,sb->fsa", linear[:, joints], starts) + translation[:, joints]
    posed_ends = np.einsum("fsab,sb->fsa", linear[:, joints], ends) + translation[:, joints]
    # a marker's own segments (its skinning influences) never hide it
    own = (markers.influence_joints[:, :, None] == joints[None, None, :]) \
        & (markers.influence_weights[:, :, None] > OWN_SEGMENT_WEIGHT)
    may_occlude = ~own.any(axis=1)
    seen, facing = _camera_counts(np.ascontiguousarray(marker_positions), np.ascontiguousarray(normals),
                                  np.ascontiguousarray(posed_starts), np.ascontiguousarray(posed_ends),
                                  radii, may_occlude, CAMERA_POSITIONS, FACING_THRESHOLD, OCCLUDER_SHRINK,
                                  CONTACT_MARGIN)
    visible = seen >= MIN_CAMERAS
    empty = np.flatnonzero(~visible.any(axis=1))
    visible[empty, np.argmax(facing[empty], axis=1)] = True
    return visible


def _ghost_events(frames: int, count: int, ghost_rate: float, rng: np.random.Generator
                  ) -> list[tuple[int, int, int, np.ndarray]]:
    """Ghosts as ``(first frame, end frame (exclusive), marker, offset (3,) mm)``, in the order drawn.

    Ghost events start at random frames until about ``ghost_rate`` of the frames hold a ghost; an
    event lasts 1-10 frames and brings 1-3 ghosts (the first lives the whole event, the others part
    of it), each at a fixed offset of 10-60 mm from a random marker and moving with it."""
    target = round(ghost_rate * frames)
    has_ghost = np.zeros(frames, dtype=bool)
    covered = 0
    events = []
    while covered < target:
        start = int(rng.integers(frames))
        life = int(rng.integers(GHOST_LIFE[0], GHOST_LIFE[1] + 1))
        for index in range(int(rng.integers(1, 4))):
            own_life = life if index == 0 else int(rng.integers(1, life + 1))
            offset = rng.normal(size=3)
            offset *= rng.uniform(*GHOST_DISTANCE) / np.linalg.norm(offset)
            events.append((start, min(frames, start + own_life), int(rng.integers(count)), offset))
        covered += int((~has_ghost[start:start + life]).sum())
        has_ghost[start:start + life] = True
    return events


def _ghosts(marker_positions: np.ndarray, ghost_rate: float, rng: np.random.Generator) -> np.ndarray:
    """Ghost trajectories ``(F, G, 3)`` mm, NaN where a column holds no ghost (:func:`_ghost_events`).

    A column holds ghosts one after the other, at least one empty frame apart, so ``G`` is the largest
    number of ghosts alive at once (plus those that would touch), not the number of ghosts: the memory
    stays proportional to the take's length."""
    frames, count = marker_positions.shape[:2]
    events = _ghost_events(frames, count, ghost_rate, rng)
    free_from: list[int] = []                   # per column: the first frame a new ghost may start
    placed = []
    for first, end, marker, offset in sorted(events, key=lambda event: event[0]):
        column = next((column for column, frame in enumerate(free_from) if frame <= first), len(free_from))
        if column == len(free_from):
            free_from.append(0)
        free_from[column] = end + 1
        placed.append((column, first, end, marker, offset))
    ghosts = np.full((frames, len(free_from), 3), np.nan)
    for column, first, end, marker, offset in placed:
        ghosts[first:end, column] = marker_positions[first:end, marker] + offset
    return ghosts


def _shuffled_points(observed: np.ndarray, marker_count: int, rng: np.random.Generator
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame shuffled points ``(F, P, 3)`` from observed columns ``(F, M + G, 3)`` (NaN = absent)
    and the source marker index per point ``(F, P)`` (-1 for a ghost or padding)."""
    present = ~np.isnan(observed).any(axis=2)
    keys = rng.random(present.shape)
    keys[~present] = np.inf
    order = np.argsort(keys, axis=1)[:, :max(1, int(present.sum(axis=1).max()))]
    points = np.take_along_axis(observed, order[:, :, None], axis=1)
    kept = np.take_along_axis(present, order, axis=1)
    point_marker = np.where(kept & (order < marker_count), order, -1)
    return points, point_marker


def simulate_take(layout: str | MarkerLayout = "dense", n_frames: int = 600, seed: int = 0,
                  noise_mm: float = 0.0, ghost_rate: float = 0.0, occlusion: bool = False,
                  unlabelled: bool = False, proportions: HandProportions | None = None,
                  motion: str = "mixed", frame_rate: float = DEFAULT_FRAME_RATE,
                  progress: Callable[[float], None] | None = None) -> SimulatedTake:
    """A synthetic take of ``n_frames`` frames with ground truth (deterministic per ``seed``).

    ``layout``: shipped layout name or a :class:`MarkerLayout`; ``noise_mm``: Gaussian σ per
    coordinate (mm); ``ghost_rate``: share of frames (0..1) holding spurious points; ``occlusion``:
    hide markers the cameras cannot see (module docstring); ``unlabelled``: columns ``point_000``...
    of per-frame shuffled points instead of named markers; ``proportions``: a re-proportioned hand
    (its template is generated, which takes seconds) instead of the shipped template; ``motion``:
    see :func:`simulate_joint_angles`, whose output for ``(n_frames, seed, motion, frame_rate)`` is
    ``truth["joint_angles"]``. ``progress(fraction)`` hears each stage done (motion, markers, occlusion, points).
    """
    def report(fraction: float) -> None:
        if progress is not None:
            progress(fraction)

    if noise_mm < 0 or not 0.0 <= ghost_rate <= 1.0:
        raise InputError(f"noise must be >= 0 mm and the ghost rate within 0..1, "
                         f"got {noise_mm} mm and {ghost_rate}")
    layout = load_layout(layout) if isinstance(layout, str) else layout
    if proportions is None:
        model = load_template()
        proportions = HandProportions()
    else:
        model = build_template(proportions)
    markers = resolve_layout(model, layout)
    thetas = simulate_joint_angles(n_frames, seed, motion, frame_rate)
    report(0.3)
    positions = marker_positions_batch(model, markers, thetas)
    report(0.5)
    rng = np.random.default_rng([seed, 1])
    if occlusion:
        visible = _visibility(model, markers, proportions, thetas, positions)
    else:
        visible = np.ones(positions.shape[:2], dtype=bool)
    report(0.8)
    ghosts = _ghosts(positions, ghost_rate, rng)
    observed = np.concatenate([np.where(visible[:, :, None], positions, np.nan), ghosts], axis=1)
    observed += rng.normal(0.0, noise_mm, observed.shape)
    truth = {
        "joint_angles": thetas,
        "marker_positions": positions,
        "marker_names": np.array(markers.names),
        "visible": visible,
        "ghost_positions": ghosts,
    }
    if unlabelled:
        points, truth["point_marker"] = _shuffled_points(observed, len(markers.names), rng)
        names = [f"point_{index:03d}" for index in range(points.shape[1])]
    else:
        points = observed
        names = list(markers.names) + [f"ghost_{index:03d}" for index in range(ghosts.shape[1])]
    parameters = {"SIMULATION": {"LAYOUT": layout.name, "SEED": int(seed), "MOTION": motion,
                                 "NOISE_MM": float(noise_mm), "GHOST_RATE": float(ghost_rate),
                                 "OCCLUSION": int(occlusion), "UNLABELLED": int(unlabelled)}}
    take = Take(marker_names=names, marker_positions=points, frame_rate=frame_rate, vendor="simulated",
                parameters=parameters)
    report(1.0)
    return SimulatedTake(take=take, truth=truth)


def save_truth(truth: dict[str, np.ndarray], path: str | Path) -> None:
    """Store a truth dictionary as ``.npz`` through :mod:`core.io.durable` (WriteError naming the file)."""
    with durable_stream(path, verify=verify_zip) as stream:
        arrays: dict[str, Any] = dict(truth)  # typed Any: numpy's annotations match ndarray values against allow_pickle
        np.savez_compressed(stream, **arrays)


def load_truth(path: str | Path) -> dict[str, np.ndarray]:
    """Read a truth file written by :func:`save_truth`; :class:`InputError` when it is not one."""
    name = Path(path).name
    truth = load_npz(path, "a simulation truth file")
    missing = [key for key in REQUIRED_TRUTH if key not in truth]
    if missing:
        raise InputError(f"{name}: simulation truth lacks {', '.join(missing)}")
    return truth
