"""A small study for the batch tests: simulated raw takes (one right hand, glove-13, noise, ghosts,
occlusion, unlabelled points) in a session."""

from __future__ import annotations

from handmocap.core.io import save_take
from handmocap.core.session.session import Session
from handmocap.core.simulate import simulate_take

FRAMES = 200


def make_study(folder, count, first_seed=0):
    """``count`` raw takes in ``folder/raw`` and a session ``folder/session`` holding them."""
    raw = folder / "raw"
    raw.mkdir(parents=True, exist_ok=True)
    session = Session.create(folder / "session")
    for number in range(count):
        take = simulate_take(layout="glove-13", n_frames=FRAMES, seed=first_seed + number, noise_mm=0.3,
                             ghost_rate=0.05, occlusion=True, unlabelled=True).take
        path = raw / f"trial{number:02d}.c3d"
        save_take(take, path)
        session.add_take(path, layout="glove-13", hands=["right"])
    return session
