"""Fill of long takes: time per gap against take length, and the whole fill of 200 000 frames.

The takes are labelled, occluded simulations tiled to length (every other copy played backwards, so the
trajectories stay continuous at the joins): the dense layout (24 markers) and a scene of two dense hands
and three objects (60 markers; the right hand keeps the layout's names, so the model fill applies to it).
They are filled as ``handmocap fill --method auto --max-gap 80`` fills a labelled take without hands:
:func:`core.workflows.fill_review_gaps` on a review of the take (the C3D reading and writing are left out).

Run: python tests/bench/bench_fill_long.py [--lengths 1000 10000 ...] [--totals 24 60]
(single-threaded linear algebra is advised on a shared machine: OPENBLAS_NUM_THREADS=1; the CPU seconds
printed beside the wall-clock ones depend less on what else the machine runs).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from core.io import Take  # noqa: E402
from core.review import ReviewTake  # noqa: E402
from core.simulate import simulate_scene, simulate_take  # noqa: E402
from core.workflows import fill_gaps, fill_review_gaps, gap_groups, short_open_gaps  # noqa: E402

MAX_GAP = 80
BASE_FRAMES = 2000
#: the gaps timed per take length start within this many frames of a copy of the base take
TIMED_FRAMES = 1000


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


def per_gap_seconds(take: Take, repeats: int = 2) -> tuple[float, float, int, int]:
    """Wall and CPU seconds per gap of ``fill_gaps`` (the best of ``repeats`` runs) on the gaps that start in the first
    :data:`TIMED_FRAMES` frames of the copy of the base take nearest the middle (the same gaps with the same
    surroundings at every length from 10 000 frames), the number timed and the take's gap count."""
    review = ReviewTake.from_labelled_take(take)
    groups = gap_groups(review)
    gaps = short_open_gaps(review, groups, MAX_GAP)
    offset = 2 * BASE_FRAMES * (take.n_frames // 2 // (2 * BASE_FRAMES))
    timed = [gap for gap in gaps if offset <= gap.start < offset + TIMED_FRAMES]
    best, best_cpu = np.inf, np.inf
    for _ in range(repeats):
        began, began_cpu = time.perf_counter(), time.process_time()
        fill_gaps(groups, timed)
        best, best_cpu = min(best, time.perf_counter() - began), min(best_cpu, time.process_time() - began_cpu)
    return best / len(timed), best_cpu / len(timed), len(timed), len(gaps)


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
    per_gap_seconds(tiled(base, TIMED_FRAMES), 1)                    # start-up (compilation, caches)
    for length in args.lengths:
        seconds, cpu_seconds, timed, count = per_gap_seconds(tiled(base, length))
        results["per_gap"].append({"frames": length, "gaps": count, "timed": timed,
                                   "ms_per_gap": round(1000 * seconds, 1),
                                   "cpu_ms_per_gap": round(1000 * cpu_seconds, 1)})
        print(f"{length:>8} frames x 24 markers: {count:>6} gaps, {1000 * seconds:6.1f} ms per gap "
              f"({1000 * cpu_seconds:.1f} ms CPU; {timed} timed)", flush=True)
    for markers in args.totals:
        total = total_seconds(tiled(base if markers == 24 else base_take(markers), args.total_frames))
        results["totals"].append(total)
        print(f"fill of {total['frames']} frames x {total['markers']} markers: {total['seconds']} s "
              f"({total['cpu_seconds']} s CPU; {total['filled']} gaps filled: {total['methods']})", flush=True)
    print(json.dumps(results))


if __name__ == "__main__":
    main()
