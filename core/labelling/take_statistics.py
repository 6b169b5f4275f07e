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

CHAIN_FRAMES = 5
"""Frames per linked chain: the 4th difference needs five samples."""
AMBIGUITY_RATIO = 2.0
"""A link is kept when the next-nearest point (either way) is at least this times farther than the linked one."""
MAX_WINDOWS = 1500
"""At most this many chain windows are sampled, evenly over the take (cost independent of its length)."""
MAX_LINK_WORK = 50_000_000
"""Fewer windows are sampled when a take has very many points P per frame (windows × P² at most this)."""
MAX_PAIR_DISTANCES = 4_000_000
"""Point-pair distances held in memory at once while linking (32 MB)."""
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
    index of its point in ``following`` ``(W,P)``, -1 where the link is ambiguous or absent. Works in
    blocks of frames so that no more than :data:`MAX_PAIR_DISTANCES` distances are held at once."""
    count = current.shape[1]
    block = max(1, MAX_PAIR_DISTANCES // max(count * count, 1))
    if len(current) > block:
        return np.concatenate([_links(current[start:start + block], following[start:start + block])
                               for start in range(0, len(current), block)])
    return _links(current, following)


def _two_smallest(distances: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index of the smallest value along ``axis`` of ``distances``, that value and the second smallest
    (inf when there is none); linear time (partition, not sort)."""
    size = distances.shape[axis]
    nearest = np.argmin(distances, axis=axis)
    best = np.min(distances, axis=axis)
    if size < 2:
        return nearest, best, np.full(best.shape, np.inf)
    second = np.take(np.partition(distances, 1, axis=axis), 1, axis=axis)
    return nearest, best, second


def _links(current: np.ndarray, following: np.ndarray) -> np.ndarray:
    distances = np.sqrt(((current[:, :, None, :] - following[:, None, :, :]) ** 2).sum(axis=3))
    distances = np.where(np.isfinite(distances), distances, np.inf)
    if distances.shape[2] < 1:
        return np.full(distances.shape[:2], -1)
    nearest, best, second = _two_smallest(distances, 2)                  # (W,P) per current point
    backward_nearest, _, backward_second = _two_smallest(distances, 1)   # (W,P) per following point
    mutual = np.take_along_axis(backward_nearest, nearest, axis=1) == np.arange(distances.shape[1])[None, :]
    clear = (second >= AMBIGUITY_RATIO * best) & \
        (np.take_along_axis(backward_second, nearest, axis=1) >= AMBIGUITY_RATIO * best)
    return np.where(np.isfinite(best) & mutual & clear, nearest, -1)


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
