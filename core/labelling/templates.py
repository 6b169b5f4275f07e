"""Learn a lab's labelling template from takes the lab labelled (QTM's AIM training, Nexus's labelling
skeleton calibration): :func:`learn_template`. The template's file format is :mod:`core.model.lab_template`.

Steps:

1. The labelled columns of every take (:func:`core.io.is_marker_label`) are pooled by name.
2. Hands: markers whose names carry a side token (``R_``, ``L-``, ``Right:``, ``_L`` …, see
   :func:`name_side`) form that side's hand. Markers without one are split into rigid objects (groups of
   at least 3 whose pairwise distances stay constant to within the noise, see :func:`rigid_groups`) and,
   when at least :data:`MIN_HAND_MARKERS` remain, one hand whose side is the one its fitted placement
   reaches better.
3. Where each marker of a hand sits (:func:`place_hand`): the palm is the group of markers rigid with each
   other that lies farthest from the rest; the other markers form digit chains (by name stem, e.g.
   ``A1 A2 A3``, else by rigidity); the thumb is the chain farthest from the others, the fingers follow
   by adjacency; inside a chain the marker nearest the palm sits on the most proximal segment. That first
   guess is placed on the template (palm markers carried into the rest pose through the wrist of an IK of
   the finger markers) and refined with :func:`core.calibration.marker_placement.fit_marker_placement`,
   per side.
4. Statistics: the mean and standard deviation of every within-hand marker distance over the takes.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from handmocap.core.calibration.marker_placement import fit_marker_placement, rest_positions_of_targets
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik import IKSettings, solve_positions
from handmocap.core.io import Take, is_marker_label
from handmocap.core.labelling.take_statistics import measure_take
from handmocap.core.model import HandModel, MarkerLayout, MarkerSpec, load_template, resolve_layout
from handmocap.core.model.hand_columns import name_side  # re-exported: the side a marker name says
from handmocap.core.model.lab_template import LabTemplate, PairStatistics, TemplateHand
from handmocap.core.model.markers import SIDE_DIRECTIONS
from handmocap.core.model.objects import ObjectSpec, rigid_body_from_points
from handmocap.core.model.skeleton import DIGITS, JOINT_NAMES

#: fewest markers a hand needs to be placed (the wrist pose needs 3; a digit chain more)
MIN_HAND_MARKERS = 5
#: frames sampled per take for the placement fit (IK cost) and for the distance statistics (all frames)
PLACEMENT_FRAMES = 300

_STEM = re.compile(r"^(.*?)[-_ ]?(\d+)$")
_PALM_WORDS = ("wrist", "wan", "hand", "back", "palm", "carp", "top", "radi", "ulna", "styl", "wr", "mc", "knuckle",
               "arm")


_PAIRED = re.compile(r"^([LR])([A-Z0-9].*)$")


def paired_sides(names: Sequence[str]) -> dict[int, str]:
    """The side of the names that carry it as a bare leading ``L``/``R`` (Plug-in Gait's ``LASI``, ART's
    ``Human4:LIFT``): only where the same name with the other letter is there too. {index: side}."""
    stripped = [name_side(name)[1] if name_side(name)[0] is None else "" for name in names]
    present = set(stripped)
    sides = {}
    for index, name in enumerate(stripped):
        match = _PAIRED.match(name)
        if match and ("R" if match.group(1) == "L" else "L") + match.group(2) in present:
            sides[index] = "left" if match.group(1) == "L" else "right"
    return sides


#: markers of one hand lie within this many times the hand's typical nearest-neighbour distance of another
HAND_LINK_RATIO = 4.0


def hand_component(indices: list[int], mean: np.ndarray) -> tuple[list[int], list[int]]:
    """Of a side's markers ``indices``, those of the hand and those set aside: the largest single-linkage
    component of their mean distances (``mean (M,M)`` mm) cut at :data:`HAND_LINK_RATIO` × the median
    nearest-neighbour distance (a body model's shoulder, arm and leg markers stand far from the hand's)."""
    if len(indices) < MIN_HAND_MARKERS:
        return indices, []
    block = np.nan_to_num(mean[np.ix_(indices, indices)], nan=np.inf)
    np.fill_diagonal(block, np.inf)
    cut = HAND_LINK_RATIO * float(np.median(block.min(axis=1)))
    from scipy.sparse.csgraph import connected_components

    _, labels = connected_components(block <= cut, directed=False)
    largest = np.bincount(labels).argmax()
    keep = [index for index, label in zip(indices, labels, strict=True) if label == largest]
    return keep, [index for index in indices if index not in keep]


@dataclass
class PooledTakes:
    """The labelled markers of the learning takes: ``names (M,)`` and ``positions (F,M,3)`` mm, the frames of
    all takes one after the other (NaN where a take lacks a marker); ``take_starts`` the first frame of each
    take (distances are never taken across a take boundary; they are not in any case)."""

    names: list[str]
    positions: np.ndarray
    take_starts: list[int] = field(default_factory=list)


def pool_takes(takes: Sequence[Take]) -> PooledTakes:
    """Pool the labelled columns of ``takes`` by name. :class:`InputError` when a take has no labels."""
    names: list[str] = []
    for take in takes:
        labelled = [name for name in take.marker_names if is_marker_label(name)]
        if not labelled:
            source = take.source_path or "a take"
            raise InputError(f"{source}: no labelled markers (its points are unlabelled); a template is learned "
                             "from takes the lab labelled")
        names += [name for name in labelled if name not in names]
    lowered = [name.lower() for name in names]
    clash = next((name for index, name in enumerate(lowered) if name in lowered[:index]), None)
    if clash is not None:
        raise InputError(f"two markers are named '{clash}' but for upper and lower case; names must differ")
    blocks, starts, start = [], [], 0
    for take in takes:
        column = {name: index for index, name in enumerate(take.marker_names)}
        block = np.full((take.n_frames, len(names), 3), np.nan)
        for index, name in enumerate(names):
            if name in column:
                block[:, index] = take.marker_positions[:, column[name]]
        blocks.append(block)
        starts.append(start)
        start += take.n_frames
    return PooledTakes(names, np.concatenate(blocks), starts)


def distance_statistics(positions: np.ndarray, chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation ``(M,M)`` mm of every pair's distance over frames of ``positions
    (F,M,3)`` (NaN where a pair is never seen together), accumulated in chunks of frames."""
    count = positions.shape[1]
    total, squares, seen = np.zeros((count, count)), np.zeros((count, count)), np.zeros((count, count))
    for start in range(0, len(positions), chunk):
        block = positions[start:start + chunk]
        distances = np.linalg.norm(block[:, :, None] - block[:, None], axis=3)
        valid = np.isfinite(distances)
        values = np.where(valid, distances, 0.0)
        total += values.sum(axis=0)
        squares += (values ** 2).sum(axis=0)
        seen += valid.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(seen > 0, total / np.maximum(seen, 1), np.nan)
        variance = np.where(seen > 1, squares / np.maximum(seen, 1) - mean ** 2, np.nan)
    return mean, np.sqrt(np.maximum(variance, 0.0))


