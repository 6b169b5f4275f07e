"""Reading files on a worker one after the other: opening takes, adding takes to a session, the demo."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from PySide6.QtCore import QObject, QTimer, Signal

from handmocap.app.gui.workers import Task, TaskRunner

Result = TypeVar("Result")


class LoadQueue(QObject):
    """Runs loading tasks one at a time, in the order they were queued; each success is handed to its
    ``on_success`` on the GUI thread, each failure is a one-line message (:attr:`failed`)."""

    started = Signal(str)          # what is being loaded now, for the status bar
    succeeded = Signal(int, object)  # request id, result (after its on_success ran)
    failed = Signal(str)           # one-line message
    busy_changed = Signal(bool)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        # each task with the on_success that takes its result
        self._pending: list[tuple[str, Task, Callable[[Any], None]]] = []
        self._on_success: Callable[[Any], None] = lambda _result: None
        self.runner = TaskRunner(self)
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.busy_changed.connect(self.busy_changed)

    def queue(self, text: str, task: Callable[[Callable[[float], None], Callable[[], bool]], Result],
              on_success: Callable[[Result], None]) -> None:
        """Run ``task`` after those queued before it; ``on_success(result)`` when it succeeds."""
        self._pending.append((text, task, on_success))
        self._start_next()

    def is_busy(self) -> bool:
        """Whether a task runs or waits."""
        return self.runner.is_busy() or bool(self._pending)

    def stop(self) -> None:
        """Forget the waiting tasks; cancel and wait for the running one."""
        self._pending.clear()
        self.runner.stop()

    def _start_next(self) -> None:
        if self.runner.is_busy() or not self._pending:
            return
        text, task, self._on_success = self._pending.pop(0)
        self.started.emit(text)
        self.runner.start(task)

    def _succeeded(self, request: int, result: object) -> None:
        self._on_success(result)
        self.succeeded.emit(request, result)
        QTimer.singleShot(0, self._start_next)

    def _failed(self, _request: int, message: str) -> None:
        self.failed.emit(message)
        QTimer.singleShot(0, self._start_next)
