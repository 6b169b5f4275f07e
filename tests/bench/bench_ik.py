"""IK benchmark: layered IK with the dense layout on a simulated take, one core, warm-started frame to
frame (target ≥ 1000 frames/s). Also prints full and subspace IK for comparison.

Run: taskset -c 0 python tests/bench/bench_ik.py [frames]
"""

import json
import sys

from handmocap.core.evaluation.ik import bench_ik


def main() -> None:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
    results = {method: bench_ik(frames=frames, method=method) for method in ("layered", "full", "subspace")}
    for method, figures in results.items():
        print(f"{method:>9} IK, {figures['markers']} markers: {figures['frames_per_s']:8.0f} frames/s, "
              f"mean residual {figures['mean_residual_mm']:.3f} mm")
    print(json.dumps(results["layered"]))


if __name__ == "__main__":
    main()
