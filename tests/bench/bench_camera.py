"""Camera benchmark (issue 14): decode + overlay per frame while scrubbing (random access) a 640×480 video,
and the synthetic camera's rendering speed. Run: ``.venv/bin/python tests/bench/bench_camera.py``."""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handmocap.core.camera.frames import VideoFrames
from handmocap.core.camera.overlay import draw_overlay, project_take
from handmocap.core.camera.writers import write_video
from handmocap.core.simulate.camera import simulate_camera_take


def main() -> int:
    take = simulate_camera_take(seed=1, n_frames=600)
    camera = take.camera
    start = time.perf_counter()
    frames = [take.render(k, with_depth=k % 2 == 0)[0] for k in range(len(take.camera_times))]
    render_ms = 1000 * (time.perf_counter() - start) / len(frames)
    figures = {"render_ms_per_frame": round(render_ms, 2)}
    positions, rate = take.simulated.truth["marker_positions"], take.simulated.take.frame_rate
    with tempfile.TemporaryDirectory() as folder:
        for suffix in (".avi", ".mp4"):
            path = Path(folder) / f"video{suffix}"
            write_video(path, frames, take.frame_rate, camera.size)
            order = np.random.default_rng(0).integers(0, len(frames), 100)
            with VideoFrames(path) as video:
                times = []
                for index in order:
                    video._cache.clear()    # every request a real decode: the worst case of scrubbing
                    begin = time.perf_counter()
                    draw_overlay(video.frame(int(index)), project_take(camera, positions, rate, video.time(int(index))))
                    times.append(1000 * (time.perf_counter() - begin))
            figures[f"scrub{suffix[1:]}_ms_mean"] = round(float(np.mean(times)), 2)
            figures[f"scrub{suffix[1:]}_ms_p95"] = round(float(np.percentile(times, 95)), 2)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
