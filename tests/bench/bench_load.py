"""Load benchmark: time `load_take` on a synthetic 100 000 frame x 40 marker C3D (target < 2 s, one core).

Run: python tests/bench/bench_load.py [n_frames] [n_markers]
"""

import json
import sys

from handmocap.core.io.generate import bench_load


def main() -> None:
    n_frames = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    n_markers = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    result = bench_load(n_frames, n_markers)
    print(f"load_take: {result['seconds']:.3f} s for {result['frames']} frames x {result['markers']} markers")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
