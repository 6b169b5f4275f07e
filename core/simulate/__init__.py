"""Synthetic hand motion and takes with ground truth, for tests, benchmarks and the demo."""

from handmocap.core.simulate.motion import (
    MOTIONS,
    WORKSPACE_CENTRE,
    global_motion,
    grasp_motion,
    heldout_grasp_motion,
    minimum_jerk_trajectory,
    mixed_motion,
    prior_motion,
    simulate_joint_angles,
)
from handmocap.core.simulate.scene import SimulatedScene, scene_objects, simulate_scene
from handmocap.core.simulate.take import CAMERA_POSITIONS, SimulatedTake, load_truth, save_truth, simulate_take

__all__ = [
    "CAMERA_POSITIONS",
    "MOTIONS",
    "WORKSPACE_CENTRE",
    "SimulatedScene",
    "SimulatedTake",
    "global_motion",
    "grasp_motion",
    "heldout_grasp_motion",
    "load_truth",
    "minimum_jerk_trajectory",
    "mixed_motion",
    "prior_motion",
    "save_truth",
    "scene_objects",
    "simulate_joint_angles",
    "simulate_scene",
    "simulate_take",
]
