"""``handmocap layout ...`` and ``handmocap bench pso``: marker layout fitting, optimisation and evaluation."""

from __future__ import annotations

import argparse
from pathlib import Path

from handmocap.app.cli.common import (
    add_json_flag,
    add_outputs,
    add_rate_argument,
    print_figures,
    print_json,
    progress_printer,
)
from handmocap.core.errors import InputError


def _motions(values: list[str]) -> str | list[str | Path]:
    """A motion-set name (grasps, gestures, all) or a list of solved-take result files."""
    if len(values) == 1 and not values[0].endswith(".npz"):
        return values[0]
    files: list[str | Path] = list(values)
    return files


def command_layout_optimise(args: argparse.Namespace) -> int:
    """``handmocap layout optimise``: write a reduced marker layout optimised for a motion set; exit 2 on bad input."""
    from handmocap.core.layout import PSOSettings
    from handmocap.core.layout.workflow import optimise_layout
    from handmocap.core.model import load_template, save_layout

    report = progress_printer(f"optimising the layout ({args.method})")
    settings = PSOSettings(particles=args.particles, iterations=args.iterations)
    layout, result = optimise_layout(load_template(), _motions(args.motions), args.markers, method=args.method,
                                     base_layout=args.base, subspace_dims=args.dims, seed=args.seed,
                                     n_keyframes=args.keyframes, settings=settings, name=args.name,
                                     progress=lambda fraction, _energy: report(fraction))
    save_layout(layout, args.out)
    print(f"{args.method}: {len(layout.markers)} markers ({', '.join(layout.names)}), energy {result.energy:.4f}, "
          f"{result.evaluations} layouts evaluated -> {args.out}")
    return 0


def command_layout_evaluate(args: argparse.Namespace) -> int:
    """``handmocap layout evaluate``: print a layout's metrics and held-out reconstruction error."""
    from handmocap.core.layout import default_subspace_dims, evaluate_layout, motion_set
    from handmocap.core.model import load_layout, load_template

    layout = load_layout(args.layout)
    dims = args.dims or default_subspace_dims(len(layout.markers))
    metrics = evaluate_layout(load_template(), layout, motion_set(_motions(args.motions)), dims)
    figures = {"layout": layout.name, "markers": len(layout.markers), "subspace_dims": dims,
               "mean_mm": round(metrics.reconstruction_mean_mm, 3), "max_mm": round(metrics.reconstruction_max_mm, 3),
               "mean_condition": round(metrics.mean_condition, 3),
               "worst_occluded_condition": round(metrics.worst_occluded_condition, 3),
               "worst_occluded_marker": metrics.worst_occluded_marker,
               "min_distance_mm": round(metrics.min_distance_mm, 2), "closest_pair": list(metrics.closest_pair),
               "risk_fraction": round(metrics.risk_fraction, 3)}
    print_figures(figures, args.json)
    return 0


def command_layout_fit(args: argparse.Namespace) -> int:
    """``handmocap layout fit``: write a layout refitted to where its markers sit in a take; exit 2 on bad input."""
    from handmocap.core.calibration.marker_placement import fit_marker_placement
    from handmocap.core.io import load_take
    from handmocap.core.model import load_layout, load_template, save_layout
    from handmocap.core.model.hand_columns import name_side

    take = load_take(args.take, frame_rate=args.rate)
    names = list(take.marker_names)
    sided = [name_side(name) for name in names]
    if any(side is not None for side, _ in sided):
        # a two-hand take (R_/L_, R-/L-, Subject:Marker): the side's own columns, named without the side token
        columns = [index for index, (side, _) in enumerate(sided) if side == args.side]
        if not columns:
            raise InputError(f"{args.take}: no marker of the {args.side} hand (names say the side of "
                             f"{sum(side is not None for side, _ in sided)} markers, none {args.side})")
        names = [sided[index][1] for index in columns]
        positions = take.marker_positions[:, columns]
    else:
        positions = take.marker_positions
    layout, residuals = fit_marker_placement(positions, names, load_template(args.side),
                                             load_layout(args.layout), iterations=args.iterations)
    save_layout(layout, args.out)
    steps = " -> ".join(f"{value:.2f}" for value in residuals)
    print(f"mean IK residual per iteration (mm): {steps}; wrote {args.out}")
    return 0