def rigid_tolerance(noise_mm: float, mean_mm: np.ndarray) -> np.ndarray:
    """Largest distance spread (mm) of a pair on one rigid body: three times the spread noise alone gives a
    distance (σ√2 per axis pair), or 0.5 % of the distance (calibration scale error), whichever is more."""
    return np.maximum(3.0 * np.sqrt(2.0) * noise_mm, 0.005 * mean_mm)


def rigid_groups(indices: list[int], mean: np.ndarray, sd: np.ndarray, noise_mm: float) -> list[list[int]]:
    """Groups of at least 3 of ``indices`` whose every pair stays rigid (:func:`rigid_tolerance`), greedily
    from the most rigid pair; each marker in one group at most."""
    rigid = sd <= rigid_tolerance(noise_mm, mean)
    left = list(indices)
    groups = []
    while len(left) >= 3:
        pairs = [(sd[a, b], a, b) for i, a in enumerate(left) for b in left[i + 1:] if rigid[a, b]]
        if not pairs:
            break
        grown = None
        for _, a, b in sorted(pairs):
            group = [a, b]
            for other in left:
                if other not in group and all(rigid[other, member] for member in group):
                    group.append(other)
            if len(group) >= 3:
                grown = group
                break
        if grown is None:
            break
        groups.append(sorted(grown))
        left = [index for index in left if index not in grown]
    return groups


