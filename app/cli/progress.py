"""The one progress line of every long ``handmocap`` command (label, solve, simulate, fill, export, calibrate,
layout optimise and learn, fuse, evaluate, batch), drawn with rich on stderr: what is being done, a bar, the
share done, the rate (frames/s, or the command's own unit), the time spent and the time left, rewritten in
place. Quiet when stderr is not a terminal (a log or a pipe gets the command's result lines only).

A line is a callable taking the fraction done (0..1), as the ``progress`` callbacks of ``core`` are; it ends
(the final state stays on screen) at 1.0, when closed, or when the command ends with an error
(:func:`close_all`, called by :func:`app.cli.main.main` before the error line is printed).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:   # rich is imported when a line is drawn (a terminal), not by every command
    from rich.console import Console

_ACTIVE: list[ProgressLine] = []


def _columns() -> tuple:
    """The line's rich columns, rich imported on first use (module docstring)."""
    from rich.progress import (
        BarColumn,
        ProgressColumn,
        Task,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class _RateColumn(ProgressColumn):
        """Units done per second ("412 frames/s"); blank until there is a rate."""

        def render(self, task: Task) -> Text:
            speed = task.finished_speed or task.speed
            if not speed:
                return Text("", style="progress.data.speed")
            unit = task.fields.get("unit", "")
            return Text(f"{speed:,.0f} {unit}/s" if speed >= 10 else f"{speed:.2g} {unit}/s",
                        style="progress.data.speed")

    return (TextColumn("[progress.description]{task.description}"), BarColumn(bar_width=28),
            TaskProgressColumn(), _RateColumn(), TimeElapsedColumn(), TextColumn("spent,"),
            TimeRemainingColumn(), TextColumn("left"))


def terminal() -> bool:
    """Whether stderr is a terminal (the line is drawn only then)."""
    return sys.stderr.isatty()


class ProgressLine:
    """One in-place progress line (module docstring): ``what`` is done on ``total`` ``unit`` (e.g. 20 000
    frames; 100 "%" when the work has no count of its own). Call it with the fraction done."""

    def __init__(self, what: str, total: float | None = None, unit: str = "frames",
                 console: Console | None = None) -> None:
        self.total = float(total) if total else 100.0
        self.unit = unit if total else "%"
        self.console = console
        self.enabled = console.is_terminal if console is not None else terminal()
        self._progress: Any = None
        self._task: Any = None
        if self.enabled:
            from rich.console import Console
            from rich.progress import Progress

            self.console = console or Console(stderr=True)
            self._progress = Progress(*_columns(), console=self.console, transient=False, refresh_per_second=8)
            self._task = self._progress.add_task(what, total=self.total, unit=self.unit)
            self._progress.start()
            _ACTIVE.append(self)

    def __call__(self, fraction: float) -> None:
        """The work is ``fraction`` (0..1) done; at 1.0 the line ends."""
        if self._progress is None:
            return
        fraction = min(max(float(fraction), 0.0), 1.0)
        self._progress.update(self._task, completed=fraction * self.total)
        if fraction >= 1.0:
            self.close()

    def describe(self, what: str) -> None:
        """Change what the line says it is doing (e.g. the batch's take counts)."""
        if self._progress is not None:
            self._progress.update(self._task, description=what)

    def close(self) -> None:
        """End the line (it stays on screen as it is)."""
        if self._progress is not None:
            self._progress.stop()
            self._progress = None
            if self in _ACTIVE:
                _ACTIVE.remove(self)

    def __enter__(self) -> ProgressLine:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def close_all() -> None:
    """End every line still drawn (the command stops with an error)."""
    for line in list(_ACTIVE):
        line.close()
