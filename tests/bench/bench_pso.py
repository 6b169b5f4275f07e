"""Layout optimisation benchmark: surface-constrained PSO (1000 particles × 100 iterations, 10 keyframes
of the grasp motion) against the greedy add-then-swap baseline, one core. Optionally the spread of the
PSO energy over seeds and the reconstruction error of grasp-optimised layouts on held-out grasps.

Run: taskset -c 0 python tests/bench/bench_pso.py [--markers 6] [--seeds 5] [--reconstruction 4 6 8]
The last line is JSON with pso_seconds, pso_energy, greedy_seconds, greedy_energy (and the extras).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from core.layout import (  # noqa: E402
    build_problem,
    default_subspace_dims,
    layout_energies,
    motion_set,
    optimise_greedy,
    optimise_pso,
    reconstruction_error,
    vertex_layout,
)
from core.model import load_template  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--markers", type=int, default=6)
    parser.add_argument("--keyframes", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=1, help="PSO runs with seeds 0..n-1 for the spread")
    parser.add_argument("--reconstruction", type=int, nargs="*", default=[],
                        help="marker counts whose grasp-optimised layouts are reconstructed on held-out grasps")
    args = parser.parse_args()

    model = load_template()
    grasps = motion_set("grasps")
    problem = build_problem(model, grasps, default_subspace_dims(args.markers), args.keyframes)
    layout_energies(problem, np.arange(args.markers)[None])   # compile the kernels

    start = time.perf_counter()
    pso = optimise_pso(problem, args.markers, seed=0)
    pso_seconds = time.perf_counter() - start
    start = time.perf_counter()
    greedy = optimise_greedy(problem, args.markers)
    greedy_seconds = time.perf_counter() - start
    figures = {"pso_seconds": round(pso_seconds, 3), "pso_energy": round(pso.energy, 4),
               "greedy_seconds": round(greedy_seconds, 3), "greedy_energy": round(greedy.energy, 4),
               "markers": args.markers, "keyframes": args.keyframes, "candidates": problem.n_candidates}
    print(f"PSO    {pso_seconds:6.2f} s  E = {pso.energy:.4f}  vertices {pso.vertices.tolist()}")
    print(f"greedy {greedy_seconds:6.2f} s  E = {greedy.energy:.4f}  vertices {greedy.vertices.tolist()}")

    if args.seeds > 1:
        energies = [pso.energy] + [optimise_pso(problem, args.markers, seed=seed).energy
                                   for seed in range(1, args.seeds)]
        figures["pso_energy_seeds"] = [round(energy, 4) for energy in energies]
        print(f"PSO energy over {args.seeds} seeds: min {min(energies):.4f} max {max(energies):.4f} "
              f"std {np.std(energies):.4f}")
    for count in args.reconstruction:
        dims = default_subspace_dims(count)
        result = optimise_pso(build_problem(model, grasps, dims, args.keyframes), count, seed=0)
        mean_mm, max_mm = reconstruction_error(model, vertex_layout(model, result.vertices), subspace_dims=dims)
        figures[f"reconstruction_{count}_mean_mm"] = round(mean_mm, 3)
        figures[f"reconstruction_{count}_max_mm"] = round(max_mm, 3)
        print(f"{count} markers: held-out grasp reconstruction mean {mean_mm:.2f} mm, max {max_mm:.2f} mm")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
