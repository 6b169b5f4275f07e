"""Auto-label of a take on the review's worker, and applying its result."""

from __future__ import annotations

import logging
from collections.abc import Callable

from PySide6.QtWidgets import QDialog

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.dialogs import AutoLabelDialog, AutoLabelSettings
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.workflows import AutoLabelOutcome, auto_label

_log = logging.getLogger(__name__)


class AutoLabelling(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: auto-label."""

    def choose_auto_label(self) -> None:
        if self.document is None:
            return
        if self.document.layout_name:
            self.auto_settings.layout = self.document.layout_name
        dialog = AutoLabelDialog(self.host, self.auto_settings)
        if dialog.exec() == QDialog.DialogCode.Accepted:
            self.auto_settings = dialog.settings()
            self.start_auto_label(self.auto_settings)

    def start_auto_label(self, settings: AutoLabelSettings, document: TakeDocument | None = None) -> None:
        """Auto-label ``document`` (default: the current take) on a worker; the result is one undoable step."""
        document = document or self.document
        if document is None:
            return
        take = document.ensure_review().take
        models = dict(document.hand_models)

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]):
            return auto_label(take, settings.layout, settings.hands, settings.objects or None, settings.online,
                              models=models or None, relabel=settings.relabel, progress=progress,
                              cancelled=cancelled)

        self._start_job("auto-label", task, document=document)

    def _apply_auto_label(self, document: TakeDocument, result: AutoLabelOutcome) -> None:
        """Keep auto-label's subject calibrations on ``document`` and push its labelling (one undoable step)."""
        document.hand_models.update(result.models)
        document.marker_sets.update(result.marker_sets)
        for side in result.models:
            document.subjects.pop(side, None)
        document.subjects.update({subject.side: subject for subject in result.subjects})
        if document is self.document:            # a new labelling: start afresh on it
            self._rejected = set()
            self.app.clear_selection()
        document.push(result.command)
        review = document.ensure_review()      # the review the labelling was pushed on
        report, known = result.report, result.report["file_labels"]
        kept = (f"; kept from the file: {len(known['kept_labels'])} labels outside the layout, its hand "
                f"labels ({known['disagreed_samples']} samples differed from auto-label)"
                if known["kept_labels"] or known["file_label_samples"] else "")
        self.status_message.emit(
            review.health_summary() or
            f"Auto-labelled {report['frames']} frames: {100 * report['labelled_share']:.1f} % of label "
            f"samples found, {report['ghost_points']} ghost points left unlabelled{kept}",
            0 if report["health"] else 10000)
        for warning in review.health:      # into the message panel, not only the status bar
            _log.warning("%s: auto-label: %s", document.title, warning.message)
        self.auto_label_applied.emit(document, result.models, result.marker_sets)
