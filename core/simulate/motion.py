"""Synthetic hand motion: finger posture trajectories and global wrist motion, ``theta (F, 26)``.

Trajectories are key postures joined by minimum-jerk segments (Flash & Hogan 1985:
``s(τ) = 10τ³ - 15τ⁴ + 6τ⁵``), so velocity and acceleration are zero at every key and motion looks
like deliberate human movement. Segment durations follow the distance to travel at a random
average speed (fingers 115-230 °/s, wrist 150-400 mm/s, both above a minimum duration), which keeps
peak speeds (1.875 × the average for minimum jerk) in the range of everyday hand movements.
Frames are 0-based, frame ``f`` at time ``f / frame_rate`` s. Everything is deterministic for a
given ``numpy.random.Generator`` state.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from handmocap.core.errors import InputError
from handmocap.core.model.skeleton import N_GLOBAL, N_PARAMS, N_POSTURE, default_joint_limits
from handmocap.core.prior.canonical_postures import canonical_postures, heldout_grasp_postures, prior_grasp_postures
from handmocap.core.prior.pca_prior import PosturePrior, load_default_prior

DEFAULT_FRAME_RATE = 100.0
#: centre of the capture workspace (mm, world frame, Z up): a hand over a table about 1 m high
WORKSPACE_CENTRE = np.array([0.0, 0.0, 1000.0])
#: half extent of the wrist translation around the centre (mm)
WORKSPACE_HALF_EXTENT = np.array([150.0, 150.0, 100.0])
MOTIONS = ("mixed", "prior", "grasps", "heldout")

_FINGER_SPEED = (2.0, 4.0)        # rad/s, average speed of the fastest joint in a transition
_FINGER_MIN_DURATION = 0.35       # s
_WRIST_SPEED = (150.0, 400.0)     # mm/s
_WRIST_MIN_DURATION = 0.5         # s
_KEY_JITTER = np.radians(2.0)     # natural variation of a canonical posture each time it is used
_OPEN_POSTURES = ("relaxed", "flat", "pinch_open")
_GESTURES = ("point", "peace", "thumbs_up", "ok_sign", "count_1", "count_2", "count_3", "count_4",
             "count_5", "spread", "claw", "fist", "flat")
_LIBRARY = canonical_postures()


class _Keys:
    """A growing list of key values ``(D,)`` and the time (s) each is reached."""

    def __init__(self, first: np.ndarray) -> None:
        self.values = [np.asarray(first, dtype=float)]
        self.times = [0.0]

    @property
    def last(self) -> np.ndarray:
        return self.values[-1]

    @property
    def duration(self) -> float:
        return self.times[-1]

    def add(self, value: np.ndarray, seconds: float) -> None:
        self.values.append(np.asarray(value, dtype=float))
        self.times.append(self.times[-1] + seconds)


def minimum_jerk_trajectory(values: np.ndarray, times: np.ndarray, n_frames: int,
                            frame_rate: float) -> np.ndarray:
    """Sample keys ``values (K, D)`` reached at ``times (K,)`` s (increasing) at ``n_frames`` frames.

    Between consecutive keys the value follows a minimum-jerk blend; after the last key it holds.
    Returns ``(n_frames, D)``.
    """
    values = np.asarray(values, dtype=float)
    times = np.asarray(times, dtype=float)
    frame_times = np.arange(n_frames) / frame_rate
    if len(times) == 1:
        return np.repeat(values[:1], n_frames, axis=0)
    segment = np.clip(np.searchsorted(times, frame_times, side="right") - 1, 0, len(times) - 2)
    span = times[segment + 1] - times[segment]
    tau = np.clip((frame_times - times[segment]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    blend = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    return values[segment] + blend[:, None] * (values[segment + 1] - values[segment])


def _finger_duration(start: np.ndarray, end: np.ndarray, rng: np.random.Generator) -> float:
    distance = float(np.max(np.abs(end - start)))
    return max(_FINGER_MIN_DURATION, distance / rng.uniform(*_FINGER_SPEED))


def _finger_limits() -> tuple[np.ndarray, np.ndarray]:
    lower, upper = default_joint_limits()
    return lower[N_GLOBAL:], upper[N_GLOBAL:]


def _jittered(posture: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    lower, upper = _finger_limits()
    return np.clip(posture + rng.normal(0.0, _KEY_JITTER, N_POSTURE), lower, upper)


def _move(keys: _Keys, posture: np.ndarray, rng: np.random.Generator, hold: float = 0.0) -> None:
    """Append a transition to ``posture`` and, when ``hold`` (s) is positive, a hold there."""
    keys.add(posture, _finger_duration(keys.last, posture, rng))
    if hold > 0:
        keys.add(posture, hold)


def _sample_prior_posture(prior: PosturePrior, rng: np.random.Generator) -> np.ndarray:
    alpha = np.clip(rng.normal(0.0, prior.stddev), prior.alpha_lower, prior.alpha_upper)
    return np.clip(prior.mean + prior.components @ alpha, prior.angle_lower, prior.angle_upper)


def _prior_episode(keys: _Keys, prior: PosturePrior, rng: np.random.Generator) -> None:
    """Three to six postures sampled from the prior, with an occasional short hold."""
    for _ in range(rng.integers(3, 7)):
        hold = rng.uniform(0.1, 0.5) if rng.random() < 0.3 else 0.0
        _move(keys, _sample_prior_posture(prior, rng), rng, hold)


def _grasp_episode(keys: _Keys, grasp: np.ndarray, rng: np.random.Generator) -> None:
    """Open -> pre-shape -> grasp -> hold -> release.

    The pre-shape opens wider than the grasp (the hand's aperture overshoots before closing on an
    object, Jeannerod 1984): the grasp blended 40-70 % towards the spread hand.
    """
    opened = _jittered(_LIBRARY[_OPEN_POSTURES[rng.integers(len(_OPEN_POSTURES))]], rng)
    _move(keys, opened, rng, hold=rng.uniform(0.2, 0.6))
    target = _jittered(grasp, rng)
    aperture = rng.uniform(0.4, 0.7)
    _move(keys, (1.0 - aperture) * target + aperture * _LIBRARY["spread"], rng)
    _move(keys, target, rng, hold=rng.uniform(0.3, 1.0))
    _move(keys, _jittered(_LIBRARY["relaxed"], rng), rng, hold=rng.uniform(0.2, 0.6))


def _gesture_episode(keys: _Keys, rng: np.random.Generator) -> None:
    """A gesture (count, point, OK, ...) shown and held."""
    gesture = _LIBRARY[_GESTURES[rng.integers(len(_GESTURES))]]
    _move(keys, _jittered(gesture, rng), rng, hold=rng.uniform(0.4, 1.0))


def _finger_trajectory(n_frames: int, frame_rate: float, rng: np.random.Generator, episode) -> np.ndarray:
    """Run ``episode(keys)`` until the keys cover ``n_frames``; returns ``(n_frames, 20)`` rad."""
    keys = _Keys(_jittered(_LIBRARY["relaxed"], rng))
    while keys.duration < (n_frames - 1) / frame_rate:
        episode(keys)
    lower, upper = _finger_limits()
    trajectory = minimum_jerk_trajectory(np.array(keys.values), np.array(keys.times), n_frames, frame_rate)
    return np.clip(trajectory, lower, upper)


def prior_motion(prior: PosturePrior, n_frames: int, rng: np.random.Generator,
                 frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Finger postures ``(n_frames, 20)`` rad moving between postures sampled from ``prior``
    (Gaussian in PC space, clipped to the training PC and angle ranges)."""
    return _finger_trajectory(n_frames, frame_rate, rng, lambda keys: _prior_episode(keys, prior, rng))