@dataclass
class HandPlacement:
    """Where the markers of one hand were found to sit: per marker its ``digits`` (a :data:`DIGITS` name or
    ``palm``) and ``segments`` (1 proximal … 3 distal; 0 on the palm)."""

    digits: list[str]
    segments: list[int]


def place_hand(names: list[str], mean: np.ndarray, sd: np.ndarray, noise_mm: float) -> HandPlacement:
    """Palm, digit chains and segments of a hand's markers ``names`` from the distance ``mean``/``sd`` ``(M,M)``
    mm over the take (module docstring, step 3). :class:`InputError` when a hand has too few markers."""
    count = len(names)
    if count < MIN_HAND_MARKERS:
        raise InputError(f"the hand of markers {', '.join(names)} has {count} markers; at least "
                         f"{MIN_HAND_MARKERS} are needed to place them on a hand")
    palm = _palm(names, mean, sd, noise_mm)
    fingers = [index for index in range(count) if index not in palm]
    chains = _chains(names, fingers, mean, sd, _palm_followers(fingers, palm, sd))
    palm = sorted(set(palm) | (set(fingers) - {index for chain in chains for index in chain}))
    said = [{name_digit(names[index]) for index in chain} for chain in chains]
    named_order = [next(iter(digits)) for digits in said if len(digits) == 1]
    if len(named_order) == len(chains) and None not in named_order and len(set(named_order)) == len(chains):
        order = [str(digit) for digit in named_order]
    else:
        order = _digit_order(chains, mean)
    digits, segments = ["palm"] * count, [0] * count
    for digit, ordered in zip(order, _ordered_chains(names, chains, palm, mean, sd), strict=True):
        said_segments = [name_segment(names[index]) for index in ordered]
        if None not in said_segments and len(set(said_segments)) == len(ordered):
            chain_segments = [int(segment) for segment in said_segments if segment is not None]
        else:
            chain_segments = [max(1, 3 - len(ordered) + 1 + offset) for offset in range(len(ordered))]
        for index, segment in zip(ordered, chain_segments, strict=True):
            digits[index] = digit
            segments[index] = segment
    return HandPlacement(digits, segments)


#: words that name a segment of a digit in a marker name
_SEGMENT_WORDS = {"tip": 3, "distal": 3, "nail": 3, "dip": 3, "middle": 2, "mid": 2, "pip": 2, "intermediate": 2,
                  "proximal": 1, "prox": 1, "base": 1, "mcp": 1, "metacarpal": 1, "knuckle": 1}


def name_segment(name: str) -> int | None:
    """The segment a marker name says by a segment word after its digit word (``index_middle`` → 2,
    ``thumb_tip`` → 3), or None."""
    tokens = [token.lower() for token in _TOKENS.findall(name_side(name)[1])]
    digit_at = next((number for number, token in enumerate(tokens) if token in _DIGIT_WORDS), -1)
    return next((_SEGMENT_WORDS[token] for token in tokens[digit_at + 1:] if token in _SEGMENT_WORDS), None)


def _ordered_chains(names: list[str], chains: list[list[int]], palm: list[int], mean: np.ndarray,
                    sd: np.ndarray) -> list[list[int]]:
    """Each digit chain from proximal to distal (:func:`_proximal_to_distal`). When every chain's names are
    numbered (``B1 B2 B3``), the lab's numbering runs the same way on every digit: the way most chains'
    geometry says (weighted by how clearly it says it) orders them all by number."""
    ordered = [_proximal_to_distal(chain, palm, mean, sd) for chain in chains]
    numbers = [[_number(names[index]) for index in chain] for chain in ordered]
    if not ordered or any(None in chain_numbers or len(set(chain_numbers)) != len(chain_numbers)
                          for chain_numbers in numbers if len(chain_numbers) > 1):
        return ordered
    vote = 0.0
    for chain, chain_numbers in zip(ordered, numbers, strict=True):
        if len(chain) < 2:
            continue
        first, last = chain[0], chain[-1]
        spread_first, spread_last = float(np.nanmean(sd[first, palm])), float(np.nanmean(sd[last, palm]))
        clarity = abs(spread_last - spread_first) / max(spread_last + spread_first, 1e-9)
        rising = (chain_numbers[-1] or 0) > (chain_numbers[0] or 0)
        vote += clarity * (1.0 if rising else -1.0)
    descending = vote < 0  # the numbers fall towards the tip (1 on the nail)
    return [sorted(chain, key=lambda index: _number(names[index]) or 0, reverse=descending) for chain in ordered]


