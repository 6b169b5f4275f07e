"""``handmocap label``, ``handmocap fill`` and ``handmocap bench label``: the review engine from the shell."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from handmocap.app.cli.common import (
    DeferredChoices,
    DeferredHelpFormatter,
    add_frames_command,
    add_json_flag,
    add_outputs,
    add_rate_argument,
    print_figures,
    print_json,
    print_summary,
    progress_printer,
)
from handmocap.core.errors import InputError


def _load_review(path: str, frame_rate: float | None = None):
    """A review of a labelled take: our labelled C3D (labels, fills, edits) or any labelled file; at
    ``frame_rate`` (Hz, ``--rate``) when given."""
    from handmocap.core.io import load_take
    from handmocap.core.review import ReviewTake, review_from_labelled_c3d

    if Path(path).suffix.lower() == ".c3d":
        review = review_from_labelled_c3d(path)
        if frame_rate is not None:
            review.take.frame_rate, review.take.frame_rate_given = frame_rate, True
        return review
    return ReviewTake.from_labelled_take(load_take(path, frame_rate=frame_rate))


def _subject_hands(parameters: dict, source: str) -> tuple[dict, dict]:
    """The subject's hand models and calibrated marker sets per side stored in a labelled take
    (:func:`core.workflows.labelling.subject_hands`), for the model fill; a calibration not used is noted."""
    from handmocap.core.workflows.labelling import subject_hands

    found = subject_hands(parameters, source)
    for note in found.notes:
        print(f"handmocap: note: {note}", file=sys.stderr)
    return found.models, found.marker_sets


def command_label(args: argparse.Namespace) -> int:
    """``handmocap label``: write the auto-labelled take (and report) and print the outcome; exit 2 on bad input."""
    from handmocap.core.io import load_take, looks_unlabelled
    from handmocap.core.io.durable import write_text_atomic
    from handmocap.core.model import load_layout, marker_columns
    from handmocap.core.model.lab_template import LabTemplate, load_lab_template
    from handmocap.core.review import ReviewTake, export_labelled_c3d
    from handmocap.core.workflows.labelling import auto_label

    take = load_take(args.raw, frame_rate=args.rate)
    layout = load_lab_template(args.layout) or load_layout(args.layout)
    outcome = auto_label(take, layout, args.hands, args.objects, args.online, relabel=args.relabel,
                         progress=None if args.quiet else progress_printer("labelling", take.n_frames))
    review = ReviewTake.unlabelled(take)
    outcome.command.do(review)
    export_labelled_c3d(review, args.out, subjects=outcome.subjects)
    report = outcome.report | {"source": str(args.raw), "output": str(args.out), "layout": layout.name,
                               "hands": args.hands, "relabel": bool(args.relabel),
                               "subject_calibration": [subject.side for subject in outcome.subjects]}
    if args.report:
        write_text_atomic(args.report, json.dumps(report, indent=2))
    residual, noise = report["mean_residual_mm"], report["noise_mm"]
    health = report["health"]
    no_hand = any(warning["kind"] == "no_hand" and not warning["model"] for warning in health)
    found = ("no hand found, nothing labelled" if no_hand else
             f"{100 * report['labelled_share']:.1f} % of label samples found")
    print(f"labelled {report['frames']} frames ({report['frames_per_s']} frames/s): {found}, "
          f"{report['ghost_points']} ghost points left unlabelled, mean IK residual "
          f"{'n/a' if residual is None else f'{residual:.2f} mm'} -> {args.out}")
    for model in report["models"]:
        first = model["first_frame_tracked"]
        share = "not used (no hand found)" if no_hand and model["kind"] in ("right", "left") else \
            f"{100 * model['labelled_share']:.1f} % labelled"
        what = (f"{model['name']} hand" if model["kind"] == model["name"] else      # "right hand", not "right right"
                f"{model['name']} ({model['kind']} hand)" if model["kind"] in ("right", "left") else
                f"{model['name']} ({model['kind']})")
        print(f"  {what:<20} tracked from frame {'never' if first < 0 else first + take.first_frame}, {share}")
    print(f"  marker noise σ {'n/a' if noise is None else f'{noise:.2f} mm'} per axis (estimated on the take)")
    figures = report["file_labels"]
    if figures["kept_labels"] or figures["file_label_samples"]:
        print(f"  kept from the file: {len(figures['kept_labels'])} labels outside the layout "
              f"({figures['kept_samples']} samples); {figures['file_label_samples']} samples labelled with the "
              f"layout's names, {figures['disagreed_samples']} of them labelled differently by auto-label"
              f"{' (auto-label used)' if args.relabel else ' (the file kept)'}")
    label_names = layout.marker_names if isinstance(layout, LabTemplate) else layout.names
    if not looks_unlabelled(take.marker_names):
        matched = int((marker_columns(take.marker_names, label_names) >= 0).sum())
        if matched < 0.5 * len(label_names):
            print(f"handmocap: warning: the take is labelled but only {matched} of the {len(label_names)} "
                  f"markers of layout '{layout.name}' are among its names: is it the layout the take uses?",
                  file=sys.stderr)
    for warning in health:
        frames = f"frames {warning['first_frame'] + take.first_frame}-{warning['last_frame'] + take.first_frame}"
        print(f"handmocap: warning: {warning['kind']} ({frames}): {warning['message']}", file=sys.stderr)
    return 0


def command_fill(args: argparse.Namespace) -> int:
    """``handmocap fill``: write the labelled take with its short gaps filled, print the counts; exit 2 on bad input."""
    from handmocap.core.gaps import provenance_names
    from handmocap.core.io import looks_unlabelled
    from handmocap.core.review import export_labelled_c3d
    from handmocap.core.workflows import fill_review_gaps, find_review_gaps, gap_groups

    review = _load_review(args.labelled, args.rate)
    if not review.n_labels:
        raise InputError(f"{args.labelled} has no labelled points; label it first (handmocap label)")
    if looks_unlabelled(review.label_names):
        raise InputError(f"{args.labelled} is not labelled (its points are named like '{review.label_names[0]}'): "
                         "filling would join unrelated points; label it first (handmocap label)")
    groups = gap_groups(review, *_subject_hands(review.take.parameters, args.labelled))
    gaps = find_review_gaps(review, groups)
    command = fill_review_gaps(review, groups, args.max_gap, args.method,
                               progress=None if args.quiet else progress_printer("filling gaps", len(gaps), "gaps"))
    counts: dict[str, int] = {}
    if command is not None:
        command.do(review)
        for fill in command.fills:
            counts[fill.method] = counts.get(fill.method, 0) + 1
    export_labelled_c3d(review, args.out)
    short = [gap for gap in gaps if gap.length <= args.max_gap and gap.filled_method is None]
    methods = ", ".join(f"{count} {name}" for name, count in sorted(counts.items())) or "none"
    still = int((review.provenance == -1).sum())
    print(f"{len(gaps)} gaps, {len(short)} of at most {args.max_gap} frames; filled {sum(counts.values())} "
          f"({methods}); {still} samples still missing -> {args.out}")
    if args.json:
        print_json({"gaps": len(gaps), "short_gaps": len(short), "filled": counts, "missing_samples": still,
                    "codes": {str(code): name for code, name in provenance_names().items()}})
    return 0


def command_bench_label(args: argparse.Namespace) -> int:
    """``handmocap bench label``: print the labelling + IK frames per second (one hand; scene)."""
    from handmocap.core.evaluation.labelling_bench import bench_label

    figures = bench_label(frames=args.frames) if args.frames else bench_label()
    print_summary(f"labelling + IK: one hand {figures['frames_per_s_one_hand']:.0f} frames/s, "
                  f"scene {figures['frames_per_s_scene']:.0f} frames/s", figures, args.json)
    return 0


def _evaluate_conditions(args: argparse.Namespace) -> int:
    """``evaluate label`` with ``--sweep``, ``--full`` or a condition (noise, occlusion, mirror, hands)."""
    from handmocap.core.evaluation.labelling_robustness import (
        HELD_OUT_SEEDS,
        SWEEP,
        Condition,
        evaluate_condition,
        evaluate_long_take,
    )
    from handmocap.core.evaluation.labelling_robustness import format_sweep as format_table

    figures: dict = {}
    seeds = tuple(range(HELD_OUT_SEEDS[0], HELD_OUT_SEEDS[0] + args.seeds))
    if args.sweep or args.noise is not None or args.occlude or args.mirror or args.hands:
        conditions = SWEEP if args.sweep else (Condition(0.3 if args.noise is None else args.noise, args.occlude,
                                                         args.mirror, args.hands or "right"),)
        results = [evaluate_condition(condition, seeds=seeds, frames=args.frames, real=not args.synthetic_only)
                   for condition in conditions]
        print(f"held-out seeds {seeds[0]}-{seeds[-1]}, {args.frames} simulated frames, real recording: "
              "frames 1-1500 with the noise added")
        print(format_table(results))
        figures["conditions"] = [{key: result[key] for key in ("condition", "summary")} for result in results]
    if args.full:
        long_take = evaluate_long_take(seed=seeds[0], noise_mm=args.noise or 0.0)
        for part in ("whole", "first_half", "second_half"):
            entry = long_take[part]
            print(f"real recording, {part.replace('_', ' ')} ({entry['frames']} frames): "
                  f"{100 * entry['correct_share']:.3f} % correct, {100 * entry['wrong_share']:.3f} % wrong, "
                  f"longest swap {entry['longest_swap_frames']}, mean residual {entry['mean_residual_mm']} mm")
        print(f"whole take {100 * long_take['whole']['correct_share']:.3f} % against its halves labelled alone "
              f"{100 * long_take['halves_pooled_correct_share']:.3f} %: "
              f"{'at least as good' if long_take['whole_at_least_halves'] else 'worse'}")
        figures["long_take"] = long_take
    if args.json:
        print_json(figures)
    return 0


def _evaluate_lab_take(args: argparse.Namespace) -> int:
    """``evaluate label --take``: strip, shuffle and relabel a lab's labelled take; print the figures per hand
    and object (correct / wrong / missed %, longest wrong run and its marker)."""
    from handmocap.core.evaluation.take_labelling import evaluate_take_labelling
    from handmocap.core.io import load_take

    take = load_take(args.take, frame_rate=args.rate)
    figures = evaluate_take_labelling(take, args.layout, args.learn_on, hands=args.hands or "auto",
                                      seed=args.seed, ghost_rate=args.ghosts, online=args.online,
                                      progress=None if args.json else progress_printer("relabelling",
                                                                                        take.n_frames))
    learned = "" if figures["frames_learned_on"] == 0 else (
        f", {'template learned on' if args.layout is None else 'after'} the first {figures['frames_learned_on']} "
        "frames")
    print(f"{args.take}: {figures['frames']} frames relabelled ({figures['frames_per_second']:.0f} frames/s)"
          f"{learned}")
    print(f"  {'group':<16} {'markers':>7} {'correct %':>10} {'wrong %':>8} {'missed %':>9}  longest wrong run")
    for name, group in figures["groups"].items():
        run = (f"{group['longest_wrong_frames']} frames ({group['longest_wrong_marker']})"
               if group["longest_wrong_frames"] else "none")
        extra = f"; taken as hand {group['taken_as_hand_pct']:.2f} %" if "taken_as_hand_pct" in group else ""
        print(f"  {name:<16} {group['markers']:>7} {group['correct_pct']:>10.3f} {group['wrong_pct']:>8.3f} "
              f"{group['missed_pct']:>9.3f}  {run}{extra}")
    overall = figures["overall"]
    print(f"  {'all':<16} {figures['labelled_markers']:>7} {overall['correct_pct']:>10.3f} "
          f"{overall['wrong_pct']:>8.3f} {overall['missed_pct']:>9.3f}")
    if figures["labels_not_in_take"]:
        print(f"  labels the take does not have (not scored): {', '.join(figures['labels_not_in_take'][:8])}")
    if args.json:
        print_json(figures)
    return 0


def command_evaluate_label(args: argparse.Namespace) -> int:
    """``handmocap evaluate label``: print the labelling accuracy on simulated takes and the real recording, or
    (``--take``) on a lab's own labelled take."""
    from handmocap.core.evaluation.labelling import evaluate_labelling, evaluate_real_recording

    if args.take:
        return _evaluate_lab_take(args)
    if args.layout or args.learn_on is not None:
        raise InputError("--layout and --learn-on apply with --take LABELLED")

    if args.sweep or args.full or args.noise is not None or args.occlude or args.mirror or args.hands:
        if args.online:
            raise InputError("--online applies to the default evaluation, not to --sweep, --full or a condition")
        return _evaluate_conditions(args)
    figures: dict = {"online": args.online}
    if not args.real_only:
        synthetic = evaluate_labelling(seeds=tuple(range(1, args.seeds + 1)), frames=args.frames, online=args.online)
        for case, summary in synthetic["summary"].items():
            key = case.replace("-", "").replace("/", "_")
            figures[f"{key}_correct_share"] = summary["correct_share"]
            figures[f"{key}_ghost_labelled_share"] = summary["ghost_labelled_share"]
            figures[f"{key}_longest_swap_frames"] = summary["longest_swap_frames"]
        figures["synthetic_all_meet_targets"] = all(s["all_meet_targets"] for s in synthetic["summary"].values())
    try:
        real = evaluate_real_recording(online=args.online)
    except InputError as error:
        print(f"real recording skipped: {error}", file=sys.stderr)
    else:
        figures.update({f"real_{key}": value for key, value in real.items()
                        if isinstance(value, int | float) and not isinstance(value, bool)})
        figures["real_meets_targets"] = real["meets_targets"]
    print_figures(figures, args.json)
    return 0


