"""Labelling benchmark: offline labelling + IK frames/s, one hand (dense) and two hands + three rigid
objects (targets ≥ 1000 and ≥ 300 frames/s on one core).

Run: taskset -c 0 python tests/bench/bench_label.py [frames]
"""

import json
import sys

from handmocap.core.evaluation.labelling_bench import bench_label


def main() -> None:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    figures = bench_label(frames=frames)
    print(f"one hand ({figures['layout_one_hand']}, {figures['one_hand_markers']} markers): "
          f"{figures['frames_per_s_one_hand']:8.0f} frames/s")
    print(f"scene (2 hands {figures['layout_scene']} + {figures['scene_objects']} objects, "
          f"{figures['scene_markers']} markers): {figures['frames_per_s_scene']:8.0f} frames/s")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
