"""Whole-take identity of a hand labelled with a lab template: is the labelling right for the whole take?

A labelling can be wrong for a whole take and still fit the hand model well (the fingers of a fretting hand
cycled by one, a tip exchanged with its middle marker): the IK residual cannot see it, the template's
distance statistics can. For each hand, the labelling is compared with the whole-take hypotheses

- the four fingers' labels cycled by one, two or three fingers (marker for marker by segment),
- one digit's tip and middle labels exchanged,
- the two hands' labels exchanged (a template with both hands whose names correspond),

by the statistics cost (:func:`statistics_cost`): over the frames, the mean of the squared standardised
deviations of every labelled pair's distance from its learned mean. A hypothesis clearly better
(:data:`SWITCH_RATIO`) replaces the labelling for the whole take; one nearly as good (:data:`DOUBT_RATIO`) and
better in a fair share of the frames (:data:`DOUBT_SHARE`) is reported as a doubt on that hand, with that share.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.labelling.health import HealthWarning
from core.model.hand_columns import name_side
from core.model.lab_template import LabTemplate, PairStatistics, TemplateHand

if TYPE_CHECKING:
    from core.labelling.scene import SceneLabelling

#: a hypothesis whose cost is below this share of the labelling's own replaces it
SWITCH_RATIO = 0.5
#: a hypothesis whose cost is below this multiple of the labelling's own is a doubt worth saying
DOUBT_RATIO = 1.25
#: ... and fits better in at least this share of the frames
DOUBT_SHARE = 0.2
#: the spread (mm) under which a pair's learned standard deviation is not trusted: the tracking noise of a
#: distance between two markers seen at 0.3 mm per axis, the floor the labeller's gates use
SPREAD_FLOOR_MM = 0.5
#: frames sampled per hand for the costs (the cost is a mean; a few thousand frames settle it)
SAMPLED_FRAMES = 3000
#: standardised deviations are clipped here so that one occluded or ghost frame cannot decide
Z_CLIP = 10.0


@dataclass
class Hypothesis:
    """A whole-take relabelling of one hand: ``name`` (what it says) and ``permutation (M,)``: the label each
    label's points go to (an index into the scene's marker list)."""

    name: str
    permutation: np.ndarray


def statistics_cost(positions: np.ndarray, statistics: PairStatistics, noise_mm: float) -> np.ndarray:
    """Per frame ``(F,)``: the mean over the labelled pairs of ``positions (F,M,3)`` mm (in the statistics'
    marker order) of the squared standardised deviation of their distance, clipped at :data:`Z_CLIP`; NaN in a
    frame with no labelled pair."""
    distances = np.linalg.norm(positions[:, :, None] - positions[:, None], axis=3)
    spread = np.maximum(statistics.sd_mm, max(SPREAD_FLOOR_MM, 2.0 * noise_mm))
    z = np.minimum(((distances - statistics.mean_mm) / spread) ** 2, Z_CLIP ** 2)
    upper = np.triu(np.ones(statistics.mean_mm.shape, dtype=bool), 1) & np.isfinite(statistics.mean_mm)
    values = np.where(upper & np.isfinite(z), z, 0.0).sum(axis=(1, 2))
    counts = (upper & np.isfinite(z)).sum(axis=(1, 2))
    with np.errstate(invalid="ignore"):
        return np.where(counts > 0, values / np.maximum(counts, 1), np.nan)


def hand_hypotheses(hand: TemplateHand, columns: np.ndarray) -> list[Hypothesis]:
    """The within-hand hypotheses (module docstring) for the hand whose markers are the scene labels
    ``columns (M,)`` in the template's order."""
    where = {(digit, segment): index for index, (digit, segment) in enumerate(zip(hand.digits, hand.segments,
                                                                                  strict=True))}
    identity = np.asarray(columns, dtype=np.int64)
    hypotheses = []
    fingers = [digit for digit in ("index", "middle", "ring", "little") if any(d == digit for d in hand.digits)]
    for shift in range(1, len(fingers)):
        permutation = identity.copy()
        for number, digit in enumerate(fingers):
            target = fingers[(number + shift) % len(fingers)]
            for (d, segment), index in where.items():
                if d == digit and (target, segment) in where:
                    permutation[index] = identity[where[(target, segment)]]
        if len(set(permutation.tolist())) == len(permutation) and (permutation != identity).any():
            hypotheses.append(Hypothesis(f"fingers cycled by {shift}", permutation))
    for digit in ("thumb", "index", "middle", "ring", "little"):
        if (digit, 3) in where and (digit, 2) in where:
            permutation = identity.copy()
            tip, middle = where[(digit, 3)], where[(digit, 2)]
            permutation[tip], permutation[middle] = identity[middle], identity[tip]
            hypotheses.append(Hypothesis(f"{digit} tip and middle exchanged", permutation))
    return hypotheses


