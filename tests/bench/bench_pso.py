"""Layout optimisation benchmark: surface-constrained PSO (1000 particles × 100 iterations, 10 keyframes
of the grasp motion) against the greedy add-then-swap baseline (every feasible vertex), one core; the
PSO energy over several seeds, PSO followed by a swap polish, and optionally the held-out grasp
reconstruction error of grasp-optimised layouts.

Run: taskset -c 0 python tests/bench/bench_pso.py [--markers 6] [--seeds 5] [--reconstruction 6 8]
The last line is JSON with pso_seconds, pso_energy, greedy_seconds, greedy_energy, the evaluation
counts, the seed spread and the extras.
"""

import argparse
import json

from handmocap.core.layout import default_subspace_dims, reconstruction_error
from handmocap.core.layout.workflow import bench_pso, optimise_layout
from handmocap.core.model import load_template


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--markers", type=int, default=6)
    parser.add_argument("--keyframes", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=5, help="PSO runs with seeds 0..n-1 for the spread")
    parser.add_argument("--reconstruction", type=int, nargs="*", default=[],
                        help="marker counts whose grasp-optimised layouts are reconstructed on held-out grasps")
    args = parser.parse_args()

    figures = bench_pso(args.markers, args.keyframes, seeds=args.seeds)
    print(f"PSO    {figures['pso_seconds']:6.2f} s  E = {figures['pso_energy']:.4f}  "
          f"({figures['pso_evaluations']} layouts evaluated)")
    print(f"greedy {figures['greedy_seconds']:6.2f} s  E = {figures['greedy_energy']:.4f}  "
          f"({figures['greedy_evaluations']} layouts evaluated)")
    print(f"PSO + swap polish {figures['pso_swap_seconds']:6.2f} s  E = {figures['pso_swap_energy']:.4f}")
    if "pso_energy_seeds" in figures:
        print(f"PSO energy over {args.seeds} seeds: {figures['pso_energy_seeds']} (std {figures['pso_energy_std']}, "
              f"{figures['pso_runs_below_greedy']} below greedy); with swap polish {figures['pso_swap_energy_seeds']}")
    model = load_template()
    for count in args.reconstruction:
        dims = default_subspace_dims(count)
        layout, _ = optimise_layout(model, "grasps", count, "pso", subspace_dims=dims, n_keyframes=args.keyframes)
        mean_mm, max_mm = reconstruction_error(model, layout, subspace_dims=dims)
        figures[f"reconstruction_{count}_mean_mm"] = round(mean_mm, 3)
        figures[f"reconstruction_{count}_max_mm"] = round(max_mm, 3)
        print(f"{count} markers: held-out grasp reconstruction mean {mean_mm:.2f} mm, max {max_mm:.2f} mm")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
