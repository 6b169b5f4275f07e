"""The review's dialogs: auto-label settings and naming an event."""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QWidget,
)

from handmocap.core.io.c3d_events import CONTEXTS
from handmocap.core.model import layout_names
from handmocap.widgets.dialog_buttons import ok_cancel_buttons


@dataclass
class AutoLabelSettings:
    """What the operator chose in the auto-label dialog."""

    layout: str = "dense"
    hands: str = "auto"
    objects: str = ""
    online: bool = False
    relabel: bool = False
#: event names offered first (an operator types any other; the names used in the session come after)
EVENT_NAMES = ("grasp on", "grasp off", "contact", "release", "start", "end")


class EventDialog(QDialog):
    """Name an event at a frame: a name (typed, or one used before) and its context (General, Left, Right,
    as the C3D EVENT group has it)."""

    def __init__(self, parent: QWidget, frame_number: int, names: list[str]) -> None:
        super().__init__(parent)
        self.setWindowTitle("Add event")
        form = QFormLayout(self)
        self.name_box = QComboBox(self)
        self.name_box.setEditable(True)
        self.name_box.addItems(list(dict.fromkeys([*names, *EVENT_NAMES])))
        self.name_box.setCurrentText(names[0] if names else EVENT_NAMES[0])
        line_edit = self.name_box.lineEdit()    # an editable box has one
        if line_edit is not None:
            line_edit.selectAll()
        self.context_box = QComboBox(self)
        self.context_box.addItems(list(CONTEXTS))
        self.context_box.setToolTip("Which side the event is about (the C3D EVENT group's context)")
        form.addRow(QLabel(f"At frame {frame_number}"))
        form.addRow("Name", self.name_box)
        form.addRow("Side", self.context_box)
        form.addRow(ok_cancel_buttons(self, "Add event"))

    def chosen(self) -> tuple[str, str]:
        """The name and the context given."""
        return self.name_box.currentText().strip(), self.context_box.currentText()


class AutoLabelDialog(QDialog):
    """Layout, hands ("auto": the labeller decides), rigid objects (a scene spec JSON), online/offline mode
    and whether to relabel from scratch (ignore the labels the file already has)."""

    def __init__(self, parent: QWidget, settings: AutoLabelSettings) -> None:
        super().__init__(parent)
        self.setWindowTitle("Auto-label")
        form = QFormLayout(self)
        self.layout_box = QComboBox(self)
        self.layout_box.addItems(layout_names())
        self.layout_box.setCurrentText(settings.layout)
        self.hands_box = QComboBox(self)
        self.hands_box.addItems(["auto", "right", "left", "both"])
        self.hands_box.setToolTip("auto: the labeller decides which hands the take shows (and warns when it "
                                  "cannot tell)")
        self.hands_box.setCurrentText(settings.hands)
        self.objects_edit = QLineEdit(settings.objects, self)
        self.objects_edit.setPlaceholderText("none")
        browse = QPushButton("Browse…", self)
        browse.clicked.connect(self._browse)
        objects = QHBoxLayout()
        objects.addWidget(self.objects_edit, 1)
        objects.addWidget(browse)
        self.online_box = QCheckBox("Online (causal: no backward pass, as in live tracking)", self)
        self.online_box.setChecked(settings.online)
        self.relabel_box = QCheckBox("Relabel from scratch (ignore the labels the file already has)", self)
        self.relabel_box.setToolTip("Off: labels outside the layout (arm, body, objects) are kept, and where the "
                                    "file labels a point with a layout marker's name that label is kept.")
        self.relabel_box.setChecked(settings.relabel)
        form.addRow("Marker layout", self.layout_box)
        form.addRow("Hands", self.hands_box)
        form.addRow("Rigid objects", objects)
        form.addRow("", self.online_box)
        form.addRow("", self.relabel_box)
        form.addRow(ok_cancel_buttons(self, "Auto-label"))

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Scene objects", "", "Scene spec (*.json);;All files (*)")
        if path:
            self.objects_edit.setText(path)

    def settings(self) -> AutoLabelSettings:
        return AutoLabelSettings(self.layout_box.currentText(), self.hands_box.currentText(),
                                 self.objects_edit.text().strip(), self.online_box.isChecked(),
                                 self.relabel_box.isChecked())

