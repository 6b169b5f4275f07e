"""The review's worker: one job at a time (auto-label, re-solve, fill all), its progress, result and end."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

from PySide6.QtCore import QObject

from handmocap.app.gui.application import Job
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.part import ReviewPart
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.errors import HandMocapError
from handmocap.core.review import Command
from handmocap.core.workflows import AutoLabelOutcome

JOB_NAME = "review"                # the worker of auto-label, re-solves and fills in Application.jobs



class ReviewJobs(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: runs its jobs."""

    def _init_jobs(self) -> None:
        """The worker of the review's jobs and what its running job works on."""
        self._job_document: TakeDocument | None = None
        self._job_kind = ""
        self._job_version = -1
        self.jobs = TaskRunner(cast(QObject, self))     # the controller: a QObject
        self.jobs.progressed.connect(lambda _request, fraction: self.progressed.emit(fraction))
        self.jobs.succeeded.connect(self._job_succeeded)
        self.jobs.failed.connect(self._job_failed)
        self.jobs.cancelled.connect(self._job_cancelled)
        self.jobs.busy_changed.connect(self._jobs_busy_changed)

    def _start_job(self, kind: str, task: Callable, document: TakeDocument | None = None) -> None:
        job_document = document or self.document
        if job_document is None or job_document.review is None:
            return
        self._job_document, self._job_kind = job_document, kind
        self._job_version = job_document.review.version
        self.jobs.start(task)
        self.app.job_started(JOB_NAME, Job(kind, job_document, self.jobs.cancel))
        self.progress_started.emit(f"{kind.capitalize()}… %p %")

    def _jobs_busy_changed(self, busy: bool) -> None:
        if not busy:
            self.app.job_ended(JOB_NAME)

    def _job_finished(self) -> None:
        self.progress_ended.emit()
        self._start_resolve()
        self.update_enabled()

    def _job_succeeded(self, _request: int, result: object) -> None:
        document, kind = self._job_document, self._job_kind
        self._job_document = None
        if document is None or document.review is None:
            self._job_finished()
            return
        try:
            if kind == "auto-label":
                self._apply_auto_label(document, cast(AutoLabelOutcome, result))
            elif kind == "fill" and result is not None:
                self._apply_fill(document, cast(Command, result))
            elif kind == "re-solve" and document.review.version == self._job_version:
                # (else the review changed meanwhile: re-solved again)
                self._apply_resolve(document, cast(list[Command], result))
        except HandMocapError as error:
            self.error_raised.emit(f"Cannot apply the {kind}", str(error))
        self._job_finished()

    def _job_failed(self, _request: int, message: str) -> None:
        kind = self._job_kind
        self._job_document = None
        self._job_finished()
        self.error_raised.emit(f"{kind.capitalize()} failed", message)

    def _job_cancelled(self, _request: int) -> None:
        kind = self._job_kind
        self._job_document = None
        self.progress_ended.emit()
        self.status_message.emit(f"{kind.capitalize()} cancelled; the take is unchanged", 5000)
        self.update_enabled()

    def stop(self) -> None:
        """Cancel and wait for the workers (the window is closing)."""
        self.jobs.stop()
        self.checks.stop()
