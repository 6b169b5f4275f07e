"""The long-take benchmark (issue 25): a two-hand take at 120 Hz, labelled, filled, solved and exported
through the Python API, with the CPU time of each step and its cost per frame.

The issue's case is one hour (432 000 frames); ``--frames`` measures a shorter take of the same kind and the
figures are also given extrapolated linearly to one hour (every step's cost grows linearly with the take:
see README, Speed). The load of the machine is printed with the figures.

Run: python tests/bench/bench_long_take.py [--frames 432000] [--seed 5]
"""

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

import handmocap
from handmocap.core.io import Take
from handmocap.core.simulate.scene import simulate_scene

ONE_HOUR_FRAMES = 432_000
RATE_HZ = 120.0


def cpu_s() -> float:
    """CPU seconds of this process (user + system)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=ONE_HOUR_FRAMES)
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    scene = simulate_scene(layout="dense", n_frames=args.frames, seed=args.seed, hands="both", n_objects=0,
                           frame_rate=RATE_HZ)
    raw: Take = scene.take
    steps: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as folder:
        started = cpu_s(), time.perf_counter()
        labelled = handmocap.label(raw, "dense", hands="both")
        steps["label"] = cpu_s() - started[0]
        mark = cpu_s()
        filled = handmocap.fill(labelled.take, max_gap=int(RATE_HZ / 2))
        steps["fill"] = cpu_s() - mark
        mark = cpu_s()
        handmocap.solve(filled.take)
        steps["solve"] = cpu_s() - mark
        mark = cpu_s()
        handmocap.export(filled.take, Path(folder) / "take.c3d", "c3d")
        steps["export_c3d"] = cpu_s() - mark
        wall = time.perf_counter() - started[1]
    total = sum(steps.values())
    scale = ONE_HOUR_FRAMES / args.frames
    figures = {"frames": args.frames, "rate_hz": RATE_HZ, "markers": raw.n_markers,
               "labelled_share": labelled.report["labelled_share"], "gaps": filled.gaps,
               "filled": len(filled.filled), "cpu_s": {k: round(v, 1) for k, v in steps.items()},
               "cpu_s_total": round(total, 1), "wall_s": round(wall, 1),
               "one_hour_cpu_min": round(total * scale / 60, 1),
               "one_hour_cpu_min_per_step": {k: round(v * scale / 60, 1) for k, v in steps.items()},
               "load_before": round(load_before, 2), "load_after": round(os.getloadavg()[0], 2)}
    print(f"{args.frames} frames ({args.frames / RATE_HZ / 60:.1f} min at {RATE_HZ:.0f} Hz), two hands, "
          f"{raw.n_markers} point columns; load {load_before:.1f} -> {figures['load_after']:.1f}")
    for step, seconds in steps.items():
        print(f"  {step:<11} {seconds:8.1f} s CPU  {1000 * seconds / args.frames:6.3f} ms/frame"
              f"  -> one hour {seconds * scale / 60:6.1f} min")
    print(f"  {'total':<11} {total:8.1f} s CPU  -> one hour {total * scale / 60:.1f} min (target 15 min)")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
