"""Synchronisation of a camera with the mocap take: the time offset (and rate ratio) of the camera clock
(:class:`core.camera.model.CameraClock`) estimated from the data.

Markers: for every candidate offset within a search window (one mocap frame apart), the labelled markers
at each camera frame's mocap time are projected and every detected blob pays its distance to the
nearest projection, truncated at :data:`TRUNCATION_PX` (the robust nearest-neighbour term of Zhao et al.
2012, eq. 4, in the image). The minimum is refined to a fraction of a frame by a parabola. Local
offsets of :data:`SEGMENTS` consecutive stretches of the video, fitted by a line against time, give the
rate ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.camera.extrinsics import Blobs
from handmocap.core.camera.model import Camera, CameraClock
from handmocap.core.errors import InputError

#: a blob further than this (px) from every projected marker costs this much
TRUNCATION_PX = 10.0
#: stretches of the video with their own offset estimate, for the rate ratio
SEGMENTS = 4
#: search half-width (mocap frames) for a stretch's offset around the global one
SEGMENT_SEARCH_FRAMES = 10


@dataclass
class SyncResult:
    """``clock`` estimated; ``offset_s`` and ``offset_frames`` (mocap frames) of camera time 0;
    ``rate_ratio``; ``quality`` 0..1: how much deeper the cost minimum is than the window's median
    (0 = flat, no evidence); ``offsets_s (C,)`` the candidates and ``costs (C,)`` their costs."""

    clock: CameraClock
    offset_frames: float
    quality: float
    offsets_s: np.ndarray
    costs: np.ndarray

    @property
    def offset_s(self) -> float:
        return self.clock.offset_s

    @property
    def rate_ratio(self) -> float:
        return self.clock.rate_ratio

    def report(self) -> dict:
        return {"offset_s": round(self.offset_s, 6), "offset_frames": round(self.offset_frames, 3),
                "rate_ratio": round(self.rate_ratio, 6), "quality": round(self.quality, 4)}


def sync_markers(camera: Camera, blobs: list[Blobs], camera_times: np.ndarray, markers: np.ndarray,
                 mocap_rate: float, window_s: float = 1.0, centre_s: float | None = None,
                 estimate_rate: bool = True) -> SyncResult:
    """Offset (and rate ratio) of a registered ``camera`` from the ``blobs`` of its frames at
    ``camera_times (K,)`` s against the take's ``markers (F,M,3)`` mm at ``mocap_rate`` Hz, searched within
    ±``window_s`` of ``centre_s`` (default: the camera's current clock offset)."""
    camera_times = np.asarray(camera_times, dtype=float)
    if len(blobs) != len(camera_times) or not sum(len(b.centres) for b in blobs):
        raise InputError("synchronisation needs camera frames with marker blobs")
    projected = camera.project(markers.reshape(-1, 3)).reshape(markers.shape[0], markers.shape[1], 2)
    centre = camera.clock.offset_s if centre_s is None else centre_s
    candidates = np.round(centre * mocap_rate) + np.arange(-round(window_s * mocap_rate),
                                                            round(window_s * mocap_rate) + 1)
    frames = np.arange(len(blobs))
    costs = np.array([_marker_cost(projected, blobs, camera_times, frames, shift, mocap_rate) for shift in candidates])
    offset_frames, quality = _minimum(candidates, costs)
    clock = CameraClock(offset_frames / mocap_rate, 1.0)
    if estimate_rate and len(blobs) >= 2 * SEGMENTS:
        clock = _rate_fit(projected, blobs, camera_times, mocap_rate, offset_frames) or clock
    return SyncResult(clock, clock.offset_s * mocap_rate, quality, candidates / mocap_rate, costs)


def _marker_cost(projected: np.ndarray, blobs: list[Blobs], camera_times: np.ndarray, frames: np.ndarray,
                 shift: float, mocap_rate: float) -> float:
    """Mean truncated blob-to-projection distance (px) of camera ``frames`` when camera time 0 is mocap
    frame ``shift``; frames outside the take cost the truncation."""
    total, count = 0.0, 0
    last = projected.shape[0] - 1
    for index in frames:
        centres = blobs[index].centres
        if not len(centres):
            continue
        position = camera_times[index] * mocap_rate + shift
        count += len(centres)
        if not 0 <= position <= last:
            total += TRUNCATION_PX * len(centres)
            continue
        low = int(np.floor(position))
        high, weight = min(low + 1, last), position - low
        pixels = (1 - weight) * projected[low] + weight * projected[high]
        pixels = pixels[np.isfinite(pixels).all(axis=1)]
        if not len(pixels):
            total += TRUNCATION_PX * len(centres)
            continue
        distance = np.linalg.norm(centres[:, None, :] - pixels[None, :, :], axis=2).min(axis=1)
        total += float(np.minimum(distance, TRUNCATION_PX).sum())
    return total / max(count, 1)


def _minimum(candidates: np.ndarray, costs: np.ndarray) -> tuple[float, float]:
    """Sub-frame position of the cost minimum (parabola through its neighbours) and the quality."""
    best = int(np.argmin(costs))
    position = float(candidates[best])
    if 0 < best < len(costs) - 1:
        left, middle, right = costs[best - 1], costs[best], costs[best + 1]
        curvature = left - 2 * middle + right
        if curvature > 0:
            position += float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))
    median = float(np.median(costs))
    quality = 0.0 if median <= 0 else float(np.clip(1.0 - costs[best] / median, 0.0, 1.0))
    return position, quality


def _rate_fit(projected: np.ndarray, blobs: list[Blobs], camera_times: np.ndarray, mocap_rate: float,
              offset_frames: float) -> CameraClock | None:
    """Clock from a line through the local offsets of :data:`SEGMENTS` stretches (None when a stretch has
    no blobs)."""
    times, offsets = [], []
    base = np.round(offset_frames)
    for frames in np.array_split(np.arange(len(blobs)), SEGMENTS):
        if not sum(len(blobs[i].centres) for i in frames):
            return None
        candidates = base + np.arange(-SEGMENT_SEARCH_FRAMES, SEGMENT_SEARCH_FRAMES + 1)
        costs = np.array([_marker_cost(projected, blobs, camera_times, frames, s, mocap_rate) for s in candidates])
        local, _ = _minimum(candidates, costs)
        times.append(camera_times[frames].mean())
        offsets.append(local / mocap_rate)
    slope, intercept = np.polyfit(times, offsets, 1)
    ratio = 1.0 + slope
    return CameraClock(float(intercept), float(ratio)) if 0.9 < ratio < 1.1 else None
