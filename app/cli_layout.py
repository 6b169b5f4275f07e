"""``handmocap layout ...`` and ``handmocap bench pso``: marker layout fitting, optimisation and evaluation."""

from __future__ import annotations

import argparse

from app.cli_common import add_json_flag, print_figures, print_json


def _motions(values: list[str]) -> str | list[str]:
    """A motion-set name (grasps, gestures, all) or a list of solved-take result files."""
    return values[0] if len(values) == 1 and not values[0].endswith(".npz") else values


def command_layout_optimize(args: argparse.Namespace) -> int:
    from core.layout.workflow import optimise_layout
    from core.model import load_template, save_layout

    layout, result = optimise_layout(load_template(), _motions(args.motions), args.markers, method=args.method,
                                     base_layout=args.base, subspace_dims=args.dims, seed=args.seed)
    save_layout(layout, args.out)
    print(f"{args.method}: {len(layout.markers)} markers, energy {result.energy:.4f} -> {args.out}")
    return 0


def command_layout_evaluate(args: argparse.Namespace) -> int:
    from core.layout import default_subspace_dims, evaluate_layout, motion_set
    from core.model import load_layout, load_template

    layout = load_layout(args.layout)
    dims = args.dims or default_subspace_dims(len(layout.markers))
    metrics = evaluate_layout(load_template(), layout, motion_set(_motions(args.motions)), dims)
    figures = {"layout": layout.name, "markers": len(layout.markers), "subspace_dims": dims,
               "mean_mm": round(metrics.reconstruction_mean_mm, 3), "max_mm": round(metrics.reconstruction_max_mm, 3),
               "mean_condition": round(metrics.mean_condition, 3),
               "worst_occluded_condition": round(metrics.worst_occluded_condition, 3),
               "worst_occluded_marker": metrics.worst_occluded_marker,
               "min_distance_mm": round(metrics.min_distance_mm, 2), "closest_pair": list(metrics.closest_pair)}
    print_figures(figures, args.json)
    return 0


def command_layout_fit(args: argparse.Namespace) -> int:
    from core.calibration.marker_placement import fit_marker_placement
    from core.io import load_take
    from core.model import load_layout, load_template, save_layout

    take = load_take(args.take)
    layout, residuals = fit_marker_placement(take.marker_positions, take.marker_names, load_template(args.side),
                                             load_layout(args.layout), iterations=args.iterations)
    save_layout(layout, args.out)
    steps = " -> ".join(f"{value:.2f}" for value in residuals)
    print(f"mean IK residual per iteration (mm): {steps}; wrote {args.out}")
    return 0


def command_bench_pso(args: argparse.Namespace) -> int:
    from core.layout.workflow import bench_pso

    figures = bench_pso()
    print(f"PSO {figures['pso_seconds']:.2f} s (E {figures['pso_energy']}), "
          f"greedy {figures['greedy_seconds']:.2f} s (E {figures['greedy_energy']})")
    if args.json:
        print_json(figures)
    return 0


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add the layout subcommands to the ``handmocap`` parser."""
    layout = commands.add_parser("layout", help="marker layout tools")
    layout_commands = layout.add_subparsers(dest="layout_command", metavar="ACTION", required=True)
    fit = layout_commands.add_parser("fit", help="fit where a layout's markers sit from a labelled take")
    fit.add_argument("take", help="labelled take (C3D, TSV, TRC, CSV)")
    fit.add_argument("--layout", required=True, help="layout to refit (name or JSON file)")
    fit.add_argument("--side", choices=["right", "left"], default="right")
    fit.add_argument("--iterations", type=int, default=3)
    fit.add_argument("--out", required=True, metavar="LAYOUT.json")
    fit.set_defaults(handler=command_layout_fit)

    optimize = layout_commands.add_parser("optimize", help="optimise a reduced marker layout for a motion set")
    optimize.add_argument("--markers", type=int, required=True, help="number of markers")
    optimize.add_argument("--motions", nargs="+", default=["grasps"],
                          help="motion set: grasps, gestures, all, or solved-take result .npz files")
    optimize.add_argument("--method", choices=["pso", "greedy", "subset"], default="pso")
    optimize.add_argument("--base", default="dense", help="base layout for --method subset (default dense)")
    optimize.add_argument("--dims", type=int, help="subspace dimensions (default: one per marker, 2 to 6)")
    optimize.add_argument("--seed", type=int, default=0)
    optimize.add_argument("--out", required=True, metavar="LAYOUT.json")
    optimize.set_defaults(handler=command_layout_optimize)
    evaluate_layout = layout_commands.add_parser("evaluate", help="metrics and held-out reconstruction error")
    evaluate_layout.add_argument("layout", help="layout JSON file or shipped layout name")
    evaluate_layout.add_argument("--motions", nargs="+", default=["grasps"],
                                 help="motion set: grasps, gestures, all, or result .npz files")
    evaluate_layout.add_argument("--dims", type=int, help="subspace dimensions (default: one per marker, 2 to 6)")
    evaluate_layout.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    evaluate_layout.set_defaults(handler=command_layout_evaluate)

    pso = bench_commands.add_parser("pso", help="PSO against greedy layout optimisation")
    add_json_flag(pso)
    pso.set_defaults(handler=command_bench_pso)