def _number(name: str) -> int | None:
    match = _STEM.match(name_side(name)[1])
    return int(match.group(2)) if match else None


def _palm(names: list[str], mean: np.ndarray, sd: np.ndarray, noise_mm: float) -> list[int]:
    """The palm markers: at least 3 markers named like a wrist or the back of the hand (``wrist``, ``Wan``,
    ``hand_top``, ``MC2`` …) when there are, else the rigid group farthest from the other markers, with every
    marker as rigid with it as its own members are. (Motion alone cannot tell a thumb held still against the
    palm from the palm, so names come first.)"""
    indices = list(range(len(names)))
    named = [index for index, name in enumerate(names) if name_digit(name) != "thumb"
             and any(word in _stem(name_side(name)[1]).lower() for word in _PALM_WORDS)]
    if 3 <= len(named) < len(names) - 1:
        return named
    groups = rigid_groups(indices, mean, sd, noise_mm)
    if not groups:
        spread = np.nanmean(sd, axis=1)
        groups = [[int(index) for index in np.argsort(spread)[:3]]]

    def remoteness(group: list[int]) -> float:
        others = [index for index in indices if index not in group]
        return float(np.nanmean(mean[np.ix_(group, others)])) if others else 0.0

    palm = max(groups, key=remoteness)
    within = max(float(np.nanmax(sd[np.ix_(palm, palm)])), 1e-6)
    for index in indices:
        if index not in palm and np.nanmax(sd[index, palm]) <= within and len(palm) < len(names) - 1:
            palm.append(index)
    return sorted(palm)


def _proximal_to_distal(chain: list[int], palm: list[int], mean: np.ndarray, sd: np.ndarray) -> list[int]:
    """A digit chain's markers from proximal to distal. Its ends are the two markers farthest apart; the
    proximal end is the one whose distances to the palm markers vary least over the take (more joints lie
    between the palm and a distal marker; a flexed finger can bring its nail nearer the wrist than its middle,
    so nearness does not tell); the others follow by their distance from it."""
    if len(chain) <= 1:
        return list(chain)
    block = mean[np.ix_(chain, chain)]
    first, last = np.unravel_index(np.nanargmax(block), block.shape)
    ends = [chain[int(first)], chain[int(last)]]
    proximal = min(ends, key=lambda index: float(np.nanmean(sd[index, palm])))
    return sorted(chain, key=lambda index: float(mean[proximal, index]) if index != proximal else -1.0)


def _palm_followers(fingers: list[int], palm: list[int], sd: np.ndarray) -> list[int]:
    """The ``fingers`` markers whose distances to some palm marker vary less than to any other non-palm marker:
    they move with the palm (a marker on the middle of the hand)."""
    followers = []
    for index in fingers:
        others = [other for other in fingers if other != index]
        if others and np.nanmin(sd[index, palm]) < np.nanmin(sd[index, others]):
            followers.append(index)
    return followers


def _prefix(name: str, cut: int) -> str:
    """``name`` without its last ``cut`` characters (ART's ``IFM IFO IFT`` share ``I``… of the index finger)."""
    return name[:-cut] if len(name) > cut else name


def _stem(name: str) -> str:
    match = _STEM.match(name)
    return match.group(1) if match else name


#: words that name a digit in a marker name (its first such token decides): thumb, index, middle, ring, little
_DIGIT_WORDS = {"thumb": "thumb", "th": "thumb", "pollex": "thumb", "index": "index", "ind": "index",
                "if": "index", "pointer": "index", "middle": "middle", "mid": "middle", "mf": "middle",
                "ring": "ring", "rf": "ring", "little": "little", "pinky": "little", "pinkie": "little",
                "small": "little", "lf": "little"}
_TOKENS = re.compile(r"[A-Za-z]+")


def name_digit(name: str) -> str | None:
    """The digit a marker name says by its first digit word (``index_middle`` → index, ``RTHUMB2`` is not
    split), or None."""
    for token in _TOKENS.findall(name_side(name)[1]):
        digit = _DIGIT_WORDS.get(token.lower())
        if digit is not None:
            return digit
    return None


