"""What an automatic labelling tells the operator about its own doubts: the noise and speed it
measured on the take, and warnings over frame ranges where the result looks wrong."""

from __future__ import annotations

import numpy as np

from handmocap.core.labelling.health_warning import HealthWarning
from handmocap.core.labelling.result import SceneLabelling

NOISY_TAKE_MM = 1.0
"""Marker noise σ per axis (mm) above which a take is reported as noisy: a well-calibrated optical
system gives 0.1-0.5 mm; real systems reach 2 mm with poor calibration or small markers far away."""
WINDOW_SECONDS = 1.0
"""Health is judged per window of this length."""
LOW_SHARE_RATIO = 0.5
"""A window where a model labels less than this share of what it labels in a typical window is flagged."""
GHOST_SHARE = 0.25
"""A window where more than this share of the points are left as ghosts (and twice the take's typical
share) is flagged: with the noise-derived gates, real ghosts are a few per cent of the points."""
RESIDUAL_RATIO = 2.0
"""A window whose mean IK residual is this many times the take's typical one is flagged, when it is also beyond
the take's own spread of window residuals (:data:`SPREAD_FACTOR`) and above :data:`RESIDUAL_FLOOR_MM`."""
RESIDUAL_FLOOR_MM = 1.5
"""A window whose mean residual is below this (and below 4 noise σ) is never flagged: an IK fit within 1.5 mm
of the markers is good, however it compares with the rest of the take."""
SPREAD_FACTOR = 5.0
"""A window is unusual when it is further than this many robust standard deviations (1.4826 x MAD) of the
take's own windows from their median."""
MERGE_WINDOWS = 3
"""Flagged windows this close (windows between them) make one warning."""
REINIT_MERGE_SECONDS = 5.0
"""Re-initialisations of a hand within this many seconds of each other make one warning."""


def _runs(flags: np.ndarray, merge: int = MERGE_WINDOWS) -> list[tuple[int, int]]:
    """(first, last) window indices of the runs of True in ``flags``; runs at most ``merge`` windows apart
    become one."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(np.int8), [0]])))
    merged: list[tuple[int, int]] = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if merged and int(start) - merged[-1][1] - 1 <= merge:
            merged[-1] = (merged[-1][0], int(stop) - 1)
        else:
            merged.append((int(start), int(stop) - 1))
    return merged


def _spread(values: np.ndarray) -> float:
    """Robust standard deviation (1.4826 x MAD) of the finite ``values`` (0 when there are none)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return 0.0
    return float(1.4826 * np.median(np.abs(finite - np.median(finite))))


def _mm(value: float) -> str:
    """A distance for a message: two significant figures below 10 mm (0.31 mm, 2.4 mm), whole mm above."""
    return f"{value:.2g} mm" if value < 10 else f"{value:.0f} mm"


def _grouped(frames: list[int], gap: int) -> list[list[int]]:
    """``frames`` (sorted) in groups whose neighbours are at most ``gap`` frames apart."""
    groups: list[list[int]] = []
    for frame in frames:
        if groups and frame - groups[-1][-1] <= gap:
            groups[-1].append(frame)
        else:
            groups.append([frame])
    return groups


def _windows(values: np.ndarray, size: int) -> np.ndarray:
    """Mean of ``values (F,)`` over consecutive windows of ``size`` frames (NaN-aware; the last may be shorter)."""
    count = int(np.ceil(len(values) / size))
    padded = np.full(count * size, np.nan)
    padded[:len(values)] = values
    blocks = padded.reshape(count, size)
    finite = np.isfinite(blocks).sum(axis=1)
    return np.where(finite > 0, np.nansum(blocks, axis=1) / np.maximum(finite, 1), np.nan)


