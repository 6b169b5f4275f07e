"""Compile every numba kernel once, at installation, so that no operator waits for the compiler.

The kernels are compiled with ``cache=True``: the machine code is written next to the sources
(``__pycache__/*.nbc``) and loaded by every later process. Each kernel is compiled for the argument
types it is called with, so the warm-up runs the real workflows on small simulated takes: labelling
of one hand and of a scene with an object, IK, a model-based gap fill, the layout energy and the
placement-sheet raster. Run it with ``python -m handmocap.core.workflows.warm_up`` (the set-up script does).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from handmocap.core.ik import solve_take
from handmocap.core.labelling import label_scene
from handmocap.core.layout.objective import build_problem, default_subspace_dims, layout_energies
from handmocap.core.layout.placement_sheet import placement_sheet, rasterise_view
from handmocap.core.model import load_layout, load_template
from handmocap.core.review import ReviewTake
from handmocap.core.simulate import simulate_scene, simulate_take
from handmocap.core.workflows.filling import fill_review_gaps, gap_groups

FRAMES = 80  #: frames of the warm-up takes: enough for every code path, short enough to run in seconds


def _labelling() -> None:
    one = simulate_take(layout="dense", n_frames=FRAMES, seed=0, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                        unlabelled=True)
    label_scene(one.take, "right", "dense")
    scene = simulate_scene(layout="dense", n_frames=FRAMES, seed=0, n_objects=1)
    label_scene(scene.take, "both", "dense", objects=scene.objects)


def _solve_and_fill() -> None:
    take = simulate_take(layout="dense", n_frames=FRAMES, seed=0, noise_mm=0.3).take
    solve_take(take, load_template(), load_layout("dense"))
    take.marker_positions[20:40, 5] = np.nan
    review = ReviewTake.from_labelled_take(take)
    fill_review_gaps(review, gap_groups(review), max_gap=FRAMES, method="auto")


def _layouts() -> None:
    model = load_template()
    motion = simulate_take(layout="dense", n_frames=FRAMES, seed=0).truth["joint_angles"]
    problem = build_problem(model, motion, default_subspace_dims(6), n_keyframes=3)
    layout_energies(problem, np.arange(6)[None, :])
    sheet = placement_sheet(model, load_layout("glove-13"))
    rasterise_view(sheet.views[0], pixels_per_mm=2.0, scale=1.0)


STEPS: tuple[tuple[str, Callable[[], None]], ...] = (
    ("labelling", _labelling), ("IK and gap fill", _solve_and_fill), ("layouts", _layouts))


def warm_up(report: Callable[[str], None] = print) -> float:
    """Run every step (``report`` hears one line per step); returns the seconds it took."""
    start = time.perf_counter()
    for name, step in STEPS:
        step_start = time.perf_counter()
        step()
        report(f"compiled the {name} kernels ({time.perf_counter() - step_start:.1f} s)")
    return time.perf_counter() - start


if __name__ == "__main__":
    seconds = warm_up()
    print(f"numba kernels ready ({seconds:.1f} s)")