def command_layout_learn(args: argparse.Namespace) -> int:
    """``handmocap layout learn``: learn a lab's labelling template from labelled takes, write it, print what was
    found (per hand: each marker's digit and segment, the placement residual; the objects); exit 2 on bad input."""
    from handmocap.core.io import load_take
    from handmocap.core.labelling.templates import learn_template
    from handmocap.core.model.lab_template import save_lab_template

    takes = [load_take(path, frame_rate=args.rate) for path in args.takes]
    name = args.name or Path(args.out).stem
    learned = learn_template(takes, name=name, progress=None if args.quiet else progress_printer(
        "learning the template", sum(take.n_frames for take in takes)))
    save_lab_template(learned.template, args.out)
    report = learned.report
    print(f"template '{name}' from {len(takes)} take(s), {report['frames']} frames, marker noise σ "
          f"{report['noise_mm']:.2f} mm -> {args.out}")
    for side, hand in report["hands"].items():
        print(f"  {side} hand: {hand['markers']} markers, placement residual {hand['residual_mm']:.2f} mm")
        by_digit: dict[str, list[str]] = {}
        for marker, where in hand["digits"].items():
            by_digit.setdefault(where.split()[0], []).append(f"{marker} ({where.split()[1]})"
                                                              if where.split()[0] != "palm" else marker)
        for digit, markers in by_digit.items():
            print(f"    {digit:<7} {', '.join(markers)}")
    for obj, markers in report["objects"].items():
        print(f"  object '{obj}': {', '.join(markers)}")
    if report["ignored_markers"]:
        print(f"  not used: {', '.join(report['ignored_markers'])} (neither a hand nor a rigid object)")
    if args.json:
        print_json(report)
    return 0


def command_layout_sheet(args: argparse.Namespace) -> int:
    """``handmocap layout sheet``: write the placement sheet (PNG or PDF) of a layout; exit 2 on bad input."""
    from handmocap.core.layout.placement_sheet import placement_sheet
    from handmocap.core.model import load_layout, load_template
    from handmocap.widgets.placement_sheet import save_placement_sheet

    layout = load_layout(args.layout)
    path = save_placement_sheet(placement_sheet(load_template(args.side), layout), args.out)
    print(f"placement sheet of '{layout.name}' ({len(layout.markers)} markers) -> {path}")
    return 0


def command_layout_view(args: argparse.Namespace) -> int:
    """``handmocap layout view``: run the layout view; with --screenshot, exit 1 when it is not saved."""
    from handmocap.app.gui.layout_view import run_layout_view

    return run_layout_view(args.screenshot, args.compare, args.frame)


def command_layout_table(args: argparse.Namespace) -> int:
    """``handmocap layout table``: print the held-out grasp error against the number of markers, grasp-specific
    against generic layouts."""
    from handmocap.core.layout import PSOSettings
    from handmocap.core.layout.workflow import error_against_markers
    from handmocap.core.model import load_template

    settings = PSOSettings(particles=args.particles, iterations=args.iterations)
    print(f"held-out grasp reconstruction error (mm) of layouts optimised for {args.specific} and for "
          f"{args.generic}:")
    specific, generic = f"{args.specific} mean", f"{args.generic} mean"
    print(f"  {'markers':>7} {'PCs':>3}  {specific:>14} {'max':>7}  {generic:>14} {'max':>7}")

    def show(row) -> None:
        print(f"  {row.markers:>7} {row.subspace_dims:>3}  {row.specific_mean_mm:>14.2f} {row.specific_max_mm:>7.2f}"
              f"  {row.generic_mean_mm:>14.2f} {row.generic_max_mm:>7.2f}", flush=True)

    rows = error_against_markers(load_template(), args.counts, args.specific, args.generic, settings, args.seed,
                                 reconstruction_frames=args.frames, row_done=show)
    if args.json:
        print_json({"specific": args.specific, "generic": args.generic, "rows": [row.to_json() for row in rows],
                    "specific_better": sum(row.specific_mean_mm < row.generic_mean_mm for row in rows)})
    return 0