def assess_labelling(result: SceneLabelling, frame_rate: float) -> list[HealthWarning]:
    """The doubts about ``result`` an operator should check (see :data:`WARNING_KINDS`): a noisy take, a
    side decided by a small margin, and per model the windows of :data:`WINDOW_SECONDS` where it labels
    much less than usual, leaves many points as ghosts or fits much worse than usual. Frames 0-based."""
    warnings: list[HealthWarning] = []
    frames = result.assignment.shape[0]
    size = max(1, int(round(WINDOW_SECONDS * frame_rate)))
    if result.noise_mm is not None and result.noise_mm > NOISY_TAKE_MM:
        warnings.append(HealthWarning("noisy_take", "", 0, frames - 1,
                                      f"marker noise σ ≈ {result.noise_mm:.2f} mm per axis (above "
                                      f"{NOISY_TAKE_MM:g} mm): the labelling gates were widened to match; "
                                      "check the calibration"))
    decision = result.side_decision
    if decision is not None:
        for side in decision.uncertain:
            warnings.append(HealthWarning("side_uncertain", side, decision.frame, decision.frame,
                                          f"the {side} hand was told from its mirror image by a small margin "
                                          f"({decision.margins[side]:.2f}): check the side"))
    for model in result.models:
        if model.kind not in ("right", "left"):
            continue
        if model.init_frame < 0:
            warnings.append(HealthWarning("no_hand", model.name, 0, frames - 1,
                                          f"the {model.name} hand was not found in any frame"))
            continue
        for group in _grouped(sorted(model.reinitialised), max(1, int(REINIT_MERGE_SECONDS * frame_rate))):
            times = "" if len(group) == 1 else f" {len(group)} times"
            warnings.append(HealthWarning(
                "reinitialised", model.name, group[0], group[-1],
                f"the {model.name} hand was fitted afresh here{times} (it was lost, or fitted much worse than "
                "elsewhere) and its labels changed: check them on either side"))
        labelled = (result.assignment[:, model.markers] >= 0).mean(axis=1).astype(float)
        labelled[:model.init_frame] = np.nan
        shares = _windows(labelled, size)
        typical = float(np.nanmedian(shares)) if np.isfinite(shares).any() else 0.0
        with np.errstate(invalid="ignore"):
            low = (shares < LOW_SHARE_RATIO * typical) & (shares < typical - SPREAD_FACTOR * _spread(shares))
        for first, last in _runs(low):
            warnings.append(HealthWarning(
                "low_labelled_share", model.name, first * size, min(frames, (last + 1) * size) - 1,
                f"the {model.name} hand labels {100 * float(np.nanmean(shares[first:last + 1])):.0f} % of its markers "
                f"here against {100 * typical:.0f} % elsewhere"))
        labelled_residuals = np.where(result.assignment[:, model.markers] >= 0, result.residuals_mm[:, model.markers],
                                      np.nan)
        counts = np.isfinite(labelled_residuals).sum(axis=1)
        residuals = np.where(counts > 0, np.nansum(labelled_residuals, axis=1) / np.maximum(counts, 1), np.nan)
        windows = _windows(residuals, size)
        if np.isfinite(windows).any():
            typical_residual = float(np.nanmedian(windows))
            floor = max(RESIDUAL_FLOOR_MM, 4.03 * (result.noise_mm or 0.0))
            limit = max(RESIDUAL_RATIO * typical_residual, typical_residual + SPREAD_FACTOR * _spread(windows), floor)
            with np.errstate(invalid="ignore"):
                high = windows > limit
            for first, last in _runs(high):
                here = float(np.nanmax(windows[first:last + 1]))
                warnings.append(HealthWarning(
                    "high_residual", model.name, first * size, min(frames, (last + 1) * size) - 1,
                    f"the {model.name} hand fits with up to {_mm(here)} mean residual here against "
                    f"{_mm(typical_residual)} typically over the take"))
    points = np.isfinite(result.points).all(axis=2).sum(axis=1).astype(float)
    ghost_share = _windows(result.ghost_points.sum(axis=1) / np.maximum(points, 1), size)
    if len(ghost_share):
        typical_ghosts = float(np.nanmedian(ghost_share))
        with np.errstate(invalid="ignore"):
            ghostly = ghost_share > max(GHOST_SHARE, 2.0 * typical_ghosts)
        for first, last in _runs(ghostly):
            warnings.append(HealthWarning(
                "many_ghosts", "", first * size, min(frames, (last + 1) * size) - 1,
                f"{100 * float(np.nanmean(ghost_share[first:last + 1])):.0f} % of the points are left unlabelled "
                "as ghosts here: check for markers of another subject or object, or a wrong layout"))
        if typical_ghosts > GHOST_SHARE:
            warnings.append(HealthWarning(
                "many_ghosts", "", 0, frames - 1,
                f"{100 * typical_ghosts:.0f} % of the points are left unlabelled as ghosts over the take: "
                "markers outside the layout (label them, or give their rigid body) or a wrong layout"))
    return warnings
