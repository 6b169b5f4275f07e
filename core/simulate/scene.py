"""Synthetic labelling scenes: a right and a left hand and rigid objects, with ground truth.

The right hand moves around ``WORKSPACE_CENTRE + (+SIDE_OFFSET_MM, 0, 0)`` and the left hand around
``WORKSPACE_CENTRE − (SIDE_OFFSET_MM, 0, 0)`` (the motions of :func:`simulate_joint_angles`, other
seeds), so the hands never touch. Rigid objects (a box, a cylinder and, for three, a sphere) stand in
a row ``OBJECT_ROW_Y_MM`` in front of the workspace and drift slowly (±40 mm, ±0.5 rad about Z,
±0.2 rad tilt). Hands are occluded by the camera model of :mod:`core.simulate.take`; object markers
drop out in random gaps (5-30 frames, about 3 % of their samples). Gaussian noise on every
coordinate, ghosts in about ``ghost_rate`` of the frames next to random markers of the scene, and the
points are shuffled per frame. ``truth["point_marker"] (F,P)`` indexes the scene's marker list
(``R_``/``L_``-prefixed hand markers when both hands are in, then the objects' markers), the order
:func:`core.labelling.label_scene` uses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.model import MarkerLayout, load_layout, load_template, marker_positions_batch, resolve_layout
from handmocap.core.model.objects import ObjectSpec, object_from_json
from handmocap.core.model.skeleton import HandProportions
from handmocap.core.simulate.motion import DEFAULT_FRAME_RATE, WORKSPACE_CENTRE, simulate_joint_angles
from handmocap.core.simulate.take import _ghosts, _shuffled_points, _visibility

SIDE_OFFSET_MM = 400.0
OBJECT_ROW_Y_MM = 520.0

#: the objects of a simulated scene, in their own frames (see :mod:`core.model.objects`)
SCENE_OBJECTS = (
    {"name": "box", "type": "box", "size_mm": [90.0, 60.0, 40.0],
     "markers": {"box1": [45.0, -20.0, 24.0], "box2": [10.0, 30.0, 24.0], "box3": [-45.0, 5.0, 24.0],
                 "box4": [-20.0, -30.0, 0.0]}},
    {"name": "cup", "type": "cylinder", "radius_mm": 35.0, "height_mm": 100.0,
     "markers": {"cup1": [39.0, 0.0, 45.0], "cup2": [0.0, 39.0, 15.0], "cup3": [-27.6, -27.6, -10.0],
                 "cup4": [33.8, -19.5, -35.0]}},
    {"name": "ball", "type": "sphere", "radius_mm": 32.0,
     "markers": {"ball1": [0.0, 0.0, 36.0], "ball2": [36.0, 0.0, 0.0], "ball3": [0.0, -25.5, -25.5],
                 "ball4": [-20.8, 20.8, 20.8]}},
)


@dataclass
class SimulatedScene:
    """A synthetic scene take, its truth and the object specs.

    ``truth``: ``marker_names (M,)``, ``marker_positions (F,M,3)`` mm noise-free, ``visible (F,M)``,
    ``point_marker (F,P)`` (-1 ghost or padding), ``model_of_marker (M,)``, ``joint_angles_right`` /
    ``joint_angles_left (F,26)``, ``object_pose_<name> (F,4,4)``.
    """

    take: Take
    truth: dict[str, np.ndarray]
    objects: list[ObjectSpec]


def scene_objects(count: int) -> list[ObjectSpec]:
    """The first ``count`` (0-3) objects of :data:`SCENE_OBJECTS` as specs."""
    if not 0 <= count <= len(SCENE_OBJECTS):
        raise InputError(f"a simulated scene has 0 to {len(SCENE_OBJECTS)} objects, not {count}")
    return [object_from_json(entry, "simulated scene") for entry in SCENE_OBJECTS[:count]]


def _object_poses(count: int, n_frames: int, rng: np.random.Generator, frame_rate: float) -> np.ndarray:
    """Slowly drifting poses ``(count, F, 4, 4)`` of the objects, in a row in front of the hands."""
    time = np.arange(n_frames) / frame_rate
    poses = np.tile(np.eye(4), (count, n_frames, 1, 1))
    for index in range(count):
        base = WORKSPACE_CENTRE + np.array([(index - (count - 1) / 2.0) * 260.0, OBJECT_ROW_Y_MM, -60.0])
        frequencies = rng.uniform(0.05, 0.25, 6)
        phases = rng.uniform(0.0, 2.0 * np.pi, 6)
        wave = np.sin(2.0 * np.pi * frequencies[None, :] * time[:, None] + phases[None, :])   # (F,6)
        poses[index, :, :3, 3] = base + 40.0 * wave[:, :3]
        angles = np.column_stack([0.2 * wave[:, 3], 0.2 * wave[:, 4], rng.uniform(-np.pi, np.pi) + 0.5 * wave[:, 5]])
        poses[index, :, :3, :3] = Rotation.from_euler("xyz", angles).as_matrix()
    return poses


def _object_visibility(shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Random dropouts of object markers ``(F,K)`` bool: gaps of 5-30 frames, ~3 % of the samples."""
    frames, count = shape
    visible = np.ones(shape, dtype=bool)
    for marker in range(count):
        while (~visible[:, marker]).mean() < 0.03 and frames > 30:
            start, length = int(rng.integers(frames)), int(rng.integers(5, 31))
            visible[start:start + length, marker] = False
    visible[0] = True   # the first frame shows every object marker (initialisation)
    return visible


