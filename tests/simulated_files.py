"""Simulated takes saved as files, as the tests of several folders (cli, gui, session) use them."""

from __future__ import annotations

from pathlib import Path

from handmocap.core.io import save_take
from handmocap.core.review import ApplyLabelling, ReviewTake
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session
from handmocap.core.simulate import simulate_take
from handmocap.core.simulate.motion import simulate_joint_angles


def save_raw_take(path: Path, n_frames: int, seed: int):
    """A raw take (unlabelled, per-frame shuffled; dense layout, 0.3 mm noise, ghosts and occlusion gaps) saved
    as the C3D file ``path``; returns the simulation (``.take``, ``.truth``)."""
    simulated = simulate_take(layout="dense", n_frames=n_frames, seed=seed, noise_mm=0.3, ghost_rate=0.05,
                              occlusion=True, unlabelled=True)
    save_take(simulated.take, path)
    return simulated


def solved_review(frames: int, seed: int, ghosts: int = 1):
    """The review of a synthetic labelled take (5 labels, ``ghosts`` ghosts) with simulated joint angles as its
    solve: ``(ReviewTake, true marker positions)``."""
    take, result, truth = synthetic_labelling(frames=frames, labels=5, ghosts=ghosts, seed=seed)
    result.joint_angles = simulate_joint_angles(frames, 0, "mixed", 100.0)
    return ReviewTake.from_labelling(take, result, layout="test"), truth


def labelled_session(root: Path, frames: int, seed: int):
    """A session ``root/session`` holding the synthetic raw take ``root/raw.c3d`` (5 labels, 1 ghost), opened
    with its labelling applied: ``(opened take, labelling result)``."""
    take, result, _ = synthetic_labelling(frames=frames, labels=5, ghosts=1, seed=seed)
    save_take(take, root / "raw.c3d")
    session = Session.create(root / "session")
    opened = session.open_take(session.add_take(root / "raw.c3d").id)
    opened.push(ApplyLabelling(result))
    return opened, result
