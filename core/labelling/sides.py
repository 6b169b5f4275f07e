"""Which hands a take shows (``hands="auto"``): right, left or both, decided from the markers.

A single frame cannot tell a hand from its mirror image well (a right model fits a left hand's
back-of-hand markers with a low residual by taking the fingers in reverse order), but the fingers'
motion can: flexion bends them towards the palm, which the mirrored fit can only follow by leaving
its joint limits. So, from the first frame where a hand fits a cluster, every hand-sized cluster is
fitted with both models, the best fits of each are tracked over the next
``settings.hypothesis_frames`` frames, and each cluster gets the side whose tracked fit costs less
(mean eq. 2 cost per frame). Two hand clusters are one right and one left hand (the pairing of least
total cost, so two hands are never started exchanged). The margin between the two sides' costs is
kept (a small one is reported to the operator), and so is the winning fit of each side: tracking
starts from it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.labelling.initialise import clusters_of, find_spread_object, fit_hand
from handmocap.core.labelling.models import HandTracker, RigidTrack, SceneSettings

Start = tuple[np.ndarray, np.ndarray]
"""Where a hand starts: point column per marker (K,) (-1 none) and θ (26,)."""

SIDE_MARGIN = 0.5
"""A side decided by a cost margin (mm-equivalent of eq. 2 per frame) below this is reported as
uncertain: half a millimetre of mean residual, or half a marker lost per frame."""


@dataclass(frozen=True)
class SideDecision:
    """``sides``: the hands found ("right", "left" or both, in that order); ``frame`` where it was decided;
    ``margins`` per side: the other side's tracked cost minus this side's (mm-equivalent, larger is surer);
    ``starts``: the tracked fit each side won with, to start tracking from."""

    sides: list[str]
    frame: int
    margins: dict[str, float]
    #: per side, the winning start: point column per marker (K,) (-1 none) and θ (26,) in ``frame``
    starts: dict[str, Start] = field(default_factory=dict)

    @property
    def uncertain(self) -> list[str]:
        return [side for side, margin in self.margins.items() if margin < SIDE_MARGIN]


def decide_sides(positions: np.ndarray, make_track: Callable[[str], HandTracker], settings: SceneSettings,
                 cut_mm: float, cost: Callable[[HandTracker, int, np.ndarray, np.ndarray], float],
                 objects: Sequence[RigidTrack] = (), expect_both: bool = False) -> SideDecision:
    """Decide the hands of ``positions (F,P,3)`` mm (module docstring). ``make_track(side)`` gives a fresh
    track of that side; ``cost(track, frame, labels (K,) point columns, θ)`` the tracked cost of a start. The
    points of the rigid ``objects`` found by their own geometry in a frame (a prop next to a hand) are set aside
    before its clusters are fitted. ``expect_both`` (a lab template with both hands): when the deciding frame
    shows one hand, later frames are searched for a second (:func:`_second_hand_later`); the other side then
    starts wherever the tracker first finds it. Raises :class:`InputError` when no frame holds a cluster either
    hand fits."""
    present = np.isfinite(positions).all(axis=2)
    probes = {side: make_track(side) for side in ("right", "left")}
    least = max(3, int(np.ceil(settings.init_min_share * probes["right"].count)))
    for frame in range(0, len(positions), max(settings.retry_every, 1)):
        columns = np.flatnonzero(present[frame])
        columns = columns[_not_objects(positions[frame, columns], objects, settings)]
        if len(columns) < least:
            continue
        points = positions[frame, columns]
        clusters: list[tuple[dict[str, float], dict[str, Start]]] = []     # per hand cluster: cost, start per side
        for members in clusters_of(points, cut_mm):
            if len(members) < least:
                continue
            costs: dict[str, float] = {}
            starts: dict[str, Start] = {}
            for side, probe in probes.items():
                for fit in fit_hand(probe, points[members], settings):
                    if fit[3] > settings.init_max_residual_mm or fit[2] < least:
                        continue
                    labels = np.where(fit[4] >= 0, columns[members][np.maximum(fit[4], 0)], -1)
                    tracked = cost(make_track(side), frame, labels, fit[1])
                    if tracked < costs.get(side, np.inf):
                        costs[side], starts[side] = tracked, (labels, fit[1])
            if costs:
                clusters.append(({side: costs.get(side, np.inf) for side in probes}, starts))
        if not clusters:
            continue
        clusters.sort(key=lambda cluster: min(cluster[0].values()))
        if len(clusters) == 1:
            costs, starts = clusters[0]
            best = min(costs, key=lambda side: costs[side])
            other = "left" if best == "right" else "right"
            margin = costs[other] - costs[best]
            if expect_both and _second_hand_later(positions, present, frame, probes, objects, settings, cut_mm,
                                                  least):
                return SideDecision(sorted([best, other], key=("right", "left").index), frame, {best: margin},
                                    {best: starts[best]})
            return SideDecision([best], frame, {best: margin}, {best: starts[best]})
        (first, first_starts), (second, second_starts) = clusters[0], clusters[1]
        straight = first["right"] + second["left"]
        crossed = first["left"] + second["right"]
        margin = float(abs(straight - crossed))
        chosen = {"right": first_starts.get("right"), "left": second_starts.get("left")} if straight <= crossed \
            else {"right": second_starts.get("right"), "left": first_starts.get("left")}
        return SideDecision(["right", "left"], frame, {"right": margin, "left": margin},
                            {side: start for side, start in chosen.items() if start is not None})
    raise InputError("no frame of the take initialises a hand: no cluster of points fits a left or right hand "
                     "with this layout (is the layout right, and is most of the hand visible in some frame?)")


def _not_objects(points: np.ndarray, objects: Sequence[RigidTrack], settings: SceneSettings) -> np.ndarray:
    """``(N,)`` True for the ``points (N,3)`` no rigid object takes when found by its own geometry."""
    free = np.ones(len(points), dtype=bool)
    for track in objects:
        found = find_spread_object(track, points[free], settings)
        if found is not None:
            taken = np.flatnonzero(free)[found.point_index[found.point_index >= 0]]
            free[taken] = False
    return free


#: frames searched for a second hand after a deciding frame that showed one (spread over the rest of the take)
SECOND_HAND_PROBES = 12


def _second_hand_later(positions: np.ndarray, present: np.ndarray, frame: int, probes: dict[str, HandTracker],
                       objects: Sequence[RigidTrack], settings: SceneSettings, cut_mm: float, least: int) -> bool:
    """True when a frame after ``frame`` (:data:`SECOND_HAND_PROBES` of them, evenly spread) holds two clusters
    that a hand model fits (either side): the take shows two hands, the second out of sight at first."""
    later = np.unique(np.linspace(frame + 1, len(positions) - 1, SECOND_HAND_PROBES).astype(np.int64))
    for probe_frame in later[later > frame]:
        columns = np.flatnonzero(present[probe_frame])
        columns = columns[_not_objects(positions[probe_frame, columns], objects, settings)]
        points = positions[probe_frame, columns]
        fitted = 0
        for members in clusters_of(points, cut_mm):
            if len(members) < least:
                continue
            if any(fit[3] <= settings.init_max_residual_mm and fit[2] >= least
                   for probe in probes.values() for fit in fit_hand(probe, points[members], settings)):
                fitted += 1
        if fitted >= 2:
            return True
    return False
