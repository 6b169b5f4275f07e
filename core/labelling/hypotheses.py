"""Whole-take identity of a hand labelled with a lab template: is the labelling right for the whole take?

A labelling can be wrong for a whole take and still fit the hand model well (the fingers of a fretting hand
cycled by one, a tip exchanged with its middle marker): the IK residual cannot see it, the template's
distance statistics can. For each hand, the labelling is compared with the whole-take hypotheses

- the four fingers' labels cycled by one, two or three fingers (marker for marker by segment),
- one digit's tip and middle labels exchanged, or those of every finger (tips hidden in a grasp from the
  start can leave each tip's label on its middle marker),
- the two hands' labels exchanged (a template with both hands whose names correspond),

by the template's distance statistics. Within a hand only the points that change label are judged, against
the hand's labels that do not change (:func:`anchored_costs`: the negative log-likelihood of each distance under
the learned normal, so that a widely spread label such as a fingertip cannot take any point cheaply); the hands
exchanged are judged on every within-hand pair (:func:`statistics_cost`). A hypothesis clearly better
(:data:`CLEAR_GAIN`), or better and so in most frames (:data:`CONSISTENT_SHARE`), replaces the labelling for the
whole take (again while one does, :data:`ROUNDS`); one nearly as good (:data:`DOUBT_GAIN`) and better in a fair
share of the frames (:data:`DOUBT_SHARE`) is reported as a doubt on that hand, with that share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.labelling.health_warning import HealthWarning
from handmocap.core.labelling.result import SceneLabelling
from handmocap.core.model.hand_columns import name_side
from handmocap.core.model.lab_template import LabTemplate, PairStatistics, TemplateHand

#: a hypothesis whose cost per pair is this much below the labelling's (squared standard deviations: every
#: distance two sigmas better on average) replaces it
CLEAR_GAIN = 4.0
#: ... and so does one that costs less and fits better in most of the frames where it differs (a paired
#: comparison over the take: a true ambiguity fits better in about half of them)
CONSISTENT_SHARE = 0.75
#: rounds of hypotheses per hand
ROUNDS = 4
#: a hypothesis that costs at most this much more per pair than the labelling is a doubt worth saying ...
DOUBT_GAIN = 0.5
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
    every = identity.copy()
    for digit in ("thumb", "index", "middle", "ring", "little"):
        if (digit, 3) in where and (digit, 2) in where:
            permutation = identity.copy()
            tip, middle = where[(digit, 3)], where[(digit, 2)]
            permutation[tip], permutation[middle] = identity[middle], identity[tip]
            if digit != "thumb":
                every[tip], every[middle] = identity[middle], identity[tip]
            hypotheses.append(Hypothesis(f"{digit} tip and middle exchanged", permutation))
    if sum(h.name.endswith("tip and middle exchanged") and not h.name.startswith("thumb") for h in hypotheses) > 1:
        hypotheses.append(Hypothesis("every finger's tip and middle exchanged", every))
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
    apply a clearly better one to ``result`` in place (its assignment, confidence and residual columns), again
    while one is (up to :data:`ROUNDS` per hand: a fault on several fingers is undone a finger at a time when no
    single hypothesis covers it), and return the warnings: what was changed, and the doubts left."""
    names = list(result.marker_names)
    index_of = {name: index for index, name in enumerate(names)}
    frames = len(result.assignment)
    sampled = np.linspace(0, frames - 1, min(frames, SAMPLED_FRAMES)).astype(np.int64) if frames else np.zeros(0, int)
    noise = float(noise_mm or 0.0)
    warnings: list[HealthWarning] = []
    candidates = _candidates(result, template, index_of)
    for side in dict.fromkeys(owner for owner, _ in candidates):
        own = [hypothesis for owner, hypothesis in candidates if owner == side]
        sides = template.sides if side == "both" else [side]
        label = "both hands" if side == "both" else f"the {side} hand"
        applied: list[str] = []
        for _ in range(ROUNDS):
            positions = result.labelled_positions()[sampled]
            if not len(positions):
                break
            judged = [(*_judge(positions, template, sides, index_of, noise,
                               _full(h.permutation, names, index_of, template, side), side), h) for h in own]
            judged = [item for item in judged if np.isfinite(item[0])]
            if not judged:
                break
            gain, share, best = min(judged, key=lambda item: item[0])
            if gain <= -CLEAR_GAIN or (gain < 0 and share >= CONSISTENT_SHARE):
                _apply(result, _full(best.permutation, names, index_of, template, side))
                applied.append(f"{best.name} ({100 * share:.0f} % of the frames fit it better)")
                continue
            if gain < DOUBT_GAIN and share >= DOUBT_SHARE:
                warnings.append(HealthWarning(
                    "whole_take_doubt", "" if side == "both" else side, 0, frames - 1,
                    f"{label}: the labelling cannot be told from '{best.name}' by the template's distances "
                    f"({100 * share:.0f} % of the frames fit that better): check this hand's labels"))
            break
        if applied:
            warnings.append(HealthWarning(
                "whole_take_identity", "" if side == "both" else side, 0, frames - 1,
                f"{label}: relabelled for the whole take, as the template's marker distances say: "
                f"{'; '.join(applied)}"))
    return warnings