def simulate_scene(layout: str | MarkerLayout = "dense", n_frames: int = 600, seed: int = 0,
                   hands: str = "both", n_objects: int = 2, noise_mm: float = 0.3, ghost_rate: float = 0.05,
                   occlusion: bool = True, frame_rate: float = DEFAULT_FRAME_RATE,
                   motion: str = "mixed") -> SimulatedScene:
    """A synthetic unlabelled scene take (module docstring), deterministic per ``seed``.

    ``hands``: "right", "left" or "both"; ``n_objects``: 0-3 rigid objects; ``motion`` of the hands (e.g.
    "heldout": grasp cycles through held-out grasps, fingers strongly flexed and pressed together); other
    arguments as :func:`core.simulate.simulate_take`.
    """
    if hands not in ("right", "left", "both"):
        raise InputError(f"hands must be right, left or both, not '{hands}'")
    if noise_mm < 0 or not 0.0 <= ghost_rate <= 1.0:
        raise InputError(f"noise must be >= 0 mm and the ghost rate within 0..1, got {noise_mm} mm and {ghost_rate}")
    layout = load_layout(layout) if isinstance(layout, str) else layout
    sides = ["right", "left"] if hands == "both" else [hands]
    rng = np.random.default_rng([seed, 7])
    names: list[str] = []
    owners: list[int] = []
    positions, visible = [], []
    truth: dict[str, np.ndarray] = {}
    for number, side in enumerate(sides):
        model = load_template(side)
        markers = resolve_layout(model, layout)
        thetas = simulate_joint_angles(n_frames, seed + 1000 * number, motion, frame_rate)
        if len(sides) > 1:
            thetas[:, 0] += SIDE_OFFSET_MM if side == "right" else -SIDE_OFFSET_MM
        hand_positions = marker_positions_batch(model, markers, thetas)
        positions.append(hand_positions)
        visible.append(_visibility(model, markers, HandProportions(), thetas, hand_positions) if occlusion
                       else np.ones(hand_positions.shape[:2], dtype=bool))
        prefix = ("R_" if side == "right" else "L_") if len(sides) > 1 else ""
        names += [prefix + name for name in markers.names]
        owners += [number] * len(markers.names)
        truth[f"joint_angles_{side}"] = thetas
    objects = scene_objects(n_objects)
    poses = _object_poses(len(objects), n_frames, rng, frame_rate)
    for number, spec in enumerate(objects):
        local = spec.marker_positions
        moved = np.einsum("fab,kb->fka", poses[number, :, :3, :3], local) + poses[number, :, None, :3, 3]
        positions.append(moved)
        visible.append(_object_visibility(moved.shape[:2], rng) if occlusion
                       else np.ones(moved.shape[:2], dtype=bool))
        names += list(spec.marker_names)
        owners += [len(sides) + number] * len(local)
        truth[f"object_pose_{spec.name}"] = poses[number]
    all_positions = np.concatenate(positions, axis=1)
    all_visible = np.concatenate(visible, axis=1)
    ghosts = _ghosts(all_positions, ghost_rate, rng)
    observed = np.concatenate([np.where(all_visible[:, :, None], all_positions, np.nan), ghosts], axis=1)
    observed += rng.normal(0.0, noise_mm, observed.shape)
    points, point_marker = _shuffled_points(observed, len(names), rng)
    truth.update({"marker_names": np.array(names), "marker_positions": all_positions, "visible": all_visible,
                  "point_marker": point_marker, "model_of_marker": np.array(owners, dtype=np.int64),
                  "ghost_positions": ghosts})
    parameters = {"SIMULATION": {"LAYOUT": layout.name, "SEED": int(seed), "HANDS": hands,
                                 "OBJECTS": int(len(objects)), "NOISE_MM": float(noise_mm),
                                 "GHOST_RATE": float(ghost_rate), "OCCLUSION": int(occlusion), "UNLABELLED": 1}}
    take = Take(marker_names=[f"point_{index:03d}" for index in range(points.shape[1])], marker_positions=points,
                frame_rate=frame_rate, vendor="simulated", parameters=parameters)
    return SimulatedScene(take, truth, objects)