def _chains(names: list[str], fingers: list[int], mean: np.ndarray, sd: np.ndarray,
            followers: Sequence[int] = ()) -> list[list[int]]:
    """The digit chains among the ``fingers`` markers: by the digit their names say (:func:`name_digit`) when
    every one says one; by name stem (``B1 B2 B3``) or name prefix (ART's ``IFM IFO IFT``) when that splits them
    into 2 to 5 groups of at most 4 (a marker alone under its name that moves with the palm, one of
    ``followers``, is then no chain: ART's hand centre ``HAN``); else by average-linkage clustering of the
    distance spreads into 5 (or fewer)."""
    said = [name_digit(names[index]) for index in fingers]
    if fingers and all(said):
        by_digit: dict[str, list[int]] = {}
        for index, digit in zip(fingers, said, strict=True):
            by_digit.setdefault(str(digit), []).append(index)
        if all(len(group) <= 4 for group in by_digit.values()):
            return list(by_digit.values())
    keys: list[Callable[[str], str]] = [_stem, partial(_prefix, cut=1), partial(_prefix, cut=2)]
    for key in keys:
        by_key: dict[str, list[int]] = {}
        for index in fingers:
            by_key.setdefault(key(name_side(names[index])[1]).lower(), []).append(index)
        groups = [group for group in by_key.values() if len(group) > 1 or group[0] not in followers]
        if 2 <= len(groups) <= 5 and all(len(group) <= 4 for group in groups):
            return groups
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    if len(fingers) <= 1:
        return [fingers] if fingers else []
    spread = np.nan_to_num(sd[np.ix_(fingers, fingers)], nan=float(np.nanmax(sd)))
    spread = 0.5 * (spread + spread.T)
    np.fill_diagonal(spread, 0.0)
    clusters = fcluster(linkage(squareform(spread, checks=False), "average"), t=min(5, len(fingers)),
                        criterion="maxclust")
    return [[fingers[i] for i in np.flatnonzero(clusters == label)] for label in np.unique(clusters)]


def _digit_order(chains: list[list[int]], mean: np.ndarray) -> list[str]:
    """The digit of each chain: the thumb is the chain farthest from the others (by the mean distance of
    their markers), then the fingers by adjacency, starting next to the thumb."""
    if not chains:
        return []
    if len(chains) > 5:
        raise InputError(f"the hand's markers form {len(chains)} digit chains; a hand has 5")
    separation = np.array([[float(np.nanmean(mean[np.ix_(a, b)])) for b in chains] for a in chains])
    np.fill_diagonal(separation, np.nan)
    if len(chains) == 1:
        return ["index"]
    thumb = int(np.nanargmax(np.nanmean(separation, axis=1)))
    order = [thumb]
    while len(order) < len(chains):
        last = order[-1]
        candidates = [index for index in range(len(chains)) if index not in order]
        order.append(min(candidates, key=lambda index: separation[last, index]))
    digits = [""] * len(chains)
    names = DIGITS if len(chains) == 5 else DIGITS[:1] + DIGITS[1:len(chains)]
    for digit, chain in zip(names, order, strict=True):
        digits[chain] = digit
    return digits


def first_guess(names: list[str], placement: HandPlacement) -> MarkerLayout:
    """A layout of the hand's markers on the segments found (palm markers on the back of the hand; their
    place is fitted by :func:`place_palm`)."""
    specs = []
    for name, digit, segment in zip(names, placement.digits, placement.segments, strict=True):
        if digit == "palm":
            specs.append(MarkerSpec(name, ("wrist", "middle_mcp"), 0.5, "dorsal", None, 5.0))
            continue
        joints = (("cmc", "mcp", "ip", "tip") if digit == "thumb" else ("mcp", "pip", "dip", "tip"))
        first, second = joints[segment - 1], joints[segment]
        specs.append(MarkerSpec(name, (f"{digit}_{first}", f"{digit}_{second}"), 0.6 if second == "tip" else 0.5,
                                "dorsal", None, 5.0))
    return MarkerLayout("first guess", tuple(specs))


