"""Joint-angle files: the CSV every exporter writes and the ``joint_angles`` of a solve result ``.npz``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.durable import write_atomic
from handmocap.core.io.npz import load_npz
from handmocap.core.model.skeleton import N_PARAMS, PARAM_NAMES


def write_joint_angles_csv(path: str | os.PathLike[str], hands: list[tuple[str, np.ndarray]], first_frame: int,
                           frame_rate: float, events: dict[int, str] | None = None) -> None:
    """One CSV of ``frame, time_s`` then per hand ``(column prefix, joint_angles (F, 26))`` the 26 parameters:
    translations in mm (``wrist_tx_mm``...), angles in degrees; unsolved samples are empty cells. ``events``
    ({frame number: names}) add a last column ``event`` holding the names at their frames.
    Durable (:mod:`core.io.durable`); WriteError (an InputError) naming the file when it cannot be written."""
    n_frames = len(hands[0][1])
    frames = np.arange(n_frames) + first_frame
    header = ["frame", "time_s"]
    blocks = [frames[:, None].astype(np.float64), ((frames - first_frame) / frame_rate)[:, None]]
    for prefix, joint_angles in hands:
        header += [f"{prefix}{name}_{'mm' if index < 3 else 'deg'}" for index, name in enumerate(PARAM_NAMES)]
        angles = np.array(joint_angles, dtype=np.float64)
        angles[:, 3:] = np.degrees(angles[:, 3:])
        blocks.append(angles)
    table = np.concatenate(blocks, axis=1)
    if events:
        header.append("event")
    rows = [",".join(header)]
    for row in table:
        cells = [f"{int(row[0])}", f"{row[1]:.6f}"] + ["" if not np.isfinite(v) else f"{v:.6f}" for v in row[2:]]
        if events:
            name = events.get(int(row[0]), "").replace('"', "'")
            cells.append(f'"{name}"' if "," in name else name)
        rows.append(",".join(cells))
    write_atomic(path, ("\n".join(rows) + "\n").encode("utf-8"))


def read_result_joint_angles(path: str | os.PathLike[str]) -> np.ndarray:
    """``joint_angles (F, 26)`` (mm, rad) of a solve result ``.npz``; InputError if unreadable."""
    data = load_npz(path, "an IK result with joint angles")
    try:
        angles = np.asarray(data["joint_angles"], dtype=float)
    except (KeyError, ValueError, TypeError) as error:
        raise InputError(f"{Path(path).name}: not an IK result with joint angles ({error})") from error
    if angles.ndim != 2 or angles.shape[1] != N_PARAMS:
        raise InputError(f"{Path(path).name}: joint_angles must be (F, 26), got {angles.shape}")
    return angles
