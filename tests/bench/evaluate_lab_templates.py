"""Lab templates on data they were not tuned on: learn on one stretch, relabel another, stripped and shuffled.

Prints one row per case (correct / wrong / missed % per hand and object, longest wrong run, frames/s):

- simulated lab takes (two hands in the dense layout's places under a lab's names ``R-A1`` … ``L-Wan-3``, no
  digit words; a rigid box; 0.3 mm noise, occlusion gaps), held-out seeds, each learned on its first half and
  relabelled on its second half with ghosts in 5 % of the frames; the hands' motion mixed, and held-out grasp
  cycles (fingers strongly flexed and pressed together, as on a fret board);
- the same with a 13-marker subset (tips and middles of the fingers, three on the back of the hand);
- the real guitar take (``../shared/data/guitar``, when present) split by time both ways, all markers and the
  13-marker subset, with and without ghosts.

Usage: ``python tests/bench/evaluate_lab_templates.py [--seeds 11 12 13] [--frames 1200]``
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np

from handmocap.core.evaluation.data import SHARED_DATA
from handmocap.core.evaluation.take_labelling import evaluate_take_labelling
from handmocap.core.io import Take, load_take
from handmocap.core.model import MarkerLayout, load_layout
from handmocap.core.simulate.scene import simulate_scene

SUBSET = ("A1", "A2", "B1", "B2", "C1", "C2", "D1", "D2", "E1", "E2", "Wan-1", "Wan-2", "Wan-3", "Wan-wai")


def lab_layout() -> MarkerLayout:
    """The dense layout's finger and back-of-hand markers under a lab's names (A thumb … E little, 1 distal)."""
    names = {"back_radial": "Wan-1", "back_centre": "Wan-2", "back_ulnar": "Wan-3"}
    for letter, digit in zip("ABCDE", ("thumb", "index", "middle", "ring", "little"), strict=True):
        segments = ("metacarpal", "proximal", "distal") if digit == "thumb" else ("proximal", "middle", "distal")
        names.update({f"{digit}_{segment}": f"{letter}{number}"
                      for number, segment in zip((3, 2, 1), segments, strict=True)})
    dense = load_layout("dense")
    return MarkerLayout("lab", tuple(replace(spec, name=names[spec.name]) for spec in dense.markers
                                     if spec.name in names))


def simulated_lab_take(seed: int, frames: int, motion: str = "mixed") -> Take:
    """A labelled two-hand lab take with a box: noise 0.3 mm, occlusion gaps; ``motion`` of the hands."""
    scene = simulate_scene(lab_layout(), n_frames=frames, seed=seed, hands="both", n_objects=1, noise_mm=0.0,
                           ghost_rate=0.0, occlusion=True, motion=motion)
    truth = scene.truth
    clean = truth["marker_positions"]
    noisy = clean + np.random.default_rng([seed, 5]).normal(0.0, 0.3, clean.shape)
    positions = np.where(truth["visible"][:, :, None], noisy, np.nan)
    names = [str(name).replace("R_", "R-", 1).replace("L_", "L-", 1) for name in truth["marker_names"]]
    return Take(names, positions, scene.take.frame_rate)


def subset(take: Take) -> Take:
    """The take's objects and the hand markers of :data:`SUBSET`."""
    keep = [index for index, name in enumerate(take.marker_names)
            if name[:2] not in ("L-", "R-") or name[2:] in SUBSET]
    return Take([take.marker_names[index] for index in keep], take.marker_positions[:, keep], take.frame_rate)


def row(case: str, figures: dict) -> dict:
    """One printed row and its JSON."""
    groups = figures["groups"]
    cells = "  ".join(f"{name} {group['correct_pct']:.2f}/{group['wrong_pct']:.2f}/{group['missed_pct']:.2f}"
                      f" run {group['longest_wrong_frames']}" for name, group in groups.items())
    print(f"{case:<44} {cells}  ({figures['frames_per_second']:.0f} frames/s)", flush=True)
    return {"case": case, "groups": groups, "frames_per_second": figures["frames_per_second"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[11, 12, 13],
                        help="simulated seeds (none: the guitar take only)")
    parser.add_argument("--frames", type=int, default=1200)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    print("correct/wrong/missed % per group, longest wrong run in frames")
    rows = []
    for motion in ("mixed", "heldout"):
        for seed in args.seeds:
            take = simulated_lab_take(seed, args.frames, motion)
            for name, variant in (("all", take), ("13-marker subset", subset(take))):
                rows.append(row(f"simulated lab {motion} seed {seed}, {name}",
                                evaluate_take_labelling(variant, ghost_rate=0.05, seed=seed)))
    guitar = SHARED_DATA / "guitar" / "nokov_guitarist_arpeggio.csv"
    if guitar.is_file():
        take = load_take(guitar, frame_rate=120.0)
        half = take.n_frames // 2
        for name, variant in (("all", take), ("13-marker subset", subset(take))):
            rows.append(row(f"guitar {name}, first half -> second", evaluate_take_labelling(variant, learn_on=half)))
            reversed_variant = replace(variant, marker_positions=variant.marker_positions[::-1].copy())
            rows.append(row(f"guitar {name}, second half -> first",
                            evaluate_take_labelling(reversed_variant, learn_on=half)))
            rows.append(row(f"guitar {name}, first half -> second, ghosts 5 %",
                            evaluate_take_labelling(variant, learn_on=half, ghost_rate=0.05, seed=1)))
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
