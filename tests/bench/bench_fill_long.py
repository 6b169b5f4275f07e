"""Fill of long takes: time per gap against take length (``--method auto`` against ``pca``), and the whole fill of
200 000 frames.

The takes are labelled, occluded simulations tiled to length (every other copy played backwards, so the
trajectories stay continuous at the joins): the dense layout (24 markers) and a scene of two dense hands
and three objects (60 markers; the right hand keeps the layout's names, so the model fill applies to it).
They are filled as ``handmocap fill --method auto --max-gap 80`` fills a labelled take without hands:
:func:`core.workflows.fill_review_gaps` on a review of the take (the C3D reading and writing are left out).

Every short gap of a take is filled with each method in turn in the same run, so their ratio holds whatever else
the machine runs; ``auto`` learns along a take when PCA wins (:class:`core.gaps.check.FillChooser`), so its cost
per gap falls with the number of gaps. The CPU seconds printed beside the wall-clock ones depend less on the
machine's load than the wall-clock ones; the load average is printed with them.

Run: OPENBLAS_NUM_THREADS=1 taskset -c 0 python tests/bench/bench_fill_long.py [--lengths 1000 10000 ...]
[--totals 24 60]
"""

import argparse
import json
import os
import time

import numpy as np

from handmocap.core.io import Take
from handmocap.core.review import ReviewTake
from handmocap.core.simulate import simulate_scene, simulate_take
from handmocap.core.workflows import fill_gaps, fill_review_gaps, gap_groups, short_open_gaps

MAX_GAP = 80
BASE_FRAMES = 2000


def base_take(markers: int) -> Take:
    """A labelled, occluded simulated take of :data:`BASE_FRAMES` frames with 24 or 60 markers."""
    if markers == 24:
        return simulate_take("dense", n_frames=BASE_FRAMES, seed=1, noise_mm=0.3, occlusion=True).take
    scene = simulate_scene("dense", n_frames=BASE_FRAMES, seed=1, hands="both", n_objects=3, ghost_rate=0.0)
    truth = scene.truth
    rng = np.random.default_rng(1)
    positions = truth["marker_positions"] + rng.normal(0.0, 0.3, truth["marker_positions"].shape)
    positions[~truth["visible"]] = np.nan
    names = [str(name).removeprefix("R_") for name in truth["marker_names"]]
    return Take(marker_names=names, marker_positions=positions, frame_rate=scene.take.frame_rate)


def tiled(base: Take, n_frames: int) -> Take:
    """``base`` repeated (forwards, backwards, forwards, ...) to ``n_frames`` frames."""
    copies = [base.marker_positions if index % 2 == 0 else base.marker_positions[::-1]
              for index in range(-(-n_frames // base.n_frames))]
    return Take(marker_names=list(base.marker_names), marker_positions=np.concatenate(copies)[:n_frames].copy(),
                frame_rate=base.frame_rate)


def per_gap_seconds(take: Take, method: str) -> tuple[float, float, int]:
    """Wall and CPU seconds per gap of ``fill_gaps`` with ``method`` on every short gap of ``take``, and their
    number."""
    review = ReviewTake.from_labelled_take(take)
    groups = gap_groups(review)
    gaps = short_open_gaps(review, groups, MAX_GAP)
    began, began_cpu = time.perf_counter(), time.process_time()
    fill_gaps(groups, gaps, method)
    return (time.perf_counter() - began) / len(gaps), (time.process_time() - began_cpu) / len(gaps), len(gaps)


def total_seconds(take: Take) -> dict:
    """The whole fill of ``take`` as the command line runs it: review, groups, every short gap."""
    began, began_cpu = time.perf_counter(), time.process_time()
    review = ReviewTake.from_labelled_take(take)
    command = fill_review_gaps(review, gap_groups(review), MAX_GAP)
    if command is not None:
        command.do(review)
    seconds, cpu_seconds = time.perf_counter() - began, time.process_time() - began_cpu
    methods: dict[str, int] = {}
    for fill in command.fills if command is not None else []:
        methods[fill.method] = methods.get(fill.method, 0) + 1
    return {"frames": take.n_frames, "markers": take.n_markers, "seconds": round(seconds, 1),
            "cpu_seconds": round(cpu_seconds, 1),
            "filled": sum(methods.values()), "methods": methods}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int, nargs="*", default=[1_000, 10_000, 100_000, 200_000])
    parser.add_argument("--totals", type=int, nargs="*", default=[24, 60], choices=[24, 60],
                        help="markers of the 200 000-frame takes filled whole")
    parser.add_argument("--total-frames", type=int, default=200_000)
    args = parser.parse_args()
    results: dict = {"per_gap": [], "totals": []}
    base = base_take(24)
    per_gap_seconds(tiled(base, 2 * BASE_FRAMES), "auto")           # start-up (kernels loaded, caches)
    for length in args.lengths:
        take = tiled(base, length)
        row: dict = {"frames": length, "load": round(os.getloadavg()[0], 2)}
        for method in ("pca", "auto"):
            seconds, cpu_seconds, count = per_gap_seconds(take, method)
            row |= {"gaps": count, f"{method}_ms_per_gap": round(1000 * seconds, 2),
                    f"{method}_cpu_ms_per_gap": round(1000 * cpu_seconds, 2)}
        row["auto_over_pca_cpu"] = round(row["auto_cpu_ms_per_gap"] / row["pca_cpu_ms_per_gap"], 2)
        results["per_gap"].append(row)
        print(f"{length:>8} frames x 24 markers: {row['gaps']:>6} gaps; per gap: pca {row['pca_ms_per_gap']:.1f} ms "
              f"({row['pca_cpu_ms_per_gap']:.1f} ms CPU), auto {row['auto_ms_per_gap']:.1f} ms "
              f"({row['auto_cpu_ms_per_gap']:.1f} ms CPU): auto/pca {row['auto_over_pca_cpu']:.2f}x CPU; "
              f"load {row['load']}", flush=True)
    for markers in args.totals:
        total = total_seconds(tiled(base if markers == 24 else base_take(markers), args.total_frames))
        total["load"] = round(os.getloadavg()[0], 2)
        results["totals"].append(total)
        print(f"fill of {total['frames']} frames x {total['markers']} markers: {total['seconds']} s "
              f"({total['cpu_seconds']} s CPU; {total['filled']} gaps filled: {total['methods']}); "
              f"load {total['load']}", flush=True)
    print(json.dumps(results))


if __name__ == "__main__":
    main()
