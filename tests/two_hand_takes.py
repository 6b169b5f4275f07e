"""Labelled takes of one or two simulated hands named the ways other programs name them, for the tests of
:func:`core.model.detect_hands` and of everything built on it (solve, fill, export, the GUI).

Every take is the simulated scene of :func:`core.simulate.simulate_scene` (glove-13, no objects, no ghosts)
with its labelled markers kept where the cameras see them; only the names change:

* ``label``: as ``handmocap label --hands both`` writes them (``R_hand_top``, ``L_hand_top``);
* ``template``: a lab's own names per side (``R-Wan-nei``, ``L-A1``) from :func:`lab_template_json`;
* ``vicon``: Vicon subjects that say the side (``RightHand:hand_top``, ``LeftHand:hand_top``);
* ``dash``: a side prefix with a dash (``R-hand_top``, ``L-hand_top``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from handmocap.core.io import Take
from handmocap.core.model import load_layout
from handmocap.core.simulate import simulate_scene

LAYOUT = "glove-13"
#: a lab's names for the markers of glove-13 (the same placement, the lab's words)
LAB_NAMES = {"hand_top": "Wan-nei", "hand_left": "Wan-wai", "hand_right": "Zhang", "thumb_tip": "A1",
             "thumb_middle": "A2", "index_tip": "B1", "index_middle": "B2", "middle_tip": "C1",
             "middle_middle": "C2", "ring_tip": "D1", "ring_middle": "D2", "little_tip": "E1", "little_middle": "E2"}
STYLES = ("label", "template", "vicon", "dash")


def marker_name(style: str, side: str, marker: str) -> str:
    """The name ``style`` gives the glove-13 ``marker`` of the ``side`` hand."""
    letter = "R" if side == "right" else "L"
    if style == "label":
        return f"{letter}_{marker}"
    if style == "template":
        return f"{letter}-{LAB_NAMES[marker]}"
    if style == "vicon":
        return f"{side.capitalize()}Hand:{marker}"
    if style == "dash":
        return f"{letter}-{marker}"
    raise ValueError(style)


def simulated_hands(hands: str = "both", frames: int = 150, seed: int = 3) -> tuple[list[tuple[str, str]], np.ndarray,
                                                                                   dict]:
    """``[(side, glove-13 marker)]`` per column, positions ``(F, M, 3)`` mm (NaN where hidden) and the truth."""
    scene = simulate_scene(LAYOUT, n_frames=frames, seed=seed, hands=hands, n_objects=0, noise_mm=0.2,
                           ghost_rate=0.0, occlusion=True)
    truth = scene.truth
    sides = ["right", "left"] if hands == "both" else [hands]
    markers = [(sides[int(owner)], str(name).split("_", 1)[1] if hands == "both" else str(name))
               for name, owner in zip(truth["marker_names"], truth["model_of_marker"], strict=True)]
    positions = np.where(truth["visible"][:, :, None], truth["marker_positions"], np.nan)
    return markers, positions, truth


def named_take(style: str, hands: str = "both", frames: int = 150, seed: int = 3) -> Take:
    """A labelled take of ``hands`` ("both", "right", "left") with its markers named in ``style``."""
    markers, positions, _ = simulated_hands(hands, frames, seed)
    return Take([marker_name(style, side, marker) for side, marker in markers], positions, 100.0)


def lab_template_json(name: str = "guitar-lab") -> dict:
    """A lab template (:mod:`core.model.lab_template`) with the glove-13 placement under the lab's names."""
    specs = load_layout(LAYOUT).to_json()["markers"]
    hands = {side: {"markers": [{**spec, "name": marker_name("template", side, spec["name"])} for spec in specs]}
             for side in ("right", "left")}
    return {"name": name, "template_version": 1, "markers": hands["right"]["markers"], "hands": hands, "objects": []}


def write_lab_template(folder: Path, name: str = "guitar-lab") -> Path:
    """Write :func:`lab_template_json` as ``folder/<name>.json``; its path."""
    path = Path(folder) / f"{name}.json"
    path.write_text(json.dumps(lab_template_json(name)), encoding="utf-8")
    return path
