"""What a change of a review announces: typed events emitted by the undo stack.

Every do, attach, undo and redo of :class:`~core.review.commands.UndoStack` tells its listeners one
:class:`ReviewChanged`: which operation, the frames it touched and what kind of data changed
(:class:`Change`), so that each view redraws what it shows and nothing else.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import NamedTuple


class FrameSpan(NamedTuple):
    """Frames ``start .. stop - 1`` (0-based) a command changed; empty when ``stop <= start``."""

    start: int
    stop: int

    @property
    def empty(self) -> bool:
        return self.stop <= self.start

    def union(self, other: FrameSpan) -> FrameSpan:
        if self.empty:
            return other
        if other.empty:
            return self
        return FrameSpan(min(self.start, other.start), max(self.stop, other.stop))


EMPTY_SPAN = FrameSpan(0, 0)


OPERATIONS = ("do", "attach", "undo", "redo", "clean")


class Change(enum.Flag):
    """The kinds of review data a command changes (combined with ``|``)."""

    NONE = 0
    LABELS = enum.auto()      #: which point each label takes, ghosts, edit flags, labelling confidence
    FILLS = enum.auto()       #: accepted gap fills
    SOLVE = enum.auto()       #: the hands' joint angles and the residuals
    STRUCTURE = enum.auto()   #: label names, hands, rigid bodies, health: the whole review
    TIMELINE = enum.auto()    #: the take's events (named frames) and the range it is trimmed to
    ALL = LABELS | FILLS | SOLVE | STRUCTURE | TIMELINE


@dataclass(frozen=True)
class ReviewChanged:
    """The review changed: ``operation`` ("do", "attach", "undo", "redo"; "clean" when only the undo
    history's saved mark or content changed), the frames ``span`` it touched (0-based, stop exclusive)
    and ``what`` changed there."""

    operation: str
    span: FrameSpan
    what: Change

    @property
    def structure(self) -> bool:
        """Whether labels or hands may have come or gone (views rebuild rather than update)."""
        return bool(self.what & Change.STRUCTURE)
