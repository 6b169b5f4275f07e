"""Where markers may go and which motion a layout is optimised for (journal "Geometric feasibility").

Feasible vertices face the back of the hand (``n · h > 0.9``) and move rigidly with one joint (skin
weight 1). A motion set is a posture trajectory ``theta (F, 26)``; keyframes are picked from it by
farthest-point sampling in the 20-D finger posture space (the journal uses 3–10 keyframes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.model import HandModel
from handmocap.core.model.joint_angles import read_result_joint_angles
from handmocap.core.model.skeleton import N_GLOBAL, N_PARAMS, N_POSTURE
from handmocap.core.prior import canonical_postures
from handmocap.core.simulate import global_motion, minimum_jerk_trajectory, simulate_joint_angles

FACING_THRESHOLD = 0.9
RIGID_WEIGHT_TOLERANCE = 1e-6
MIN_KEYFRAMES, MAX_KEYFRAMES = 3, 10
MOTION_SETS = ("grasps", "gestures", "all")
GESTURES = ("flat", "relaxed", "fist", "point", "peace", "thumbs_up", "ok_sign", "count_1", "count_2",
            "count_3", "count_4", "count_5", "spread", "claw", "pinch_open", "pinch_closed")
_GESTURE_SECONDS = (0.5, 0.5)   # transition and hold time per gesture (s)


def feasible_vertices(model: HandModel, facing_threshold: float = FACING_THRESHOLD) -> np.ndarray:
    """Ids ``(Vf,)`` of the vertices with ``n · h > facing_threshold`` and a single skin weight 1."""
    facing = model.vertex_normals @ model.back_direction > facing_threshold
    rigid = (model.skin_weights >= 1.0 - RIGID_WEIGHT_TOLERANCE).any(axis=1)
    return np.flatnonzero(facing & rigid)


def gesture_motion(n_frames: int, seed: int = 0, frame_rate: float = 100.0) -> np.ndarray:
    """``theta (n_frames, 26)``: the common gestures in random order, each reached and held, with a
    global wrist motion from the simulator."""
    rng = np.random.default_rng(seed)
    library = canonical_postures()
    seconds_per_key = sum(_GESTURE_SECONDS)
    count = int(np.ceil(n_frames / frame_rate / seconds_per_key)) + 1
    order = rng.permutation(np.resize(np.arange(len(GESTURES)), count))
    keys = [library["relaxed"]]
    times = [0.0]
    for index in order:
        keys += [library[GESTURES[index]]] * 2
        times += [times[-1] + _GESTURE_SECONDS[0], times[-1] + seconds_per_key]
    theta = np.empty((n_frames, N_PARAMS))
    theta[:, :N_GLOBAL] = global_motion(n_frames, rng, frame_rate)
    theta[:, N_GLOBAL:] = minimum_jerk_trajectory(np.array(keys), np.array(times), n_frames, frame_rate)
    return theta


def motion_from_results(paths: list[str | Path]) -> np.ndarray:
    """``theta (F, 26)`` of solved takes (result ``.npz`` files with ``joint_angles``), NaN frames dropped."""
    motions = [angles[np.isfinite(angles).all(axis=1)] for angles in map(read_result_joint_angles, paths)]
    motion = np.vstack(motions) if motions else np.empty((0, N_PARAMS))
    if len(motion) == 0:
        raise InputError("the motion set is empty: no solved frames in the given results")
    return motion


def motion_set(source: str | Path | list[str | Path], n_frames: int = 3000, seed: int = 0) -> np.ndarray:
    """The motion a layout is optimised for, ``theta (F, 26)``.

    ``source``: ``"grasps"`` (scripted grasp cycles through the prior-set Cutkosky/Feix grasps),
    ``"gestures"``, ``"all"`` (prior samples, grasps and gestures mixed), or result ``.npz`` file(s).
    """
    if isinstance(source, list):
        return motion_from_results(source)
    if str(source) == "grasps":
        return simulate_joint_angles(n_frames, seed, motion="grasps")
    if str(source) == "gestures":
        return gesture_motion(n_frames, seed)
    if str(source) == "all":
        return simulate_joint_angles(n_frames, seed, motion="mixed")
    if Path(source).suffix == ".npz":
        return motion_from_results([source])
    raise InputError(f"unknown motion set '{source}' (choose {', '.join(MOTION_SETS)} or result .npz files)")


def keyframes(motion: np.ndarray, count: int) -> np.ndarray:
    """Frame indices ``(count,)`` spread over the finger postures of ``motion (F, 26)`` by farthest-point
    sampling (20-D, rad): the first is the frame farthest from the mean posture."""
    motion = np.asarray(motion, dtype=float)
    if motion.ndim != 2 or motion.shape[1] != N_PARAMS or len(motion) == 0:
        raise InputError("the motion set is empty: keyframes need at least one frame of 26 joint angles")
    if not MIN_KEYFRAMES <= count <= MAX_KEYFRAMES:
        raise InputError(f"use {MIN_KEYFRAMES} to {MAX_KEYFRAMES} keyframes, not {count}")
    postures = motion[:, N_GLOBAL:N_GLOBAL + N_POSTURE]
    distance = np.linalg.norm(postures - postures.mean(axis=0), axis=1)
    chosen = [int(np.argmax(distance))]
    distance = np.linalg.norm(postures - postures[chosen[0]], axis=1)
    while len(chosen) < min(count, len(postures)):
        chosen.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(postures - postures[chosen[-1]], axis=1))
    return np.array(chosen, dtype=np.int64)
