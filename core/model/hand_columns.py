"""Which hands a labelled take holds: per side, the marker layout and the take column of each of its markers.

A take's markers may be named

(a) as ``handmocap label`` writes them: the layout's names for one hand, ``R_<name>`` / ``L_<name>`` for two;
(b) by a lab template (:mod:`core.model.lab_template`): the lab's own names per side (``L-A1``, ``R-Wan-nei``);
(c) by another program with a layout's names and a side token (:func:`name_side`): ``R_``, ``L-``,
    ``Right:``, a Vicon subject ``LeftHand:index_tip``, a suffix ``index_tip_l``; a subject that does not
    say the side (``Subject:index_tip``) is dropped.

:func:`detect_hands` finds them, with the layout given or recognised among the known layouts and templates
(:func:`core.model.layout_names`: the shipped ones and those of the added folders, e.g. a session's
``layouts``). Names are compared without case and surrounding spaces, as :func:`core.model.marker_columns` does.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.model.lab_template import LabTemplate, layout_path, load_lab_template
from handmocap.core.model.markers import MarkerLayout, layout_names, load_layout

SIDES = ("right", "left")
#: a hand is found when at least this share of its layout's markers are among the names ...
MATCH_SHARE = 0.5
#: ... and at least this many (all of them for a smaller layout)
MIN_MATCHES = 3
NO_LAYOUT_MESSAGE = "no layout matches these names: learn one with `handmocap layout learn`"

_SIDE_WORDS = {"r": "right", "l": "left", "right": "right", "left": "left", "rh": "right", "lh": "left",
               "rgt": "right", "lft": "left"}
_PREFIX = re.compile(r"^(right|left|rh|lh|rgt|lft|r|l)(?:hand)?[-_:. ]+(.+)$", re.IGNORECASE)
_SUFFIX = re.compile(r"^(.+?)[-_. ](right|left|rh|lh|r|l)$", re.IGNORECASE)
_SUBJECT = re.compile(r"^([^:]+):(.+)$")


def name_side(name: str) -> tuple[str | None, str]:
    """The hand side a marker name says (``"right"``, ``"left"`` or None) and the name without it:
    ``R_index_tip``, ``L-A1``, ``Right:thumb``, ``LeftHand:IF3``, ``index_tip_l``."""
    stripped = name.strip()
    subject = _SUBJECT.match(stripped)
    if subject:
        side = _subject_side(subject.group(1))
        if side is not None:
            return side, subject.group(2)
        stripped = subject.group(2)
    for pattern, group in ((_PREFIX, 1), (_SUFFIX, 2)):
        match = pattern.match(stripped)
        if match:
            side = _SIDE_WORDS.get(match.group(group).lower())
            if side is not None:
                return side, match.group(3 - group)
    return None, stripped


def _subject_side(subject: str) -> str | None:
    """The side a Vicon subject name says (``LeftHand``, ``hand_R``), or None."""
    words = subject.lower()
    if "left" in words or words.endswith(("_l", "-l", " l", "lh")):
        return "left"
    return "right" if "right" in words or words.endswith(("_r", "-r", " r", "rh")) else None


@dataclass(frozen=True, eq=False)
class HandColumns:
    """One hand of a take: its ``side``, its ``layout`` (the markers of that side; a template's are the lab's
    names), ``layout_name`` (the name or file it was found by, for :func:`hand_layout`), ``columns (M,)`` the
    take column of each layout marker (-1 where the take lacks it) and ``side_from_names`` (False when the
    names do not say the side: it was given, or assumed)."""

    side: str
    layout: MarkerLayout
    layout_name: str
    columns: np.ndarray
    side_from_names: bool = True

    @property
    def present(self) -> np.ndarray:
        """``(M,)`` bool: the layout markers the take has."""
        return self.columns >= 0

    @property
    def labels(self) -> np.ndarray:
        """``(K,)`` the take columns of the markers the take has, in layout order."""
        return self.columns[self.present]

    @property
    def present_layout(self) -> MarkerLayout:
        """The layout of the markers the take has (layout order, the layout's names)."""
        if self.present.all():
            return self.layout
        markers = tuple(spec for spec, here in zip(self.layout.markers, self.present, strict=True) if here)
        return MarkerLayout(self.layout.name, markers, self.layout.description)


def _minimum(count: int) -> int:
    return max(min(MIN_MATCHES, count), math.ceil(MATCH_SHARE * count))


def _keys(name: str) -> set[tuple[str | None, str]]:
    """The ways a take name may name a marker: ``(None, whole name)``, ``(None, name after a subject that says
    no side)`` and ``(side, name without the side token)`` (side None when the name says none)."""
    text = name.strip()
    keys: set[tuple[str | None, str]] = {(None, text.lower())}
    subject = _SUBJECT.match(text)
    if subject and _subject_side(subject.group(1)) is None:
        keys.add((None, subject.group(2).strip().lower()))
    side, bare = name_side(text)
    return keys | {(side, bare.strip().lower())}


def _columns(keys: list[set[tuple[str | None, str]]], layout: MarkerLayout, sides: set[str | None]) -> np.ndarray:
    """Column of each marker of ``layout`` whose key has a side in ``sides`` (-1 none; first column wins)."""
    lookup: dict[str, int] = {}
    for column, column_keys in enumerate(keys):
        for side, bare in column_keys:
            if side in sides:
                lookup.setdefault(bare, column)
    return np.array([lookup.get(name.strip().lower(), -1) for name in layout.names], dtype=np.int64)


def _candidate(layout: str | Path | MarkerLayout | LabTemplate) -> tuple[str, LabTemplate | MarkerLayout]:
    """``(name to store, template or plain layout)`` of a layout given by name, file, or object."""
    if isinstance(layout, LabTemplate | MarkerLayout):
        return layout.name, layout
    template = load_lab_template(layout)
    return str(layout), template if template is not None else load_layout(layout)


def _hands_of(name: str, found: LabTemplate | MarkerLayout, keys: list[set[tuple[str | None, str]]],
              side: str | None) -> list[HandColumns]:
    """The hands of one candidate layout among the take names ``keys`` (module docstring), right first."""
    hands: list[HandColumns] = []
    if isinstance(found, LabTemplate):
        for hand_side in SIDES:
            layout = found.layout_for(hand_side)
            sides: set[str | None] = {hand_side, None} if hand_side in found.hands else {hand_side}
            columns = _columns(keys, layout, sides)
            if (columns >= 0).sum() >= _minimum(len(columns)):
                hands.append(HandColumns(hand_side, layout, name, columns))
        return hands
    for hand_side in SIDES:
        columns = _columns(keys, found, {hand_side})
        if (columns >= 0).sum() >= _minimum(len(columns)):
            hands.append(HandColumns(hand_side, found, name, columns))
    columns = _columns(keys, found, {None})
    taken = {hand.side for hand in hands}
    free = [item for item in ([side] if side else []) + list(SIDES) if item not in taken]
    if free and (columns >= 0).sum() >= _minimum(len(columns)):
        hands.append(HandColumns(free[0], found, name, columns, side_from_names=False))
    hands.sort(key=lambda hand: SIDES.index(hand.side))
    return hands


def detect_hands(marker_names: Sequence[str], layout: str | Path | MarkerLayout | LabTemplate | None = None,
                 side: str | None = None, required: bool = False,
                 candidates: Sequence[str | Path] = ()) -> list[HandColumns]:
    """The hands a take with columns ``marker_names (P,)`` holds (module docstring), right first.

    ``layout``: the layout or template (name, file or object) the take is labelled with; None recognises it
    among ``candidates`` (e.g. a session's layout files) and :func:`core.model.layout_names` (the one matching
    the most names; a template before a plain layout, then the earlier one, on a tie). ``side``: the side of a
    hand whose names do not say it (default: right, or the side the other hand leaves). A hand needs
    :data:`MATCH_SHARE` of its layout's markers, at least :data:`MIN_MATCHES`.
    Nothing found: ``[]``, or with ``required`` an :class:`InputError` of one line.
    """
    if side not in (None, *SIDES):
        raise InputError(f"hand side must be 'right' or 'left', not '{side}'")
    keys = [_keys(str(name)) for name in marker_names]
    if layout is not None:
        name, found = _candidate(layout)
        hands = _hands_of(name, found, keys, side)
        if not hands and required:
            layouts = [found.layout_for(item) for item in found.sides] if isinstance(found, LabTemplate) else [found]
            _refuse(marker_names, name, layouts)
        return hands
    best: tuple[tuple[int, int, int], list[HandColumns]] | None = None
    for number, candidate in enumerate([*candidates, *layout_names()]):
        try:
            name, found = _candidate(candidate)
        except InputError:
            continue  # a damaged layout file in a session folder does not stop the others
        hands = _hands_of(name, found, keys, side)
        if not hands:
            continue
        score = (sum(int(hand.present.sum()) for hand in hands), int(isinstance(found, LabTemplate)), -number)
        if best is None or score > best[0]:
            best = (score, hands)
    if best is None:
        if required:
            raise InputError(NO_LAYOUT_MESSAGE)
        return []
    return best[1]


def _refuse(marker_names: Sequence[str], name: str, layouts: list[MarkerLayout]) -> None:
    """InputError naming how many of the layout's markers the names hold (the best side), and a few missing."""
    keys = [_keys(str(item)) for item in marker_names]
    layout = layouts[0]
    columns = max((_columns(keys, item, {None, *SIDES}) for item in layouts), key=lambda c: int((c >= 0).sum()))
    found = int((columns >= 0).sum())
    missing = [marker for marker, column in zip(layout.names, columns, strict=True) if column < 0]
    more = f" and {len(missing) - 4} more" if len(missing) > 4 else ""
    raise InputError(f"the take has only {found} of the {len(layout.names)} markers of layout '{Path(name).stem}' "
                     f"(missing {', '.join(missing[:4])}{more}): give the layout the take is labelled with")


_LAYOUT_CACHE: dict[tuple[str, int, str], MarkerLayout] = {}


def hand_layout(layout_name: str | Path, side: str) -> MarkerLayout:
    """The layout of the ``side`` hand of layout or template ``layout_name`` (a template's markers of that
    side, else the layout itself). :class:`InputError` when it cannot be read."""
    path = layout_path(layout_name)
    if path is None:
        return load_layout(layout_name)  # says which layouts there are
    key = (str(path.resolve()), path.stat().st_mtime_ns, side)
    if key not in _LAYOUT_CACHE:
        template = load_lab_template(path)
        if len(_LAYOUT_CACHE) > 32:
            _LAYOUT_CACHE.clear()
        _LAYOUT_CACHE[key] = template.layout_for(side) if template is not None else load_layout(path)
    return _LAYOUT_CACHE[key]


def track_layout(layout_name: str | Path, side: str, label_names: Sequence[str]) -> MarkerLayout:
    """The markers of the ``side`` hand of ``layout_name`` that ``label_names (K,)`` name, in that order (a
    hand's labels in a review: ``R_index_tip``, ``Right:index_tip``, the layout's own names...).
    :class:`InputError` when a label names no marker of the layout."""
    layout = hand_layout(layout_name, side)
    wanted = [name.strip().lower() for name in label_names]
    if [name.strip().lower() for name in layout.names] == wanted:
        return layout
    keys = [_keys(str(name)) for name in label_names]
    columns = _columns(keys, layout, {None, side})
    by_label = {int(column): spec for column, spec in zip(columns, layout.markers, strict=True) if column >= 0}
    missing = [name for index, name in enumerate(label_names) if index not in by_label]
    if missing:
        raise InputError(f"the {side} hand's labels {', '.join(missing[:3])} are not markers of layout "
                         f"'{layout.name}'")
    return MarkerLayout(layout.name, tuple(by_label[index] for index in range(len(label_names))), layout.description)