def grasp_motion(postures: list[np.ndarray], n_frames: int, rng: np.random.Generator,
                 frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Scripted grasp cycles (open, pre-shape, grasp, hold, release) through randomly chosen
    ``postures`` (each ``(20,)`` rad); returns ``(n_frames, 20)`` rad."""
    if not postures:
        raise InputError("grasp motion needs at least one grasp posture")
    return _finger_trajectory(
        n_frames, frame_rate, rng,
        lambda keys: _grasp_episode(keys, postures[rng.integers(len(postures))], rng))


def heldout_grasp_motion(n_frames: int, rng: np.random.Generator,
                         frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Grasp cycles through the held-out grasps, which the default prior has never seen."""
    return grasp_motion(list(heldout_grasp_postures().values()), n_frames, rng, frame_rate)


def mixed_motion(prior: PosturePrior, n_frames: int, rng: np.random.Generator,
                 frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Episodes of prior samples (30 %), grasp cycles through the prior-set grasps (45 %) and
    gestures (25 %); returns ``(n_frames, 20)`` rad."""
    grasps = list(prior_grasp_postures().values())

    def episode(keys: _Keys) -> None:
        choice = rng.random()
        if choice < 0.3:
            _prior_episode(keys, prior, rng)
        elif choice < 0.75:
            _grasp_episode(keys, grasps[rng.integers(len(grasps))], rng)
        else:
            _gesture_episode(keys, rng)

    return _finger_trajectory(n_frames, frame_rate, rng, episode)


def _continuous_rotation_vectors(rotations: Rotation) -> np.ndarray:
    """Rotation vectors ``(F, 3)`` without the sign flip at 180°: each frame picks the equivalent
    vector (angle - 2π along the same axis) closest to the previous frame's."""
    vectors = rotations.as_rotvec()
    for frame in range(1, len(vectors)):
        angle = np.linalg.norm(vectors[frame])
        if angle > np.pi / 2:
            alternative = vectors[frame] * (1.0 - 2.0 * np.pi / angle)
            previous = vectors[frame - 1]
            if np.linalg.norm(alternative - previous) < np.linalg.norm(vectors[frame] - previous):
                vectors[frame] = alternative
    return vectors


def global_motion(n_frames: int, rng: np.random.Generator,
                  frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Wrist translation (mm) and rotation vector (rad), ``(n_frames, 6)``.

    The wrist wanders within :data:`WORKSPACE_HALF_EXTENT` of :data:`WORKSPACE_CENTRE`. The hand is
    mostly palm-down (rest frame: back of the hand +Z, fingers +Y): yaw ±45°, pitch ±20°, roll ±25°
    about the forearm axis, with occasional turns (10 % of orientation keys) of 60-150° of
    supination that are held briefly and then undone. Orientation keys are Euler angles
    (``R = Rz(yaw) Rx(pitch) Ry(roll)``) blended with minimum jerk.
    """
    end = (n_frames - 1) / frame_rate
    positions = _Keys(WORKSPACE_CENTRE + rng.uniform(-0.5, 0.5, 3) * WORKSPACE_HALF_EXTENT)
    while positions.duration < end:
        target = WORKSPACE_CENTRE + rng.uniform(-1.0, 1.0, 3) * WORKSPACE_HALF_EXTENT
        distance = float(np.linalg.norm(target - positions.last))
        positions.add(target, max(_WRIST_MIN_DURATION, distance / rng.uniform(*_WRIST_SPEED)))
        if rng.random() < 0.3:
            positions.add(target, rng.uniform(0.2, 1.0))
    limits = np.radians([45.0, 20.0, 25.0])
    angles = _Keys(rng.uniform(-0.5, 0.5, 3) * limits)
    while angles.duration < end:
        target = rng.uniform(-1.0, 1.0, 3) * limits
        if rng.random() < 0.1:
            target[2] = np.radians(rng.uniform(60.0, 150.0))
            angles.add(target, rng.uniform(0.5, 1.0))
            angles.add(target, rng.uniform(0.1, 0.4))
        else:
            angles.add(target, rng.uniform(0.6, 1.6))
    translation = minimum_jerk_trajectory(np.array(positions.values), np.array(positions.times),
                                          n_frames, frame_rate)
    euler = minimum_jerk_trajectory(np.array(angles.values), np.array(angles.times), n_frames, frame_rate)
    rotation = _continuous_rotation_vectors(Rotation.from_euler("ZXY", euler))
    return np.hstack([translation, rotation])


def simulate_joint_angles(n_frames: int, seed: int = 0, motion: str = "mixed",
                          frame_rate: float = DEFAULT_FRAME_RATE) -> np.ndarray:
    """Joint angles ``theta (n_frames, 26)`` (mm, rad) of a synthetic take, deterministic per ``seed``.

    ``motion``: ``"mixed"`` (prior samples, prior-set grasps and gestures), ``"prior"`` (samples of
    the default prior), ``"grasps"`` (grasp cycles through the prior-set grasps) or ``"heldout"``
    (grasp cycles through the held-out grasps). Finger angles stay inside :func:`default_joint_limits`.
    """
    if n_frames < 1:
        raise InputError(f"a simulated take needs at least one frame, got {n_frames}")
    if motion not in MOTIONS:
        raise InputError(f"unknown motion '{motion}' (choose from {', '.join(MOTIONS)})")
    if not frame_rate > 0:
        raise InputError(f"frame rate must be positive, got {frame_rate}")
    rng = np.random.default_rng(seed)
    theta = np.empty((n_frames, N_PARAMS))
    theta[:, :N_GLOBAL] = global_motion(n_frames, rng, frame_rate)
    if motion == "mixed":
        theta[:, N_GLOBAL:] = mixed_motion(load_default_prior(), n_frames, rng, frame_rate)
    elif motion == "prior":
        theta[:, N_GLOBAL:] = prior_motion(load_default_prior(), n_frames, rng, frame_rate)
    elif motion == "grasps":
        theta[:, N_GLOBAL:] = grasp_motion(list(prior_grasp_postures().values()), n_frames, rng, frame_rate)
    else:
        theta[:, N_GLOBAL:] = heldout_grasp_motion(n_frames, rng, frame_rate)
    return theta
