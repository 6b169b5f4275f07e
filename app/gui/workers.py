"""Running long ``core`` work on a worker thread.

A task is a plain function ``task(progress, cancelled) -> result``. :class:`TaskRunner` runs one at a
time on a QThread; the worker never touches a widget: progress, results and errors come back by
signal, tagged with the request id the caller got from :meth:`TaskRunner.start`, so the GUI applies
a result only if it still belongs to the current document.

A worker running Python code holds the interpreter lock for up to the switch interval each time the
GUI thread asks for it, and the GUI thread asks for it at every call into a Python slot or model; with
Python's default 5 ms, painting a window during a solve took seconds. :class:`TaskRunner` lowers the
interval to :data:`GUI_SWITCH_INTERVAL_S`.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal, Slot

from handmocap.core.errors import CancelledError, HandMocapError

Task = Callable[[Callable[[float], None], Callable[[], bool]], Any]

LOG = logging.getLogger(__name__)
PROGRESS_INTERVAL_S = 0.05   # a task may report every frame; the GUI hears at most 20 updates a second
GUI_SWITCH_INTERVAL_S = 0.001  # longest wait of the GUI thread for the interpreter lock held by a worker


def one_line(message: str) -> str:
    """The first non-empty line of ``message`` (messages shown to the operator are one line)."""
    return next((line.strip() for line in message.splitlines() if line.strip()), message.strip())


class _Worker(QObject):
    progressed = Signal(int, float)
    succeeded = Signal(int, object)
    failed = Signal(int, str)
    was_cancelled = Signal(int)

    def __init__(self, request_id: int, task: Task, cancel_event: threading.Event) -> None:
        super().__init__()
        self._request_id, self._task, self._cancel_event = request_id, task, cancel_event
        self._last_report = 0.0

    def _report(self, fraction: float) -> None:
        """Forward progress, throttled to :data:`PROGRESS_INTERVAL_S` (the end is always reported)."""
        now = time.monotonic()
        if fraction >= 1.0 or now - self._last_report >= PROGRESS_INTERVAL_S:
            self._last_report = now
            self.progressed.emit(self._request_id, float(fraction))

    @Slot()
    def run(self) -> None:
        request = self._request_id
        try:
            result = self._task(self._report, self._cancel_event.is_set)
        except CancelledError:
            self.was_cancelled.emit(request)
        except HandMocapError as error:
            self.failed.emit(request, one_line(str(error)))
        except Exception as error:  # noqa: BLE001 - any failure becomes a message, never a crash
            LOG.exception("task %d failed", request)
            self.failed.emit(request, one_line(f"unexpected error: {type(error).__name__}: {error}"))
        else:
            self.succeeded.emit(request, result)


class TaskRunner(QObject):
    """Runs one task at a time on a worker thread; re-emits its signals on the GUI thread."""

    progressed = Signal(int, float)        # request id, fraction 0..1
    succeeded = Signal(int, object)        # request id, result
    failed = Signal(int, str)              # request id, one-line message
    cancelled = Signal(int)                # request id
    busy_changed = Signal(bool)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._next_id = 0
        self._thread: QThread | None = None
        self._worker: _Worker | None = None
        self._cancel_event = threading.Event()
        self._retired: list[tuple[QThread, _Worker]] = []   # abandoned tasks still ending on their threads
        sys.setswitchinterval(min(sys.getswitchinterval(), GUI_SWITCH_INTERVAL_S))

    def is_busy(self) -> bool:
        """Whether a task is running."""
        return self._thread is not None

    @property
    def current_request(self) -> int:
        """Request id of the running task (0 when idle)."""
        return self._next_id if self._thread is not None else 0

    def start(self, task: Task) -> int:
        """Start ``task`` (cancelling and waiting for a running one first; an abandoned one is not waited for);
        returns its request id."""
        if self._thread is not None:
            self.cancel()
            self._join()
        self._next_id += 1
        self._cancel_event = threading.Event()
        thread = QThread()
        worker = _Worker(self._next_id, task, self._cancel_event)
        worker.moveToThread(thread)
        thread.started.connect(worker.run)
        worker.progressed.connect(self.progressed)
        # bound slots of this GUI-thread object: Qt queues these calls onto the GUI thread
        worker.succeeded.connect(self._on_succeeded)
        worker.failed.connect(self._on_failed)
        worker.was_cancelled.connect(self._on_cancelled)
        self._thread, self._worker = thread, worker
        thread.start()
        self.busy_changed.emit(True)
        return self._next_id

    @Slot(int, object)
    def _on_succeeded(self, request_id: int, result: object) -> None:
        self._join(request_id)
        self.succeeded.emit(request_id, result)

    @Slot(int, str)
    def _on_failed(self, request_id: int, message: str) -> None:
        self._join(request_id)
        self.failed.emit(request_id, message)

    @Slot(int)
    def _on_cancelled(self, request_id: int) -> None:
        self._join(request_id)
        self.cancelled.emit(request_id)

    def cancel(self) -> None:
        """Ask the running task to stop at its next check."""
        self._cancel_event.set()

    def abandon(self) -> None:
        """Cancel the running task without waiting for it: nothing it reports or returns is heard any more
        and the runner is idle at once (a task may be started next); its thread ends by itself at the task's
        next check of ``cancelled()``. For an operator's action that must take effect now (undo during a
        re-solve)."""
        if self._thread is None or self._worker is None:     # (set together)
            return
        self._cancel_event.set()
        thread, worker = self._thread, self._worker
        self._thread = self._worker = None
        for signal in (worker.progressed, worker.succeeded, worker.failed, worker.was_cancelled):
            signal.disconnect()
        for signal in (worker.succeeded, worker.failed, worker.was_cancelled):
            signal.connect(thread.quit)     # the thread's event loop ends when the task returns
        self._retired.append((thread, worker))
        thread.finished.connect(self._release_finished)   # a bound slot: queued onto the GUI thread
        self.busy_changed.emit(False)

    @Slot()
    def _release_finished(self) -> None:
        """Release the threads of abandoned tasks that have ended."""
        for entry in list(self._retired):
            if entry[0].isFinished():
                self._retired.remove(entry)
                entry[1].deleteLater()

    def stop(self) -> None:
        """Cancel the running task and wait for its thread (and those of abandoned tasks) to end."""
        for thread, _worker in list(self._retired):
            thread.quit()
            thread.wait()
        self._retired.clear()
        if self._thread is None:
            return
        self.cancel()
        self._join()

    def _join(self, request_id: int | None = None) -> None:
        """End the worker thread (only the current request's, when ``request_id`` is given)."""
        if (self._thread is None or self._worker is None      # (set together)
                or (request_id is not None and request_id != self._next_id)):
            return
        thread, worker = self._thread, self._worker   # both stay alive until the thread has ended
        self._thread = self._worker = None
        thread.quit()
        thread.wait()
        worker.deleteLater()
        self.busy_changed.emit(False)