def place_palm(targets: np.ndarray, model: HandModel, layout: MarkerLayout, placement: HandPlacement) -> MarkerLayout:
    """Put the palm markers where the take shows them: IK of the digit markers alone on ``targets (F,M,3)``
    mm, then each palm marker carried into the rest pose through the wrist (median over frames) and written
    between the wrist and the nearest knuckle."""
    palm = [index for index, digit in enumerate(placement.digits) if digit == "palm"]
    digits_only = targets.copy()
    digits_only[:, palm] = np.nan
    if len(palm) == len(placement.digits) or not palm:
        return layout
    markers = resolve_layout(model, layout)
    result = solve_positions(digits_only, model, markers, settings=IKSettings(method="layered"))
    knuckle_joints = {digit: f"{digit}_{'cmc' if digit == 'thumb' else 'mcp'}" for digit in DIGITS}
    knuckles = {digit: model.skeleton.rest_positions[JOINT_NAMES.index(joint)]
                for digit, joint in knuckle_joints.items()}
    wrist = model.skeleton.rest_positions[0]
    specs = list(layout.markers)
    for index in palm:
        rest = rest_positions_of_targets(model, result.joint_angles, targets[:, index], 0)
        if len(rest) < 5:
            continue
        point = np.median(rest, axis=0)
        digit = min(DIGITS[1:], key=lambda name: np.linalg.norm(point - knuckles[name]))
        knuckle = knuckles[digit]
        axis = knuckle - wrist
        along = float(np.clip((point - wrist) @ axis / (axis @ axis), -0.6, 1.2))
        frame = model.skeleton.rest_rotations[JOINT_NAMES.index("middle_mcp")]
        local = frame.T @ (point - (wrist + along * axis))
        if model.side == "left":
            local[0] = -local[0]
        norm = float(np.linalg.norm(local))
        side = tuple(round(float(v), 3) for v in local / norm) if norm > 1e-6 else SIDE_DIRECTIONS["dorsal"]
        specs[index] = MarkerSpec(specs[index].name, ("wrist", f"{digit}_mcp"), round(along, 3),
                                  (float(side[0]), float(side[1]), float(side[2])), None, 5.0)
    return MarkerLayout(layout.name, tuple(specs), layout.description)


@dataclass
class LearnedHand:
    """One hand as learned: its template entry and the mean IK residual (mm) of the fitted placement."""

    hand: TemplateHand
    residual_mm: float


def learn_hand(names: list[str], positions: np.ndarray, side: str, noise_mm: float,
               cancelled: Callable[[], bool] | None = None) -> LearnedHand:
    """Place the markers ``names`` of one hand (``positions (F,M,3)`` mm) on the ``side`` template and fit
    their placement; their pair statistics come with it."""
    mean, sd = distance_statistics(positions)
    placement = place_hand(names, mean, sd, noise_mm)
    model = load_template(side)
    frames = np.flatnonzero(np.isfinite(positions).all(axis=2).sum(axis=1) >= 3)
    if len(frames) == 0:
        raise InputError(f"the {side} hand ({', '.join(names[:4])}…) is never seen with 3 markers")
    sampled = positions[frames[np.linspace(0, len(frames) - 1, min(PLACEMENT_FRAMES, len(frames))).astype(int)]]
    layout = place_palm(sampled, model, first_guess(names, placement), placement)
    if cancelled is not None and cancelled():
        raise CancelledError("template learning cancelled; nothing was written")
    fitted, residuals = fit_marker_placement(sampled, names, model, layout, iterations=4, cancelled=cancelled)
    statistics = PairStatistics(tuple(names), mean, sd)
    hand = TemplateHand(side, MarkerLayout(f"{side} hand", fitted.markers), tuple(placement.digits),
                        tuple(placement.segments), statistics)
    return LearnedHand(hand, float(min(residuals)))


@dataclass
class LearnedTemplate:
    """The result of :func:`learn_template`: the ``template`` and a JSON-ready ``report`` (per hand: markers,
    digits found, placement residual; objects; noise)."""

    template: LabTemplate
    report: dict


