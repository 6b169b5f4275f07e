"""Export memory benchmark: the peak memory a labelled-C3D export and a plain C3D save add to a 100 000-frame take.

Cases (see ``_child``): labelled, labelled-shown, plain. Each runs in a fresh child process: it builds
the take (and the review of it), resets the kernel's peak-RSS counter (``/proc/self/clear_refs``),
exports, and reports the peak RSS reached during the export minus the RSS before it, against the size
of the take's positions in memory (F x P x 3 float64). Target (issue 12): the export adds at most 1.5 x
the take's size.

Run: python tests/bench/bench_export.py [n_frames] [n_points] [n_labels]
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

TARGET_RATIO = 1.5


def _status_kib(field: str) -> int:
    """A ``VmRSS``/``VmHWM`` figure of this process from ``/proc/self/status``, KiB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise RuntimeError(f"no {field} in /proc/self/status")


def _child(case: str, n_frames: int, n_points: int, n_labels: int, out: str) -> dict:
    """Build the take, export it as ``case`` to ``out``; the memory figures. "labelled": a fresh review
    (the export computes its labelled positions, which the review then keeps); "labelled-shown": the review's
    labelled positions already computed (as in the application, which draws them); "plain": ``save_take``."""
    import numpy as np

    from handmocap.core.io import Take, save_take
    from handmocap.core.review import ReviewTake, export_labelled_c3d
    from handmocap.core.review.take import MEASURED

    rng = np.random.default_rng(0)
    positions = rng.uniform(-1000.0, 1000.0, (n_frames, n_points, 3))
    positions[rng.random((n_frames, n_points)) < 0.05] = np.nan
    take = Take([f"*{index}" for index in range(n_points)], positions, frame_rate=240.0)
    review = None
    if case.startswith("labelled"):
        review = ReviewTake.unlabelled(take, [f"label{index:02d}" for index in range(n_labels)])
        present = np.isfinite(positions[:, :n_labels]).all(axis=2)
        review.assignment[:] = np.where(present, np.arange(n_labels)[None, :], -1)
        review.provenance[:] = np.where(present, MEASURED, review.provenance)
        review.ghost[:, n_labels:] = rng.random((n_frames, n_points - n_labels)) < 0.1
        review.__post_init__()
        if case == "labelled-shown":
            review.labelled_positions()
    baseline = _status_kib("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")  # peak RSS := current RSS
    start = time.perf_counter()
    if review is not None:
        export_labelled_c3d(review, out)
    else:
        save_take(take, out)
    seconds = time.perf_counter() - start
    extra_mb = (_status_kib("VmHWM") - baseline) / 1024
    take_mb = positions.nbytes / 2**20
    return {"case": case, "frames": n_frames, "points": n_points, "labels": n_labels if review else 0,
            "take_mb": round(take_mb, 1), "export_extra_mb": round(extra_mb, 1),
            "ratio": round(extra_mb / take_mb, 2), "seconds": round(seconds, 2),
            "file_mb": round(Path(out).stat().st_size / 2**20, 1)}


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        case, frames, points, labels, out = sys.argv[2], *map(int, sys.argv[3:6]), sys.argv[6]
        print(json.dumps(_child(case, frames, points, labels, out)))
        return
    n_frames = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    n_points = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    n_labels = int(sys.argv[3]) if len(sys.argv) > 3 else 24
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for case in ("labelled", "labelled-shown", "plain"):
            out = str(Path(folder) / f"{case}.c3d")
            completed = subprocess.run([sys.executable, __file__, "--child", case, str(n_frames), str(n_points),
                                        str(n_labels), out], capture_output=True, text=True, check=True, cwd=ROOT)
            result = json.loads(completed.stdout.strip().splitlines()[-1])
            results.append(result)
            print(f"{case:>14} C3D export of {result['frames']} frames x {result['points']} points "
                  f"(take {result['take_mb']} MB): +{result['export_extra_mb']} MB peak RSS "
                  f"({result['ratio']} x the take; target <= {TARGET_RATIO}), {result['seconds']} s, "
                  f"file {result['file_mb']} MB")
    print(json.dumps({"results": results, "target_ratio": TARGET_RATIO,
                      "meets_target": all(result["ratio"] <= TARGET_RATIO for result in results)}))


if __name__ == "__main__":
    main()