def command_bench_pso(args: argparse.Namespace) -> int:
    """``handmocap bench pso``: print the time and energy of PSO against greedy layout optimisation."""
    from handmocap.core.layout.workflow import bench_pso

    figures = bench_pso(n_markers=args.markers, seeds=args.seeds)
    print(f"PSO {figures['pso_seconds']:.2f} s (E {figures['pso_energy']}, {figures['pso_evaluations']} layouts), "
          f"greedy {figures['greedy_seconds']:.2f} s (E {figures['greedy_energy']}, "
          f"{figures['greedy_evaluations']} layouts)")
    print(f"PSO + swap polish {figures['pso_swap_seconds']:.2f} s (E {figures['pso_swap_energy']})")
    if "pso_energy_seeds" in figures:
        print(f"PSO energy over {args.seeds} seeds: {figures['pso_energy_seeds']} "
              f"(std {figures['pso_energy_std']}); {figures['pso_runs_below_greedy']} below greedy; "
              f"with swap polish: {figures['pso_swap_energy_seeds']}")
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
    fit.add_argument("--side", choices=["right", "left"], default="right",
                     help="the hand to fit (of a two-hand take: the markers whose names say this side)")
    add_rate_argument(fit)
    fit.add_argument("--iterations", type=int, default=3, help="rounds of fitting the placements (default 3)")
    fit.add_argument("--out", required=True, metavar="LAYOUT.json", help="the fitted layout to write")
    add_outputs(fit, "out")
    fit.set_defaults(handler=command_layout_fit)

    learn = layout_commands.add_parser(
        "learn", help="learn a lab's labelling template (marker set per hand, names, statistics, objects) from "
        "takes the lab labelled")
    learn.add_argument("takes", nargs="+", metavar="TAKE", help="labelled takes (C3D, TSV, TRC, CSV of any vendor)")
    learn.add_argument("--out", required=True, metavar="LAB.json", help="the template to write (a layout file)")
    learn.add_argument("--name", help="the template's name (default: the output file's name)")
    add_rate_argument(learn)
    learn.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(learn, "out")
    add_json_flag(learn)
    learn.set_defaults(handler=command_layout_learn)

    optimise = layout_commands.add_parser("optimise", aliases=["optimize"],
                                          help="optimise a reduced marker layout for a motion set")
    optimise.add_argument("--markers", type=int, required=True, help="number of markers")
    optimise.add_argument("--motions", nargs="+", default=["grasps"],
                          help="motion set: grasps, gestures, all, or solved-take result .npz files")
    optimise.add_argument("--method", choices=["pso", "pso-swap", "greedy", "subset"], default="pso",
                          help="pso (journal), pso-swap (PSO then greedy swap polish), greedy, subset")
    optimise.add_argument("--base", default="dense", help="base layout for --method subset (default dense)")
    optimise.add_argument("--dims", type=int, help="subspace dimensions (default: one per marker, 2 to 6)")
    optimise.add_argument("--keyframes", type=int, default=10, help="keyframes of the motion (3 to 10)")
    optimise.add_argument("--particles", type=int, default=1000, help="PSO particles (default 1000)")
    optimise.add_argument("--iterations", type=int, default=100, help="PSO iterations (default 100)")
    optimise.add_argument("--seed", type=int, default=0, help="seed of the swarm (default 0)")
    optimise.add_argument("--name", help="layout name (default METHOD-K)")
    optimise.add_argument("--out", required=True, metavar="LAYOUT.json", help="the layout to write")
    add_outputs(optimise, "out")
    optimise.set_defaults(handler=command_layout_optimise)
    evaluate_layout = layout_commands.add_parser("evaluate", help="metrics and held-out reconstruction error")
    evaluate_layout.add_argument("layout", help="layout JSON file or shipped layout name")
    evaluate_layout.add_argument("--motions", nargs="+", default=["grasps"],
                                 help="motion set: grasps, gestures, all, or result .npz files")
    evaluate_layout.add_argument("--dims", type=int, help="subspace dimensions (default: one per marker, 2 to 6)")
    evaluate_layout.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    evaluate_layout.set_defaults(handler=command_layout_evaluate)

    sheet = layout_commands.add_parser(
        "sheet", help="printable placement sheet (A4 PNG, or PDF with a second page at 1:1)")
    sheet.add_argument("layout", help="layout JSON file or shipped layout name")
    sheet.add_argument("--side", choices=["right", "left"], default="right", help="the hand drawn (default right)")
    sheet.add_argument("--out", required=True, metavar="SHEET.png|SHEET.pdf",
                       help="the sheet to write: A4 PNG, or PDF with the back of the hand at 1:1")
    add_outputs(sheet, "out")
    sheet.set_defaults(handler=command_layout_sheet)

    view = layout_commands.add_parser("view", help="open the layout view (optimise, compare, placement sheets)")
    view.add_argument("--compare", nargs="+", metavar="LAYOUT", help="tick these layouts for comparison")
    view.add_argument("--frame", type=int, default=700, help="frame shown in the comparison (0-based)")
    view.add_argument("--screenshot", metavar="PNG", help="save a screenshot of the window and quit")
    add_outputs(view, "screenshot")
    view.set_defaults(handler=command_layout_view)

    table = layout_commands.add_parser("table", help="held-out grasp error against the number of markers, "
                                                     "grasp-specific against generic layouts")
    table.add_argument("--counts", type=int, nargs="+", default=list(range(4, 13)), help="marker counts (4..12)")
    table.add_argument("--specific", default="grasps", help="motion set of the specific layouts (default grasps)")
    table.add_argument("--generic", default="gestures", help="motion set of the generic layouts (default gestures)")
    table.add_argument("--particles", type=int, default=1000, help="PSO particles (default 1000)")
    table.add_argument("--iterations", type=int, default=100, help="PSO iterations (default 100)")
    table.add_argument("--frames", type=int, default=1500, help="held-out frames reconstructed per layout")
    table.add_argument("--seed", type=int, default=0, help="seed of the swarm (default 0)")
    add_json_flag(table)
    table.set_defaults(handler=command_layout_table)

    pso = bench_commands.add_parser("pso", help="PSO against greedy layout optimisation")
    pso.add_argument("--markers", type=int, default=6, help="markers of the layout optimised (default 6)")
    pso.add_argument("--seeds", type=int, default=1, help="PSO runs with seeds 0..n-1 for the energy spread")
    add_json_flag(pso)
    pso.set_defaults(handler=command_bench_pso)
