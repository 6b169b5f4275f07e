"""The streamed C3D writer: chunked frames and side-by-side point blocks give the same file as one piece."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from handmocap.core.io import Take, c3d_writer, load_take
from handmocap.core.io.c3d_writer import write_c3d, write_c3d_points
from handmocap.core.io.errors import TakeFormatError


def _positions(frames: int, points: int) -> np.ndarray:
    rng = np.random.default_rng(7)
    positions = rng.uniform(-900.0, 900.0, (frames, points, 3))
    positions[rng.random((frames, points)) < 0.2] = np.nan
    return positions


def test_chunks_and_blocks_write_the_same_bytes(tmp_path: Path, monkeypatch) -> None:
    positions = _positions(1001, 5)
    names = [f"p{index}" for index in range(5)]
    whole = tmp_path / "whole.c3d"
    write_c3d(Take(names, positions, frame_rate=120.0, first_frame=3), whole)
    monkeypatch.setattr(c3d_writer, "CHUNK_BYTES", 16 * 5 * 7)  # 7 frames per chunk, the last one short
    split = tmp_path / "split.c3d"
    write_c3d_points(split, names, [positions[:, :2], positions[:, 2:].astype(np.float32)], 120.0, 3, {})
    assert split.read_bytes() == whole.read_bytes()
    copy = load_take(split)
    assert copy.first_frame == 3 and copy.marker_names == names
    np.testing.assert_array_equal(copy.missing_mask, ~np.isfinite(positions).all(axis=2))
    np.testing.assert_allclose(copy.marker_positions, positions, rtol=1e-6, atol=1e-3)
    assert whole.stat().st_size % 512 == 0


def test_blocks_must_fit_the_names(tmp_path: Path) -> None:
    with pytest.raises(TakeFormatError, match="3 names for 2 points"):
        write_c3d_points(tmp_path / "x.c3d", ["a", "b", "c"], [_positions(4, 2)], 100.0, 1, {})
    with pytest.raises(TakeFormatError, match="same frames"):
        write_c3d_points(tmp_path / "x.c3d", ["a", "b"], [_positions(4, 1), _positions(5, 1)], 100.0, 1, {})
    with pytest.raises(TakeFormatError, match="too large"):
        write_c3d_points(tmp_path / "x.c3d", ["a"], [_positions(4, 1)], 100.0, 1, {"BIG": {"LIST": ["x"] * 300}})
    assert list(tmp_path.iterdir()) == []
