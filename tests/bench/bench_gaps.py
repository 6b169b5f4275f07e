"""Gap-fill benchmark: seconds per PCA fill and per fill check of a 40-frame gap on takes of growing
length (the PCA fill works on a window around the gap, so its time must not grow with the take).

Run: python tests/bench/bench_gaps.py [frames ...]   (default 2 000, 20 000 and 200 000 frames)
"""

import json
import sys
import time

import numpy as np

from handmocap.core.gaps import Gap, check_gap, fill_pca
from handmocap.core.io import Take
from handmocap.core.simulate import simulate_take

GAP_LENGTH = 40
REPEATS = 20


def bench(n_frames: int, base: Take) -> dict:
    """Seconds per PCA fill and per fill check (every method but the model) of a gap in the middle."""
    reps = -(-n_frames // base.n_frames)
    positions = np.concatenate([base.marker_positions] * reps)[:n_frames]
    marker, start = base.marker_names.index("index_tip"), n_frames // 2
    positions[start:start + GAP_LENGTH, marker] = np.nan
    take = Take(list(base.marker_names), positions, base.frame_rate)
    fill_pca(positions, marker, start, GAP_LENGTH)                  # start-up (linear algebra libraries)
    began = time.perf_counter()
    for _ in range(REPEATS):
        fill_pca(positions, marker, start, GAP_LENGTH)
    fill_s = (time.perf_counter() - began) / REPEATS
    began = time.perf_counter()
    check_gap(take, Gap(marker, "index_tip", start, GAP_LENGTH),
              methods=("linear", "spline", "pattern", "rigid", "pca"))
    return {"frames": n_frames, "pca_fill_s": round(fill_s, 4), "fill_check_s": round(time.perf_counter() - began, 4)}


def main() -> None:
    sizes = [int(arg) for arg in sys.argv[1:]] or [2_000, 20_000, 200_000]
    base = simulate_take(layout="glove-13", n_frames=2_000, seed=1, noise_mm=0.3).take
    results = [bench(size, base) for size in sizes]
    for result in results:
        print(f"{result['frames']:>8} frames: PCA fill {1000 * result['pca_fill_s']:.1f} ms, "
              f"fill check {1000 * result['fill_check_s']:.0f} ms")
    print(json.dumps(results))


if __name__ == "__main__":
    main()
