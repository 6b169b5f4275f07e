"""Markers + RGB-D fusion of a take (Zhao et al. 2012): :func:`fuse_take`.

1. Markers-only layered IK of the whole take predicts the pose at every RGB-D frame (crop, GrabCut
   initialisation, wrist cut) and gives the first frame's pose (the paper initialises by ICP + IK on markers).
2. Every RGB-D frame inside the take is solved on eq. 3, sequentially, from the previous frame's solution:
   ``optimiser="pso"``: the paper's swarm; ``"icp"``: a few swarm generations, then articulated ICP (thesis Ch. 6)
   with the soft posture prior over the online-adapted subspace (thesis Ch. 5; postures of frames with every
   marker seen are learnt).
3. Frame-rate lifting to the mocap frames (§6, :mod:`core.fusion.lifting`).

Long work with ``progress(fraction)`` and ``cancelled()`` callbacks like :func:`core.ik.solve_take`; raises
:class:`core.errors.CancelledError` when cancelled.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.fusion.energy import TERMS, EnergyWeights, FrameEnergy
from handmocap.core.fusion.hand_render import HandRenderer
from handmocap.core.fusion.icp import ArticulatedICP, ICPSettings
from handmocap.core.fusion.lifting import lift
from handmocap.core.fusion.observation import ideal_image, observe
from handmocap.core.fusion.pso import SwarmSettings, particle_swarm
from handmocap.core.fusion.subspace import AdaptiveSubspace
from handmocap.core.ik import IKSettings, match_layout, solve_positions
from handmocap.core.io.durable import durable_stream, verify_zip
from handmocap.core.model import HandModel, MarkerLayout, load_layout, load_template, resolve_layout
from handmocap.core.model.skeleton import N_GLOBAL, PARAM_NAMES, default_joint_limits
from handmocap.core.prior import PosturePrior, load_default_prior

OPTIMISERS = ("icp", "pso")
#: RGB-D frames whose colour is used for the background estimate when none is given (per-pixel median)
BACKGROUND_FRAMES = 15


class FrameStream(Protocol):
    """What :func:`fuse_take` reads of a camera stream (e.g. :class:`core.camera.frames.FrameSource`)."""

    def __len__(self) -> int: ...

    def frame(self, index: int) -> np.ndarray: ...

    def time(self, index: int) -> float: ...


@dataclass
class RGBDFrames:
    """An RGB-D recording: ``depth`` frames (mm, 0 = none; the camera's clock), optional ``colour`` frames of the
    same instants, an optional empty-scene ``background`` colour image, an optional wristband hue range (OpenCV
    hue 0..180)."""

    depth: FrameStream
    colour: FrameStream | None = None
    background: np.ndarray | None = None
    wristband_hue: tuple[int, int] | None = None


@dataclass(frozen=True)
class FusionSettings:
    """Optimiser, energy weights, swarm and ICP settings, subspace adaptation, lifting."""

    optimiser: str = "icp"
    weights: EnergyWeights = field(default_factory=EnergyWeights)
    swarm: SwarmSettings = field(default_factory=SwarmSettings)
    #: the swarm that seeds the ICP
    seed_swarm: SwarmSettings = field(default_factory=lambda: SwarmSettings(particles=8, generations=3))
    icp: ICPSettings = field(default_factory=ICPSettings)
    #: adapt the posture subspace to the fused postures of the frames whose markers are all seen (a posture is
    #: learnt only where the markers vouch for it: postures fitted to depth alone would teach the prior their errors)
    adapt_subspace: bool = True
    #: samples in the adaptation buffer (thesis: 250 at 25 Hz ≈ 10 s; here 0.5 s of a 30 Hz camera)
    subspace_buffer: int = 15
    max_side: int = 96
    lift_pull: float = 10.0
    filter_frames: float = 2.0
    random_seed: int = 0

    def __post_init__(self) -> None:
        if self.optimiser not in OPTIMISERS:
            raise InputError(f"unknown optimiser '{self.optimiser}' (use {', '.join(OPTIMISERS)})")


@dataclass
class FusionResult:
    """``joint_angles (F,26)`` per mocap frame; ``rgbd_joint_angles (K,26)`` at the RGB-D frames ``rgbd_frames (K,)``
    (camera frame index) seen at fractional mocap frames ``rgbd_mocap_frames (K,)``; ``energy_terms (K,5)``
    unweighted (:data:`TERMS`) at the solution; ``markers_only (F,26)`` the layered IK it started from."""

    joint_angles: np.ndarray
    rgbd_joint_angles: np.ndarray
    rgbd_frames: np.ndarray
    rgbd_mocap_frames: np.ndarray
    energy_terms: np.ndarray
    markers_only: np.ndarray
    optimiser: str
    seconds_per_rgbd_frame: float
    silhouette_sources: list[str]
    subspace: dict
    frame_rate: float = 100.0
    first_frame: int = 1

    def save(self, path: str | Path) -> None:
        """Write ``.npz`` through :mod:`core.io.durable`."""
        with durable_stream(path, verify=verify_zip) as stream:
            np.savez_compressed(stream, joint_angles=self.joint_angles, rgbd_joint_angles=self.rgbd_joint_angles,
                                rgbd_frames=self.rgbd_frames, rgbd_mocap_frames=self.rgbd_mocap_frames,
                                energy_terms=self.energy_terms, energy_term_names=np.array(TERMS),
                                markers_only=self.markers_only, optimiser=self.optimiser,
                                seconds_per_rgbd_frame=self.seconds_per_rgbd_frame,
                                silhouette_sources=np.array(self.silhouette_sources),
                                frame_rate=self.frame_rate, first_frame=self.first_frame,
                                param_names=np.array(PARAM_NAMES))


def _background(frames: RGBDFrames, camera: Camera) -> np.ndarray | None:
    if frames.colour is None:
        return None
    if frames.background is not None:
        return ideal_image(frames.background, camera)
    picks = np.unique(np.linspace(0, len(frames.colour) - 1, min(BACKGROUND_FRAMES, len(frames.colour))).astype(int))
    return ideal_image(np.median(np.stack([frames.colour.frame(k) for k in picks]), axis=0).astype(np.uint8), camera)


def _interpolate_targets(targets: np.ndarray, position: float) -> np.ndarray:
    """Markers (M,3) at fractional frame ``position``: linear between the two frames (NaN where either is)."""
    low = int(np.floor(position))
    high, weight = min(low + 1, len(targets) - 1), position - low
    return (1 - weight) * targets[low] + weight * targets[high]


def _prior_digits(markers_seen: np.ndarray, digit_of_marker: np.ndarray) -> np.ndarray:
    """Digits (5,) bool whose markers are not all seen in the frame."""
    held = np.zeros(5, dtype=bool)
    for digit in range(5):
        mine = digit_of_marker == digit
        held[digit] = not (mine.any() and markers_seen[mine].all())
    return held


def fuse_take(take, camera: Camera, frames: RGBDFrames, settings: FusionSettings | None = None,
              progress: Callable[[float], None] | None = None, cancelled: Callable[[], bool] | None = None,
              layout: MarkerLayout | str = "dense", model: HandModel | None = None,
              prior: PosturePrior | None = None, camera_frames: Sequence[int] | None = None) -> FusionResult:
    """Fuse a labelled take (``core.io.Take``) with an RGB-D recording of it by a registered ``camera`` (its
    clock maps camera time to mocap time). ``camera_frames``: the RGB-D frames to solve (default: all inside the
    take). See the module docstring."""
    settings = settings or FusionSettings()
    layout = load_layout(layout) if isinstance(layout, str) else layout
    model = model or load_template()
    prior = prior or load_default_prior()
    if take.n_frames == 0:
        raise InputError("the take has no frames")
    if not camera.registered:
        raise InputError(f"camera '{camera.name}' is not registered to the mocap space (run 'handmocap camera "
                         "register' first)")
    columns = match_layout(take.marker_names, layout)
    markers = resolve_layout(model, layout)
    targets = np.full((take.n_frames, len(columns), 3), np.nan)
    targets[:, columns >= 0] = take.marker_positions[:, columns[columns >= 0]]
    report = progress or (lambda fraction: None)

    def check() -> None:
        if cancelled is not None and cancelled():
            raise CancelledError("fusion cancelled; the take is unchanged")

    markers_only = solve_positions(targets, model, markers, prior, IKSettings(method="layered"),
                                   lambda fraction: report(0.1 * fraction), cancelled).joint_angles
    candidates = range(len(frames.depth)) if camera_frames is None else camera_frames
    chosen, positions = [], []
    for index in candidates:
        position = float(camera.clock.mocap_frame(frames.depth.time(index), take.frame_rate))
        if 0.0 <= position <= take.n_frames - 1 and np.isfinite(markers_only[int(round(position))]).all():
            chosen.append(int(index))
            positions.append(position)
    if not chosen:
        raise InputError("no RGB-D frame falls inside the take (check the camera's clock offset)")
    renderer = HandRenderer(model, camera)
    lower, upper = default_joint_limits()
    subspace = AdaptiveSubspace(prior, buffer=settings.subspace_buffer)
    icp = ArticulatedICP(renderer, markers, lower, upper, settings.icp)
    digit_of_marker = np.array([(joint - 1) // 3 if joint > 0 else -1 for joint in
                                markers.influence_joints[np.arange(len(markers.names)),
                                                         markers.influence_weights.argmax(axis=1)]])
    background = _background(frames, camera)
    rng = np.random.default_rng(settings.random_seed)
    solutions, terms, sources = [], [], []
    previous = None
    solving = 0.0
    for step, (index, position) in enumerate(zip(chosen, positions, strict=True)):
        check()
        raw_depth = frames.depth.frame(index)
        raw_colour = None if frames.colour is None else frames.colour.frame(index)
        started = time.perf_counter()
        frame_targets = _interpolate_targets(targets, position)
        guess = markers_only[int(round(position))]
        depth = ideal_image(raw_depth, camera, nearest=True)
        colour = None if raw_colour is None else ideal_image(raw_colour, camera)
        observation = observe(renderer, guess if previous is None else previous, depth, colour, background,
                              frame_targets, frames.wristband_hue, settings.max_side)
        energy = FrameEnergy(renderer, observation, markers, previous, settings.weights)
        start = guess if previous is None else previous
        extra = () if previous is None else (guess,)
        if settings.optimiser == "pso":
            theta, _ = particle_swarm(energy, start, lower, upper, settings.swarm, rng, extra, cancelled=cancelled)
        else:
            theta, _ = particle_swarm(energy, start, lower, upper, settings.seed_swarm, rng, extra,
                                      cancelled=cancelled)
            seen = np.isfinite(frame_targets).all(axis=1)
            theta = icp.fit(theta, observation, subspace.prior_matrix(), subspace.mean,
                            _prior_digits(seen, digit_of_marker), previous)
            if settings.adapt_subspace and seen.all():
                subspace.offer(theta[N_GLOBAL:])
        solutions.append(theta)
        terms.append(energy.terms(theta))
        sources.append(observation.source)
        previous = theta
        solving += time.perf_counter() - started
        report(0.1 + 0.8 * (step + 1) / len(chosen))
    seconds = solving / len(chosen)
    check()
    key_frames, key_poses = np.array(positions), np.array(solutions)
    order = np.argsort(key_frames)
    lifted = lift(model, markers, targets, key_frames[order], key_poses[order], lower, upper, settings.lift_pull,
                  settings.filter_frames)
    report(1.0)
    return FusionResult(lifted, key_poses, np.array(chosen), key_frames, np.array(terms), markers_only,
                        settings.optimiser, seconds, sources, subspace.report(), take.frame_rate, take.first_frame)
