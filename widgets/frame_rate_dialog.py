"""Asking the frame rate of a take file that states none (a NOKOV CSV, a CSV without a time column).

:class:`FrameRatePrompt` asks once per file with :class:`FrameRateDialog` and offers the rate given last (100 Hz
at first), so a folder of takes of one system is opened with one click per file.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QDialog, QDoubleSpinBox, QFormLayout, QLabel, QVBoxLayout, QWidget

from handmocap.widgets.dialog_buttons import ok_cancel_buttons

#: the rate offered before any was given (Hz)
DEFAULT_FRAME_RATE_HZ = 100.0
#: the rates the field accepts (Hz)
FRAME_RATE_RANGE_HZ = (0.1, 100_000.0)


class FrameRateDialog(QDialog):
    """"<file> states no frame rate": a rate field in Hz, Open and Skip."""

    def __init__(self, file_name: str, rate_hz: float = DEFAULT_FRAME_RATE_HZ, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Frame rate")
        message = QLabel(f"<b>{file_name}</b> does not say at what frame rate it was recorded.<br>"
                         "Give the rate of the capture system:", self)
        message.setWordWrap(True)
        self.rate_box = QDoubleSpinBox(self)
        self.rate_box.setRange(*FRAME_RATE_RANGE_HZ)
        self.rate_box.setDecimals(3)
        self.rate_box.setSuffix(" Hz")
        self.rate_box.setValue(rate_hz)
        self.rate_box.setToolTip("Frames per second of the take (the capture system's rate, e.g. 120 Hz)")
        form = QFormLayout()
        form.addRow("Frame rate", self.rate_box)
        layout = QVBoxLayout(self)
        layout.addWidget(message)
        layout.addLayout(form)
        layout.addWidget(ok_cancel_buttons(self, "Open", "Skip this file"))
        self.rate_box.selectAll()
        self.rate_box.setFocus()

    def rate_hz(self) -> float:
        """The rate given (Hz)."""
        return float(self.rate_box.value())


class FrameRatePrompt:
    """Asks the frame rate of each take file that states none, offering the rate given last."""

    def __init__(self, parent: QWidget | None = None) -> None:
        self.parent = parent
        self.last_rate_hz = DEFAULT_FRAME_RATE_HZ

    def ask(self, path: str | Path) -> float | None:
        """The rate (Hz) the user gives for ``path``, None when the file is skipped."""
        dialog = FrameRateDialog(Path(path).name, self.last_rate_hz, self.parent)
        try:
            if dialog.exec() != QDialog.DialogCode.Accepted:
                return None
            self.last_rate_hz = dialog.rate_hz()
            return self.last_rate_hz
        finally:
            dialog.deleteLater()
