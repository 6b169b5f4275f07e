"""Markers + RGB-D fusion against markers-only layered IK on synthetic takes (``handmocap evaluate fusion``).

Per seed: a simulated take (as :func:`core.simulate.camera.simulate_camera_take`: 100 Hz mocap, 3 s, finger motion
:data:`MOTIONS` in turn, 24-marker dense layout, 0.3 mm marker noise) filmed by a simulated RGB-D camera
(30 Hz, Kinect-like depth, lens distortion, a clean plate of the empty scene as background) in which the thumb
tip and IP markers and the ring tip and DIP markers (``thumb_distal``, ``thumb_proximal``, ``ring_distal``,
``ring_middle``) are hidden for one stretch of :data:`HIDDEN_SECONDS` s, as in Zhao et al. Fig. 6. Errors are
mean distances (mm) of the middle joint, distal joint and tip of the occluded digits (thumb, ring) and of the
visible fingers (index, middle, little) over the mocap frames of the stretch, and the occluded digits' error over
the frames where the camera sees the hidden segments (:func:`camera_sees_hidden`) and where it does not; the
ratio the fusion would reach if it were exact wherever the camera sees them bounds what better depth fitting
alone can give. The swarm (the paper's settings)
is run on the first :data:`SWARM_FRAMES` RGB-D frames of the stretch only (it takes seconds per frame).

Development used seeds 1–8; :data:`HELD_OUT_SEEDS` are reported.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from handmocap.core.camera.render import rasterise
from handmocap.core.fusion.hand_render import HandRenderer, crop_around
from handmocap.core.fusion.pose import digit_points
from handmocap.core.fusion.tracker import FusionResult, FusionSettings, RGBDFrames, fuse_take
from handmocap.core.io import Take
from handmocap.core.model import load_layout, load_template
from handmocap.core.simulate.camera import SimulatedCameraTake, render_scene, simulate_camera_take
from handmocap.core.simulate.take import simulate_take

HELD_OUT_SEEDS = (201, 202, 203)
#: finger motion of the n-th seed (:func:`core.simulate.motion.simulate_joint_angles`): grasps and gestures mixed
#: with prior postures, grasps outside the posture prior, grasps of the prior set
MOTIONS = ("mixed", "heldout", "grasps")
HIDDEN_MARKERS = ("thumb_distal", "thumb_proximal", "ring_distal", "ring_middle")
OCCLUDED_DIGITS = (0, 3)
VISIBLE_DIGITS = (1, 2, 4)
HIDDEN_START_S = 0.3
HIDDEN_SECONDS = 2.2
TAKE_FRAMES = 300
MARKER_NOISE_MM = 0.3
SWARM_FRAMES = 4
#: the hidden segments count as seen by the camera when this share of their projected area is not covered
MIN_SEEN_SHARE = 0.5
#: joints that carry the hidden segments: thumb MCP and IP, ring PIP and DIP
HIDDEN_SEGMENT_JOINTS = (2, 3, 11, 12)
MOCAP_RATE = 100.0
CAMERA_RATE = 30.0


@dataclass
class _Frames:
    """Camera frames rendered on demand (the :class:`core.fusion.tracker.FrameStream` protocol); ``rendered``:
    the colour and depth of every frame rendered so far, shared by the colour and depth streams."""

    simulated: SimulatedCameraTake
    depth_stream: bool
    rendered: dict

    def __len__(self) -> int:
        return len(self.simulated.camera_times)

    def frame(self, index: int) -> np.ndarray:
        if index not in self.rendered:
            self.rendered[index] = self.simulated.render(index)
        colour, depth = self.rendered[index]
        return depth if self.depth_stream else colour

    def time(self, index: int) -> float:
        return float(self.simulated.camera_times[index])


def simulated_camera_take(seed: int, n_frames: int, motion: str) -> SimulatedCameraTake:
    """As :func:`core.simulate.camera.simulate_camera_take` (dense layout, 100 Hz mocap, 30 Hz camera) with the
    finger ``motion`` of :func:`core.simulate.motion.simulate_joint_angles`."""
    timing = simulate_camera_take(seed, 2)
    camera = timing.camera
    simulated = simulate_take("dense", n_frames, seed, motion=motion, frame_rate=MOCAP_RATE)
    last = float(camera.clock.camera_time((n_frames - 1) / MOCAP_RATE))
    first = max(0.0, float(camera.clock.camera_time(0.0)))
    times = np.arange(int(np.ceil(first * CAMERA_RATE)), int(np.floor(last * CAMERA_RATE)) + 1) / CAMERA_RATE
    return SimulatedCameraTake(simulated, camera, times, CAMERA_RATE, seed)


def occluded_take(seed: int, n_frames: int = TAKE_FRAMES, motion: str = "mixed"
                  ) -> tuple[SimulatedCameraTake, Take, np.ndarray]:
    """The simulated camera take of ``seed``, its take with the hidden stretch and noise, and the hidden frames
    (F,) bool."""
    simulated = simulated_camera_take(seed, n_frames, motion)
    take = simulated.simulated.take
    rate = take.frame_rate
    hidden = np.zeros(take.n_frames, dtype=bool)
    hidden[int(HIDDEN_START_S * rate):int((HIDDEN_START_S + HIDDEN_SECONDS) * rate)] = True
    positions = take.marker_positions.copy()
    positions += np.random.default_rng([seed, 150]).normal(0.0, MARKER_NOISE_MM, positions.shape)
    for name in HIDDEN_MARKERS:
        positions[hidden, take.marker_names.index(name)] = np.nan
    return simulated, Take(marker_names=list(take.marker_names), marker_positions=positions, frame_rate=rate,
                           vendor="simulated"), hidden


def rgbd_frames(simulated: SimulatedCameraTake) -> RGBDFrames:
    """The simulated recording with a clean plate of the empty scene as background."""
    background, _ = render_scene(simulated.camera, None, None, np.zeros((0, 3)), 3.0,
                                 np.random.default_rng([simulated.seed, 151]), with_depth=False)
    rendered: dict = {}
    return RGBDFrames(_Frames(simulated, True, rendered), _Frames(simulated, False, rendered), background)


def joint_errors(estimated: np.ndarray, truth: np.ndarray, frames: np.ndarray, digits: tuple[int, ...]) -> float:
    """Mean distance (mm) of the middle, distal joints and tips of ``digits`` over ``frames`` (indices)."""
    if len(frames) == 0:
        return float("nan")
    model = load_template()
    errors = [np.linalg.norm(digit_points(model, estimated[frame])[list(digits)]
                             - digit_points(model, truth[frame])[list(digits)], axis=2).mean() for frame in frames]
    return float(np.mean(errors))


def camera_sees_hidden(simulated: SimulatedCameraTake, result: FusionResult) -> np.ndarray:
    """Per solved RGB-D frame (K,) bool: the camera sees at least :data:`MIN_SEEN_SHARE` of the projected area of
    the hidden segments (thumb proximal and distal phalanges, ring middle and distal phalanges) at the true pose,
    i.e. the rest of the hand does not cover them (Zhao et al. Fig. 6 is such a case)."""
    model = load_template()
    renderer = HandRenderer(model, simulated.camera)
    dominant = model.skin_joints[np.arange(len(model.vertices)), model.skin_weights.argmax(axis=1)]
    segment_faces = np.isin(dominant[renderer.faces], HIDDEN_SEGMENT_JOINTS).all(axis=1)
    alone = renderer.faces[segment_faces]
    seen = []
    for position in result.rgbd_mocap_frames:
        theta, _ = simulated.pose_at(position / simulated.simulated.take.frame_rate)
        crop = crop_around(renderer.pixels(theta), simulated.camera, max_side=160)
        rendering = renderer.render(theta, crop, with_edges=False)
        visible = np.isin(rendering.face, np.nonzero(segment_faces)[0]).sum()
        focal, principal = crop.intrinsics(simulated.camera)
        _, faces = rasterise(rendering.points, alone, focal, principal, crop.shape)
        seen.append(visible >= MIN_SEEN_SHARE * max(int((faces >= 0).sum()), 1))
    return np.array(seen)


def _covered(result: FusionResult, hidden: np.ndarray) -> np.ndarray:
    """Hidden mocap frames within the span of the solved RGB-D frames."""
    frames = np.nonzero(hidden)[0]
    low, high = result.rgbd_mocap_frames.min(), result.rgbd_mocap_frames.max()
    return frames[(frames >= low) & (frames <= high)]


def evaluate_seed(seed: int, settings: FusionSettings | None = None, n_frames: int = TAKE_FRAMES,
                  swarm: bool = True, motion: str = "mixed") -> dict:
    """Figures of one seed (module docstring)."""
    settings = settings or FusionSettings()
    simulated, take, hidden = occluded_take(seed, n_frames, motion)
    truth = simulated.simulated.truth["joint_angles"]
    frames = rgbd_frames(simulated)
    layout = load_layout("dense")
    fused = fuse_take(take, simulated.camera, frames, settings, layout=layout)
    covered = _covered(fused, hidden)
    seen_keys = np.round(fused.rgbd_mocap_frames[camera_sees_hidden(simulated, fused)]).astype(int)
    nearest_key = np.round(fused.rgbd_mocap_frames).astype(int)[
        np.abs(covered[:, None] - fused.rgbd_mocap_frames[None, :]).argmin(axis=1)]
    seen_frames = covered[np.isin(nearest_key, seen_keys)]
    unseen_frames = covered[~np.isin(nearest_key, seen_keys)]
    figures = {
        "occluded_markers_only": joint_errors(fused.markers_only, truth, covered, OCCLUDED_DIGITS),
        "occluded_fused": joint_errors(fused.joint_angles, truth, covered, OCCLUDED_DIGITS),
        "visible_markers_only": joint_errors(fused.markers_only, truth, covered, VISIBLE_DIGITS),
        "visible_fused": joint_errors(fused.joint_angles, truth, covered, VISIBLE_DIGITS),
        "frames_per_s": 1.0 / fused.seconds_per_rgbd_frame,
        "hidden_frames": len(covered),
        "seen_frames": len(seen_frames),
        "occluded_seen_markers_only": joint_errors(fused.markers_only, truth, seen_frames, OCCLUDED_DIGITS),
        "occluded_seen_fused": joint_errors(fused.joint_angles, truth, seen_frames, OCCLUDED_DIGITS),
        "occluded_unseen_markers_only": joint_errors(fused.markers_only, truth, unseen_frames, OCCLUDED_DIGITS),
        "occluded_unseen_fused": joint_errors(fused.joint_angles, truth, unseen_frames, OCCLUDED_DIGITS),
        "rgbd_frames": len(fused.rgbd_frames),
        "subspace": fused.subspace,
    }
    fixed = fuse_take(take, simulated.camera, frames, replace(settings, adapt_subspace=False), layout=layout)
    figures["occluded_fused_no_adaptation"] = joint_errors(fixed.joint_angles, truth, covered, OCCLUDED_DIGITS)
    if swarm:
        in_stretch = [index for index, position in zip(fused.rgbd_frames, fused.rgbd_mocap_frames, strict=True)
                      if hidden[int(round(position))]][:SWARM_FRAMES]
        paper = fuse_take(take, simulated.camera, frames, replace(settings, optimiser="pso"), layout=layout,
                          camera_frames=in_stretch)
        local = fuse_take(take, simulated.camera, frames, settings, layout=layout, camera_frames=in_stretch)
        window = _covered(paper, hidden)
        figures.update({
            "pso_occluded_fused": joint_errors(paper.joint_angles, truth, window, OCCLUDED_DIGITS),
            "pso_icp_occluded_fused": joint_errors(local.joint_angles, truth, window, OCCLUDED_DIGITS),
            "pso_occluded_markers_only": joint_errors(paper.markers_only, truth, window, OCCLUDED_DIGITS),
            "pso_frames_per_s": 1.0 / paper.seconds_per_rgbd_frame,
        })
    return figures


def _bound(per_seed: list[dict]) -> float:
    """The occluded digits' fused / markers-only ratio over the seeds if the fusion were exact wherever the camera
    sees the hidden segments and kept its error where it does not: what better depth fitting alone could reach."""
    unseen = sum((f["hidden_frames"] - f["seen_frames"]) * np.nan_to_num(f["occluded_unseen_fused"])
                 for f in per_seed)
    total = sum(f["hidden_frames"] * f["occluded_markers_only"] for f in per_seed)
    return round(float(unseen / total), 3) if total else float("nan")


def evaluate_fusion(seeds: tuple[int, ...] = HELD_OUT_SEEDS, settings: FusionSettings | None = None,
                    n_frames: int = TAKE_FRAMES, swarm: bool = True) -> dict:
    """Figures over ``seeds`` (means over seeds; the worst seed's ratio too)."""
    settings = settings or FusionSettings()
    per_seed = [evaluate_seed(seed, settings, n_frames, swarm, MOTIONS[index % len(MOTIONS)])
                for index, seed in enumerate(seeds)]

    def mean(key: str) -> float:
        return round(float(np.nanmean([figures[key] for figures in per_seed])), 3)

    figures = {
        "occluded_joint_error_mm_markers_only": mean("occluded_markers_only"),
        "occluded_joint_error_mm_fused": mean("occluded_fused"),
        "occluded_ratio_worst_seed": round(max(f["occluded_fused"] / f["occluded_markers_only"] for f in per_seed), 3),
        "visible_joint_error_mm_markers_only": mean("visible_markers_only"),
        "visible_joint_error_mm_fused": mean("visible_fused"),
        "occluded_joint_error_mm_fused_without_subspace_adaptation": mean("occluded_fused_no_adaptation"),
        "occluded_seen_by_camera_joint_error_mm_markers_only": mean("occluded_seen_markers_only"),
        "occluded_seen_by_camera_joint_error_mm_fused": mean("occluded_seen_fused"),
        "hidden_frames_seen_by_camera_share": round(sum(f["seen_frames"] for f in per_seed)
                                                    / max(sum(f["hidden_frames"] for f in per_seed), 1), 3),
        "occluded_unseen_by_camera_joint_error_mm_markers_only": mean("occluded_unseen_markers_only"),
        "occluded_unseen_by_camera_joint_error_mm_fused": mean("occluded_unseen_fused"),
        "occluded_ratio_if_seen_frames_were_exact": _bound(per_seed),
        "fused_frames_per_s": mean("frames_per_s"),
        "optimiser": settings.optimiser,
        "seeds": list(seeds),
        "motions": [MOTIONS[index % len(MOTIONS)] for index in range(len(seeds))],
        "rgbd_frames": int(sum(f["rgbd_frames"] for f in per_seed)),
        "hidden_markers": list(HIDDEN_MARKERS),
        "hidden_seconds": HIDDEN_SECONDS,
        "subspace_adaptation": [f["subspace"] for f in per_seed],
    }
    if swarm:
        figures.update({
            "pso_frames": SWARM_FRAMES * len(seeds),
            "pso_occluded_joint_error_mm_markers_only": mean("pso_occluded_markers_only"),
            "pso_occluded_joint_error_mm_fused": mean("pso_occluded_fused"),
            "pso_same_frames_icp_occluded_joint_error_mm_fused": mean("pso_icp_occluded_fused"),
            "pso_frames_per_s": round(mean("pso_frames_per_s"), 4),
        })
    return figures
