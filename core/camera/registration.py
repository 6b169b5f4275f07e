"""Registration of a camera against a take it filmed: extrinsics from the markers and the clock, which
depend on each other (pairing camera and mocap frames needs the clock; the clock needs the pose).

1. The initial pose comes from the camera frame with the most blobs, paired with the mocap frame of each
   candidate offset (:data:`SEARCH_STEP_S` apart, nearest the guess first) until one pairing explains
   most of its blobs (:data:`ACCEPT_SHARE` within :data:`ACCEPT_PX`).
2. The clock is estimated from the blobs of all frames (:func:`core.camera.sync.sync_markers`).
3. The pose is refined over all frames paired with that clock; the clock is estimated again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.camera.extrinsics import Blobs, MarkerFrame, Registration, register_from_markers
from handmocap.core.camera.model import Camera, CameraClock
from handmocap.core.camera.overlay import markers_at
from handmocap.core.camera.sync import SyncResult, sync_markers
from handmocap.core.errors import InputError

#: offset step (s) of the initial search: the hand moves a few pixels in it
SEARCH_STEP_S = 0.03
#: blob triples tried per candidate offset
SEARCH_TRIPLES = 2
ACCEPT_SHARE = 0.8
ACCEPT_PX = 1.5
#: frames (at most) used for the refinement
REFINE_FRAMES = 60


@dataclass
class TakeRegistration:
    """A camera registered to a take: its pose (``registration``) and the clock of the synchronisation (``sync``)."""

    registration: Registration
    sync: SyncResult

    @property
    def camera(self) -> Camera:
        return self.registration.camera.with_clock(self.sync.clock)

    def report(self) -> dict:
        return {**self.registration.report(), **self.sync.report()}


def register_take(camera: Camera, blobs: list[Blobs], camera_times: np.ndarray, positions: np.ndarray,
                  mocap_rate: float, window_s: float = 1.0, use_depth: bool | None = None) -> TakeRegistration:
    """Register ``camera`` (intrinsics; its clock is the offset guess) from the ``blobs`` of its frames at
    ``camera_times (K,)`` s against the take's labelled ``positions (F,M,3)`` mm at ``mocap_rate`` Hz, the
    offset searched within ±``window_s`` of the guess. A camera already registered (e.g. from a board or
    the calibration object) starts from its pose instead of the search of step 1."""
    camera_times = np.asarray(camera_times, dtype=float)
    if camera.registered:
        registration = None
    else:
        registration = _initial_registration(camera, blobs, camera_times, positions, mocap_rate, window_s,
                                             use_depth)
    posed = camera if registration is None else registration.camera.with_clock(camera.clock)
    sync = sync_markers(posed, blobs, camera_times, positions, mocap_rate, window_s)
    chosen = np.unique(np.linspace(0, len(blobs) - 1, min(REFINE_FRAMES, len(blobs))).astype(int))
    frames = [_paired(sync.clock, blobs[k], camera_times[k], positions, mocap_rate) for k in chosen]
    registration = register_from_markers(camera, frames, use_depth, initial=posed)
    sync = sync_markers(registration.camera.with_clock(sync.clock), blobs, camera_times, positions, mocap_rate,
                        window_s=3.0 / mocap_rate)
    return TakeRegistration(registration, sync)


def _paired(clock: CameraClock, blobs: Blobs, camera_time: float, positions: np.ndarray,
            mocap_rate: float) -> MarkerFrame:
    return MarkerFrame(blobs, markers_at(positions, float(clock.mocap_frame(camera_time, mocap_rate))))


def _initial_registration(camera: Camera, blobs: list[Blobs], camera_times: np.ndarray, positions: np.ndarray,
                          mocap_rate: float, window_s: float, use_depth: bool | None) -> Registration:
    """Step 1 of the module docstring; the best pairing found when none is accepted."""
    guess = camera.clock.offset_s
    shifts = np.arange(-window_s, window_s + 1e-9, SEARCH_STEP_S)
    best = None
    for shift in shifts[np.argsort(np.abs(shifts))]:
        clock = CameraClock(guess + shift, camera.clock.rate_ratio)
        inside = [k for k in range(len(blobs))
                  if 0 <= clock.mocap_frame(camera_times[k], mocap_rate) <= len(positions) - 1]
        if not inside:
            continue
        richest = max(inside, key=lambda k: len(blobs[k].centres))
        frame = _paired(clock, blobs[richest], camera_times[richest], positions, mocap_rate)
        try:
            registration = register_from_markers(camera, [frame], use_depth, triples=SEARCH_TRIPLES)
        except InputError:
            continue
        if best is None or registration.matched_share > best.matched_share:
            best = registration
        if registration.matched_share >= ACCEPT_SHARE and registration.reprojection_px <= ACCEPT_PX:
            return registration
    if best is None:
        raise InputError("no camera pose explains the marker blobs at any offset within the search window")
    return best