def learn_template(takes: Sequence[Take], name: str = "lab", progress: Callable[[float], None] | None = None,
                   cancelled: Callable[[], bool] | None = None) -> LearnedTemplate:
    """Learn a lab's template from labelled ``takes`` (module docstring). :class:`InputError` with one line for
    takes without labels, clashing names, a hand with too few markers to place; :class:`CancelledError`."""
    if not takes:
        raise InputError("give at least one labelled take to learn a template from")
    pooled = pool_takes(takes)
    noise = measure_take(pooled.positions[: min(len(pooled.positions), 20000)])
    noise_mm = float(noise.noise_mm) if noise.measured else 0.5
    mean, sd = distance_statistics(pooled.positions)
    by_side: dict[str, list[int]] = {"right": [], "left": []}
    unsided: list[int] = []
    paired = paired_sides(pooled.names)
    for index, marker in enumerate(pooled.names):
        side = name_side(marker)[0] or paired.get(index)
        (by_side[side] if side else unsided).append(index)
    set_aside: list[int] = []
    for side in by_side:
        by_side[side], away = hand_component(by_side[side], mean)
        set_aside += away
    groups = rigid_groups(unsided, mean, sd, noise_mm)
    grouped = {index for group in groups for index in group}
    rest = [index for index in unsided if index not in grouped]
    objects = [_object(pooled, group, number) for number, group in enumerate(groups)]
    hands: dict[str, LearnedHand] = {}
    sided = [side for side in ("right", "left") if by_side[side]]
    if len(rest) >= MIN_HAND_MARKERS and len(sided) < 2:
        hands.update(_learn_unsided(pooled, rest, noise_mm, sided, cancelled))
    for number, side in enumerate(sided):
        indices = by_side[side]
        if progress is not None:
            progress(number / max(len(sided), 1))
        names = [pooled.names[index] for index in indices]
        hands[side] = learn_hand(names, pooled.positions[:, indices], side, noise_mm, cancelled)
    if not hands:
        raise InputError(f"no hand found among the labelled markers ({', '.join(pooled.names[:8])}…): name them "
                         f"with a side (R_, L-, Right:…) or give at least {MIN_HAND_MARKERS} markers of one hand")
    if progress is not None:
        progress(1.0)
    sources = tuple(str(take.source_path) for take in takes if take.source_path)
    template = LabTemplate(name=name, hands={side: learned.hand for side, learned in hands.items()},
                           objects=tuple(objects), description=f"learned from {len(takes)} labelled take(s)",
                           learned_from=tuple(source.rsplit("/", 1)[-1] for source in sources), noise_mm=noise_mm)
    ignored = [pooled.names[index] for index in rest + set_aside
               if not any(pooled.names[index] in learned.hand.names for learned in hands.values())]
    report = {"hands": {side: {"markers": len(learned.hand.names), "residual_mm": round(learned.residual_mm, 3),
                               "digits": {marker: f"{digit} {segment}" for marker, digit, segment in
                                          zip(learned.hand.names, learned.hand.digits, learned.hand.segments,
                                              strict=True)}}
                        for side, learned in hands.items()},
              "objects": {spec.name: list(spec.marker_names) for spec in objects},
              "ignored_markers": ignored, "noise_mm": round(noise_mm, 3), "frames": int(len(pooled.positions))}
    return LearnedTemplate(template, report)


def _learn_unsided(pooled: PooledTakes, indices: list[int], noise_mm: float, sided: list[str],
                   cancelled: Callable[[], bool] | None) -> dict[str, LearnedHand]:
    """One hand of markers without a side token: the side whose fitted placement reaches them better (the
    side not already taken by named markers)."""
    names = [pooled.names[index] for index in indices]
    positions = pooled.positions[:, indices]
    candidates = [side for side in ("right", "left") if side not in sided]
    learned = [learn_hand(names, positions, side, noise_mm, cancelled) for side in candidates]
    best = min(learned, key=lambda hand: hand.residual_mm)
    return {best.hand.side: best}


def _object(pooled: PooledTakes, group: list[int], number: int) -> ObjectSpec:
    """A rigid object of the markers ``group``: named by their common name stem (else ``object<n>``), with
    their geometry in the frame where all are seen and their spread is median."""
    names = [pooled.names[index] for index in group]
    stems = {_stem(name) for name in names}
    name = stems.pop() if len(stems) == 1 and next(iter({_stem(n) for n in names})) else f"object{number + 1}"
    positions = pooled.positions[:, group]
    complete = np.flatnonzero(np.isfinite(positions).all(axis=(1, 2)))
    if len(complete) == 0:
        raise InputError(f"the rigid markers {', '.join(names)} are never all seen in one frame")
    frame = complete[len(complete) // 2]
    return rigid_body_from_points(name or f"object{number + 1}", names, positions[frame])
