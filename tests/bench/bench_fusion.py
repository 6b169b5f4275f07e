"""Fusion benchmark (issue 15): RGB-D frames solved per second on one core by the swarm-seeded articulated ICP
(default) and by the paper's swarm (48 particles × 200 generations), and the cost of one energy evaluation.
Frame decoding/rendering of the synthetic camera is not counted. Run:
``taskset -c 0 .venv/bin/python tests/bench/bench_fusion.py [--json]``."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace

import numpy as np

from handmocap.core.evaluation.fusion import occluded_take, rgbd_frames
from handmocap.core.fusion import FusionSettings, fuse_take
from handmocap.core.fusion.energy import FrameEnergy
from handmocap.core.fusion.hand_render import HandRenderer
from handmocap.core.fusion.observation import ideal_image, observe
from handmocap.core.model import load_layout, load_template, resolve_layout


def main() -> int:
    simulated, take, _ = occluded_take(seed=1, n_frames=150)
    frames = rgbd_frames(simulated)
    for index in range(len(frames.depth)):
        frames.depth.frame(index)                     # render the synthetic camera before timing
    fuse_take(take, simulated.camera, frames, FusionSettings(), camera_frames=[0, 1])     # numba compilation
    icp = fuse_take(take, simulated.camera, frames, FusionSettings())
    swarm = fuse_take(take, simulated.camera, frames, replace(FusionSettings(), optimiser="pso"),
                      camera_frames=[10, 11])
    camera, model = simulated.camera, load_template()
    renderer = HandRenderer(model, camera)
    theta = icp.rgbd_joint_angles[5]
    observation = observe(renderer, theta, ideal_image(frames.depth.frame(5), camera, nearest=True),
                          ideal_image(frames.colour.frame(5), camera), ideal_image(frames.background, camera),
                          np.full((24, 3), np.nan))
    energy = FrameEnergy(renderer, observation, resolve_layout(model, load_layout("dense")), theta)
    start = time.perf_counter()
    for _ in range(200):
        energy(theta)
    figures = {
        "fused_frames_per_s": round(1.0 / icp.seconds_per_rgbd_frame, 2),
        "rgbd_frames": len(icp.rgbd_frames),
        "pso_frames_per_s": round(1.0 / swarm.seconds_per_rgbd_frame, 3),
        "energy_ms": round(1000 * (time.perf_counter() - start) / 200, 3),
        "crop": f"{observation.crop.rows}x{observation.crop.columns} stride {observation.crop.stride}",
    }
    print(f"fusion: {figures['fused_frames_per_s']} RGB-D frames/s (icp, {figures['rgbd_frames']} frames), "
          f"{figures['pso_frames_per_s']} frames/s (paper's swarm), {figures['energy_ms']} ms per energy")
    if "--json" in sys.argv:
        print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
