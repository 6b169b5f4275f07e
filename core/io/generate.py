"""Synthetic C3D takes for benchmarks, and the load benchmark itself."""

import tempfile
import time
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.io.c3d_writer import write_c3d
from handmocap.core.io.loader import load_take
from handmocap.core.io.take import Take

BENCH_FRAME_RATE_HZ = 120.0


def write_benchmark_c3d(
    path: str | PathLike[str], n_frames: int = 100_000, n_markers: int = 40, seed: int = 0
) -> None:
    """Write a synthetic take: markers in a 100 mm cloud orbiting smoothly 1 m above the floor, 1 % missing.

    Positions are (n_frames, n_markers, 3) in mm at BENCH_FRAME_RATE_HZ, built without Python loops.
    """
    rng = np.random.default_rng(seed)
    times = np.arange(n_frames)[:, np.newaxis, np.newaxis] / BENCH_FRAME_RATE_HZ  # (F, 1, 1) s
    rest = rng.normal(0.0, 50.0, (1, n_markers, 3)) + np.array([0.0, 0.0, 1000.0])
    frequency = rng.uniform(0.1, 1.0, (1, n_markers, 3))  # Hz
    phase = rng.uniform(0.0, 2 * np.pi, (1, n_markers, 3))
    positions = rest + 200.0 * np.sin(2 * np.pi * frequency * times + phase)
    positions[rng.random((n_frames, n_markers)) < 0.01] = np.nan
    take = Take(
        marker_names=[f"marker_{index + 1:03d}" for index in range(n_markers)],
        marker_positions=positions,
        frame_rate=BENCH_FRAME_RATE_HZ,
    )
    write_c3d(take, path)


def bench_load(n_frames: int = 100_000, n_markers: int = 40) -> dict:
    """Seconds `load_take` needs for a synthetic C3D of n_frames x n_markers (written to a temp folder).

    Returns {"seconds": float, "frames": int, "markers": int}.
    """
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "benchmark.c3d"
        write_benchmark_c3d(path, n_frames, n_markers)
        start = time.perf_counter()
        take = load_take(path)
        seconds = time.perf_counter() - start
    return {"seconds": seconds, "frames": take.n_frames, "markers": take.n_markers}