def command_evaluate_gaps(args: argparse.Namespace) -> int:
    """``handmocap evaluate gaps``: print the gap-fill error per method on hidden stretches of a take."""
    from handmocap.core.evaluation.gaps import evaluate_gap_fill, evaluate_hidden_gaps, format_gap_fill_table
    from handmocap.core.evaluation.labelling import REAL_RECORDING
    from handmocap.core.io import Take, load_take
    from handmocap.core.model import load_layout, load_template

    path = Path(args.take) if args.take else REAL_RECORDING
    if not path.exists():
        raise InputError(f"{path}: no take to evaluate gap filling on (give one)")
    take = load_take(path, frame_rate=args.rate)
    if not args.whole:
        take = Take(marker_names=list(take.marker_names), marker_positions=take.marker_positions[:take.n_frames // 2],
                    frame_rate=take.frame_rate, first_frame=take.first_frame, vendor=take.vendor)
    layout = load_layout(args.layout)
    lengths = tuple(args.lengths)
    single = evaluate_gap_fill(take, load_template(), layout, lengths, n_trials=args.trials, seed=args.seed)
    print(f"one hidden gap at a time ({args.trials} per length, seed {args.seed}), error in mm:")
    print(format_gap_fill_table(single))
    many = evaluate_hidden_gaps(take, layout, lengths, n_gaps=args.gaps, seed=args.seed)
    print(f"\n{args.gaps} gaps hidden at once per length, filled as 'handmocap fill --method M' does "
          f"(seed {args.seed}), error in mm:")
    print(format_gap_fill_table(many))
    if args.json:
        figures = {f"{method}_{length}_{kind}_mm": round(value, 3) for kind, key in (("mean", "mean_error_mm"),
                                                                                     ("worst", "worst_error_mm"))
                   for method, per_length in single[key].items() for length, value in per_length.items()}
        figures |= {f"hidden_{method}_{length}_{kind}_mm": round(value, 3)
                    for kind, key in (("mean", "mean_error_mm"), ("worst", "worst_error_mm"))
                    for method, per_length in many[key].items() for length, value in per_length.items()}
        print_json(figures)
    return 0


def _fill_choices() -> tuple[str, ...]:
    from handmocap.core.gaps import fill_choices

    return fill_choices()


def _fill_method_help() -> str:
    """The help of ``fill --method``: auto and every registered fill method."""
    from handmocap.core.gaps import fill_methods

    return ("auto (default): per gap, the first method of its fill check that applies; "
            + "; ".join(f"{method.name}: {method.description}" for method in fill_methods()))


def register(commands, bench_commands, evaluate_commands) -> None:
    """Add ``label``, ``fill`` and ``bench label`` to the ``handmocap`` parser."""
    label = commands.add_parser("label", help="automatically label the raw points of a take (hands and objects)")
    label.add_argument("raw", help="raw take: C3D with unlabelled points or fragments, Qualisys TSV, TRC, the CSV "
                       "exports of Vicon Nexus, Motive or NOKOV")
    add_rate_argument(label)
    label.add_argument("--layout", required=True, help="marker layout of the hands, or a lab template from "
                       "'handmocap layout learn' (name or JSON file)")
    label.add_argument("--hands", choices=["auto", "right", "left", "both"], default="auto",
                       help="auto (default): the labeller decides which hands the take shows")
    label.add_argument("--objects", metavar="SPEC.json", help="rigid objects in the scene (see docs)")
    label.add_argument("--online", action="store_true", help="causal tracking only (no backward pass)")
    label.add_argument("--relabel", action="store_true",
                       help="label from scratch: ignore the labels the file already has (by default labels "
                            "outside the layout are kept and the file's hand labels are kept where it has them)")
    label.add_argument("--out", required=True, metavar="LABELLED.c3d",
                       help="the labelled take to write (C3D with the provenance of every sample)")
    label.add_argument("--report", metavar="REPORT.json", help="write what was found as JSON")
    label.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(label, "out", "report")
    label.set_defaults(handler=command_label)

    fill = commands.add_parser("fill", help="fill the short gaps of a labelled take",
                               formatter_class=DeferredHelpFormatter)
    add_rate_argument(fill)
    fill.add_argument("labelled", metavar="LABELLED.c3d", help="labelled take (our labelled C3D, or any "
                      "labelled C3D/TSV/TRC/CSV)")
    fill.add_argument("--max-gap", type=int, required=True, metavar="FRAMES", help="longest gap to fill")
    fill.add_argument("--method", default="auto", metavar="METHOD", choices=DeferredChoices(_fill_choices),
                      help=_fill_method_help)
    fill.add_argument("--out", required=True, metavar="FILLED.c3d", help="the filled take to write (labelled C3D)")
    fill.add_argument("--quiet", action="store_true", help="no progress output")
    add_outputs(fill, "out")
    add_json_flag(fill)
    fill.set_defaults(handler=command_fill)

    evaluate_label = evaluate_commands.add_parser(
        "label", help="labelling accuracy: simulated hands and scenes, and the stripped real recording")
    evaluate_label.add_argument("--frames", type=int, default=2000, help="frames per simulated take (default 2000)")
    evaluate_label.add_argument("--seeds", type=int, default=3, help="seeds per layout (default 3)")
    evaluate_label.add_argument("--real-only", action="store_true", help="only the real recording")
    evaluate_label.add_argument("--online", action="store_true", help="label in online (causal) mode")
    evaluate_label.add_argument("--noise", type=float, metavar="MM", help="condition: Gaussian noise per axis "
                                "(simulated takes, and added to the real recording); held-out seeds from 101")
    evaluate_label.add_argument("--occlude", type=float, default=0.0, metavar="SHARE",
                                help="condition: also hide this share of the hand samples in runs of 5-30 frames")
    evaluate_label.add_argument("--mirror", action="store_true",
                                help="condition: a left hand (simulated; the real recording mirrored)")
    evaluate_label.add_argument("--hands", choices=["auto", "right", "left", "both"],
                                help="condition: what the labeller is told (default right)")
    evaluate_label.add_argument("--sweep", action="store_true",
                                help="every condition of the robustness sweep, as a table")
    evaluate_label.add_argument("--full", action="store_true",
                                help="the whole real recording against its two halves labelled alone")
    evaluate_label.add_argument("--synthetic-only", action="store_true",
                                help="conditions: simulated takes only (not the real recording)")
    evaluate_label.add_argument("--take", metavar="LABELLED", help="measure on a lab's own labelled take: its labels "
                                "are stripped, its points shuffled, labelled again and compared")
    evaluate_label.add_argument("--layout", metavar="LAB.json", help="with --take: the layout or template to label "
                                "with (default: a template learned from the take's first frames)")
    evaluate_label.add_argument("--learn-on", type=int, metavar="FRAMES", help="with --take: learn the template on "
                                "the first FRAMES frames and label the rest (default: half the take)")
    evaluate_label.add_argument("--seed", type=int, default=0, help="with --take: the shuffle's seed (default 0)")
    evaluate_label.add_argument("--rate", type=float, metavar="HZ", help="with --take: its frame rate when the "
                                "file states none")
    evaluate_label.add_argument("--ghosts", type=float, default=0.0, metavar="SHARE",
                                help="with --take: add ghost points in this share of the frames")
    add_json_flag(evaluate_label)
    evaluate_label.set_defaults(handler=command_evaluate_label)

    evaluate_gaps = evaluate_commands.add_parser(
        "gaps", help="gap-fill error (mean and worst frame) per method on hidden stretches of finger markers, "
        "one at a time and many at once through 'fill'")
    evaluate_gaps.add_argument("take", nargs="?", help="labelled take (default: the real glove recording)")
    add_rate_argument(evaluate_gaps)
    evaluate_gaps.add_argument("--layout", default="glove-13",
                               help="marker layout the take is labelled with (default glove-13)")
    evaluate_gaps.add_argument("--lengths", type=int, nargs="+", default=[10, 20, 40, 80], metavar="FRAMES",
                               help="gap lengths (default 10 20 40 80)")
    evaluate_gaps.add_argument("--trials", type=int, default=200, help="hidden stretches per length, one at a time")
    evaluate_gaps.add_argument("--gaps", type=int, default=30, help="gaps hidden at once per length (default 30)")
    evaluate_gaps.add_argument("--whole", action="store_true", help="the whole take (default: its first half)")
    evaluate_gaps.add_argument("--seed", type=int, default=2, help="default 2 (the fills were tuned on seed 1)")
    add_json_flag(evaluate_gaps)
    evaluate_gaps.set_defaults(handler=command_evaluate_gaps)

    add_frames_command(bench_commands, "label", "labelling + IK frames per second (one hand; scene)",
                       "frames per simulated take", command_bench_label)