def _candidates(result: SceneLabelling, template: LabTemplate, index_of: dict[str, int]
                ) -> list[tuple[str, Hypothesis]]:
    """The hypotheses of each template hand of ``result`` (by side), then the hands exchanged (``"both"``)."""
    candidates: list[tuple[str, Hypothesis]] = []
    for model in result.models:
        if model.kind not in template.hands:
            continue
        hand = template.hands[model.kind]
        if not all(name in index_of for name in hand.names):
            continue
        columns = np.array([index_of[name] for name in hand.names], dtype=np.int64)
        candidates += [(model.kind, hypothesis) for hypothesis in hand_hypotheses(hand, columns)]
    partner = _side_partner(template)
    if partner is not None and all(name in index_of for name in partner):
        permutation = np.arange(len(index_of))
        for name, other in partner.items():
            permutation[index_of[name]] = index_of[other]
        candidates.append(("both", Hypothesis("the two hands exchanged", permutation)))
    return candidates


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


def _judge(positions: np.ndarray, template: LabTemplate, sides: list[str], index_of: dict[str, int],
           noise_mm: float, permutation: np.ndarray, side: str) -> tuple[float, float]:
    """How a hypothesis compares with the labelling: its mean cost per pair minus the labelling's over the
    sampled frames (negative: it fits better) and the share of the frames where they differ in which it costs
    less (NaN gain when nothing compares).

    Within one hand only the points that change label are judged, each against the hand's labels that do not
    change (the anchors), as its label now and as its label under the hypothesis: both sides of the comparison
    have the same terms (:func:`anchored_costs`). The hands exchanged are judged on all within-hand pairs."""
    if side == "both":
        current = _cost(positions, template, sides, index_of, noise_mm, np.arange(len(permutation)))
        hypothesis = _cost(positions, template, sides, index_of, noise_mm, permutation)
    else:
        hand = template.hands[side]
        columns = np.array([index_of[name] for name in hand.names], dtype=np.int64)
        local = np.searchsorted(columns[np.argsort(columns)], permutation[columns])
        local = np.argsort(columns)[local]
        current, hypothesis = anchored_costs(positions[:, columns], hand.statistics, noise_mm, local)
    valid = np.isfinite(current) & np.isfinite(hypothesis)
    if not valid.any():
        return float("nan"), 0.0
    current, hypothesis = current[valid], hypothesis[valid]
    differs = hypothesis != current
    share = float(np.mean(hypothesis[differs] < current[differs])) if differs.any() else 0.0
    return float(hypothesis.mean() - current.mean()), share


def anchored_costs(positions: np.ndarray, statistics: PairStatistics, noise_mm: float,
                   permutation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame ``(F,)``, for the hand's labels ``positions (F,M,3)`` mm (the statistics' order) and a
    within-hand ``permutation (M,)`` (label i's points go to label permutation[i]): the mean negative
    log-likelihood (squared standardised deviation, clipped at :data:`Z_CLIP`, plus twice the log spread) of
    the distances from each moved point to each anchor (an unmoved label with a point), reading the point as
    its label now and as its label under the hypothesis. NaN in a frame with no such pair."""
    moved = np.flatnonzero(permutation != np.arange(len(permutation)))
    anchors = np.flatnonzero(permutation == np.arange(len(permutation)))
    if not len(moved) or not len(anchors):
        nothing = np.full(len(positions), np.nan)
        return nothing, nothing
    distances = np.linalg.norm(positions[:, moved, None] - positions[:, None, anchors], axis=3)   # (F,S,A)
    spread = np.maximum(statistics.sd_mm, max(SPREAD_FLOOR_MM, 2.0 * noise_mm))

    def cost(labels: np.ndarray) -> np.ndarray:
        # the negative log-likelihood of a normal distance (up to a constant): a label whose distances spread
        # widely (a fingertip) must not fit any point cheaply
        pair_spread = spread[np.ix_(labels, anchors)]
        z = np.minimum(((distances - statistics.mean_mm[np.ix_(labels, anchors)]) / pair_spread) ** 2, Z_CLIP ** 2)
        z = z + 2.0 * np.log(pair_spread)
        valid = np.isfinite(z)
        with np.errstate(invalid="ignore"):
            return np.where(valid.any(axis=(1, 2)), np.where(valid, z, 0.0).sum(axis=(1, 2)) /
                            np.maximum(valid.sum(axis=(1, 2)), 1), np.nan)

    return cost(moved), cost(permutation[moved])


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
