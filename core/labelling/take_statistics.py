"""Noise and speed of a take's markers, measured on its raw points before any labelling.

The labeller's millimetre gates scale with what a take shows (:meth:`SceneSettings.adapted`), so a
noisier system, a faster subject or another frame rate is handled without re-tuning. Points are
linked frame to frame where the link is unambiguous (mutual nearest neighbours whose next-nearest
alternative is at least :data:`AMBIGUITY_RATIO` times farther), over chains of
:data:`CHAIN_FRAMES` frames. On those chains:

- the noise σ per axis comes from the 4th finite difference, whose noise variance is 70 σ² while
  smooth hand motion sampled at 60 Hz or more contributes little to it (robust: median absolute
  value / 0.6745);
- the constant-velocity extrapolation error (what the continuity test of a trajectory sees: the 2nd
  difference, noise variance 6 σ² plus the true acceleration) is summarised by a high quantile;
- the frame-to-frame step of the points by a high quantile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

CHAIN_FRAMES = 5
"""Frames per linked chain: the 4th difference needs five samples."""
AMBIGUITY_RATIO = 2.0
"""A link is kept when the next-nearest point (either way) is at least this times farther than the linked one."""
MAX_WINDOWS = 1500
"""At most this many chain windows are sampled, evenly over the take (cost independent of its length)."""
MAX_LINK_WORK = 50_000_000
"""Fewer windows are sampled when a take has very many points P per frame (windows × P² at most this)."""
FOURTH_DIFFERENCE_VARIANCE = 70.0
"""Variance of the 4th difference of white noise of unit variance: C(8, 4)."""
SECOND_DIFFERENCE_VARIANCE = 6.0
"""Variance of the 2nd difference (constant-velocity extrapolation error) of unit white noise."""
MAD_TO_SIGMA = 1.0 / 0.6745


@dataclass(frozen=True)
class TakeStatistics:
    """Measured on the raw points of a take: ``noise_mm`` σ per axis (mm); ``extrapolation_mm`` the
    99.9th percentile of the 3D constant-velocity extrapolation error (mm); ``step_mm`` the 99th
    percentile of the frame-to-frame displacement (mm); ``chains`` how many linked chains gave them
    (0: nothing could be measured and the values are NaN)."""

    noise_mm: float
    extrapolation_mm: float
    step_mm: float
    chains: int

    @property
    def measured(self) -> bool:
        return self.chains > 0 and bool(np.isfinite(self.noise_mm))


def unambiguous_links(current: np.ndarray, following: np.ndarray) -> np.ndarray:
    """Unambiguous links between two frames' points ``(W,P,3)`` (NaN absent): per point of ``current`` the
    index of its point in ``following`` ``(W,P)``, -1 where the link is ambiguous or absent: the mutual
    nearest neighbours (the first of equals) whose next-nearest alternative, either way, is at least
    :data:`AMBIGUITY_RATIO` times farther. Compiled (:func:`_links_kernel`), frame by frame, without holding
    the pair distances of more than one frame."""
    current = np.ascontiguousarray(current, dtype=np.float64)
    following = np.ascontiguousarray(following, dtype=np.float64)
    if current.shape[1] == 0 or following.shape[1] == 0:
        return np.full(current.shape[:2], -1, dtype=np.int64)
    return _links_kernel(current, following, AMBIGUITY_RATIO)


@njit(cache=True)
def _nearest_two(distances: np.ndarray, nearest: np.ndarray, best: np.ndarray, second: np.ndarray) -> None:
    """Per row of ``distances (R, C)``, written: the column of its smallest value (the first of equals), that
    value and the next smallest (inf when none)."""
    for row in range(distances.shape[0]):
        column, lowest, next_lowest = 0, np.inf, np.inf
        for j in range(distances.shape[1]):
            value = distances[row, j]
            if value < lowest:
                column, lowest, next_lowest = j, value, lowest
            elif value < next_lowest:
                next_lowest = value
        nearest[row], best[row], second[row] = column, lowest, next_lowest


@njit(cache=True)
def _links_kernel(current: np.ndarray, following: np.ndarray, ratio: float) -> np.ndarray:
    windows, count, others = current.shape[0], current.shape[1], following.shape[1]
    links = np.full((windows, count), -1, dtype=np.int64)
    distances = np.empty((count, others))
    forward_nearest = np.zeros(count, dtype=np.int64)
    forward_best = np.empty(count)
    forward_second = np.empty(count)
    backward_nearest = np.zeros(others, dtype=np.int64)
    backward_second = np.empty(others)
    backward_best = np.empty(others)
    for window in range(windows):
        for i in range(count):
            for j in range(others):
                dx = current[window, i, 0] - following[window, j, 0]
                dy = current[window, i, 1] - following[window, j, 1]
                dz = current[window, i, 2] - following[window, j, 2]
                value = np.sqrt(dx * dx + dy * dy + dz * dz)
                distances[i, j] = value if np.isfinite(value) else np.inf
        _nearest_two(distances, forward_nearest, forward_best, forward_second)
        _nearest_two(distances.T, backward_nearest, backward_best, backward_second)
        for i in range(count):
            best, nearest = forward_best[i], forward_nearest[i]
            if (np.isfinite(best) and backward_nearest[nearest] == i and forward_second[i] >= ratio * best
                    and backward_second[nearest] >= ratio * best):
                links[window, i] = nearest
    return links


def measure_take(positions: np.ndarray) -> TakeStatistics:
    """Noise and speed of the raw points ``positions (F,P,3)`` mm (NaN absent), see the module docstring."""
    positions = np.asarray(positions, dtype=float)
    frames = positions.shape[0]
    if frames < CHAIN_FRAMES or positions.shape[1] == 0:
        return TakeStatistics(np.nan, np.nan, np.nan, 0)
    count = min(MAX_WINDOWS, max(10, MAX_LINK_WORK // positions.shape[1] ** 2), frames - CHAIN_FRAMES + 1)
    starts = np.unique(np.linspace(0, frames - CHAIN_FRAMES, count).astype(np.int64))
    windows = positions[starts[:, None] + np.arange(CHAIN_FRAMES)]           # (W,5,P,3)
    column = np.broadcast_to(np.arange(positions.shape[1]), (len(starts), positions.shape[1])).copy()
    chain = [windows[:, 0]]
    valid = np.isfinite(windows[:, 0]).all(axis=2)
    for step in range(1, CHAIN_FRAMES):
        links = unambiguous_links(windows[:, step - 1], windows[:, step])
        column = np.where(valid, np.take_along_axis(links, np.maximum(column, 0), axis=1), -1)
        valid &= column >= 0
        chain.append(np.take_along_axis(windows[:, step], np.maximum(column, 0)[:, :, None], axis=1))
    samples = np.stack(chain, axis=2)[valid]                                   # (C,5,3)
    if len(samples) < 10:
        return TakeStatistics(np.nan, np.nan, np.nan, len(samples))
    fourth = samples[:, 0] - 4 * samples[:, 1] + 6 * samples[:, 2] - 4 * samples[:, 3] + samples[:, 4]
    noise = float(np.median(np.abs(fourth)) * MAD_TO_SIGMA / np.sqrt(FOURTH_DIFFERENCE_VARIANCE))
    second = samples[:, 2:] - 2 * samples[:, 1:-1] + samples[:, :-2]
    extrapolation = float(np.quantile(np.linalg.norm(second, axis=2), 0.999))
    step_mm = float(np.quantile(np.linalg.norm(np.diff(samples, axis=1), axis=2), 0.99))
    return TakeStatistics(noise, extrapolation, step_mm, len(samples))