def _side_partner(template: LabTemplate) -> dict[str, str] | None:
    """Each hand marker's name on the other hand (by the name without its side token), or None when the two
    hands' names do not correspond one to one."""
    if len(template.sides) < 2:
        return None
    stripped = {side: {name_side(name)[1].lower(): name for name in template.hands[side].names}
                for side in template.sides}
    right, left = stripped["right"], stripped["left"]
    if set(right) != set(left):
        return None
    partner = {right[key]: left[key] for key in right}
    partner.update({left[key]: right[key] for key in left})
    return partner


def check_whole_take(result: SceneLabelling, template: LabTemplate, noise_mm: float | None) -> list[HealthWarning]:
    """Judge every hand of the scene labelling ``result`` against the whole-take hypotheses (module docstring);
    apply a clearly better one to ``result`` in place (its assignment, confidence and residual columns) and
    return the warnings: what was changed, and the doubts left."""
    names = list(result.marker_names)
    index_of = {name: index for index, name in enumerate(names)}
    positions = result.labelled_positions()
    frames = len(positions)
    sampled = np.linspace(0, frames - 1, min(frames, SAMPLED_FRAMES)).astype(np.int64) if frames else np.zeros(0, int)
    noise = float(noise_mm or 0.0)
    warnings: list[HealthWarning] = []
    hands = [model for model in result.models if model.kind in template.hands]
    candidates: list[tuple[str, Hypothesis]] = []
    for model in hands:
        hand = template.hands[model.kind]
        if not all(name in index_of for name in hand.names):
            continue
        columns = np.array([index_of[name] for name in hand.names], dtype=np.int64)
        candidates += [(model.kind, hypothesis) for hypothesis in hand_hypotheses(hand, columns)]
    partner = _side_partner(template)
    if partner is not None and all(name in index_of for name in partner):
        permutation = np.arange(len(names))
        for name, other in partner.items():
            permutation[index_of[name]] = index_of[other]
        candidates += [("both", Hypothesis("the two hands exchanged", permutation))]
    for side in [model.kind for model in hands] + (["both"] if partner is not None else []):
        own = [hypothesis for owner, hypothesis in candidates if owner == side]
        if not own:
            continue
        sides = template.sides if side == "both" else [side]
        current = _cost(positions[sampled], template, sides, index_of, noise, np.arange(len(names)))
        costs = [(_cost(positions[sampled], template, sides, index_of, noise,
                        _full(h.permutation, names, index_of, template, side)), h) for h in own]
        if not np.isfinite(current.mean()):
            continue
        best_cost, best = min(costs, key=lambda item: float(np.nanmean(item[0])))
        ratio = float(np.nanmean(best_cost) / max(np.nanmean(current), 1e-12))
        label = "both hands" if side == "both" else f"the {side} hand"
        if ratio < SWITCH_RATIO:
            _apply(result, _full(best.permutation, names, index_of, template, side))
            warnings.append(HealthWarning(
                "whole_take_identity", "" if side == "both" else side, 0, frames - 1,
                f"{label}: relabelled for the whole take ({best.name}): the template's marker distances fit "
                f"{1 / max(ratio, 1e-9):.1f}× better so"))
        elif ratio < DOUBT_RATIO and (share := float(np.nanmean(best_cost < current))) >= DOUBT_SHARE:
            warnings.append(HealthWarning(
                "whole_take_doubt", "" if side == "both" else side, 0, frames - 1,
                f"{label}: the labelling cannot be told from '{best.name}' by the template's distances "
                f"({100 * share:.0f} % of the frames fit that better): check this hand's labels"))
    return warnings


def _full(permutation: np.ndarray, names: list[str], index_of: dict[str, int], template: LabTemplate,
          side: str) -> np.ndarray:
    """A permutation over all the scene's labels from a hand's permutation of its own columns (or, for
    ``side == "both"``, one already over all labels)."""
    if side == "both":
        return permutation
    full = np.arange(len(names))
    columns = np.array([index_of[name] for name in template.hands[side].names], dtype=np.int64)
    full[columns] = permutation
    return full


def _cost(positions: np.ndarray, template: LabTemplate, sides: list[str], index_of: dict[str, int],
          noise_mm: float, permutation: np.ndarray) -> np.ndarray:
    """Per sampled frame, the summed statistics cost of the template hands ``sides`` when each label's points
    are read as those of ``permutation``'s label."""
    total = np.zeros(len(positions))
    for side in sides:
        hand = template.hands[side]
        if not all(name in index_of for name in hand.names):
            continue
        columns = np.array([index_of[name] for name in hand.names], dtype=np.int64)
        relabelled = positions[:, np.argsort(permutation)[columns]]
        total += np.nan_to_num(statistics_cost(relabelled, hand.statistics, noise_mm), nan=0.0)
    return total


def _apply(result: SceneLabelling, permutation: np.ndarray) -> None:
    """Move every label's column of ``result``'s per-label arrays to ``permutation``'s label, in place."""
    inverse = np.argsort(permutation)
    for attribute in ("assignment", "confidence", "residuals_mm"):
        values = getattr(result, attribute)
        setattr(result, attribute, values[:, inverse].copy())
