"""The one table of keyboard shortcuts: it gives every action its keys, the key hint its menu shows, the key its
tooltip names, and the list Help ▸ Keyboard shortcuts shows (:class:`widgets.shortcuts_dialog.ShortcutsDialog`),
as mne-qt-browser's help does. An action gets its keys with :func:`bind` and nowhere else, so the four never
disagree. The keys are Qt's portable text ("Ctrl+Shift+Z": Cmd on macOS).
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtGui import QAction, QKeySequence


@dataclass(frozen=True)
class Shortcut:
    """``keys`` of one command (the first is the one menus show), its ``section`` (the menu or place it
    belongs to) and ``what`` it does in plain words."""

    keys: tuple[str, ...]
    section: str
    what: str


SECTIONS = ("File", "Edit", "Review", "View", "Playback", "Solve", "Tools", "Camera", "Calibration wizard",
            "Help")

#: every shortcut of the application, by command name
SHORTCUTS: dict[str, Shortcut] = {
    # File
    "open": Shortcut(("Ctrl+O",), "File", "Open take files"),
    "demo": Shortcut(("Ctrl+D",), "File", "Open the demo session"),
    "new_session": Shortcut(("Ctrl+Shift+N",), "File", "New session"),
    "open_session": Shortcut(("Ctrl+Shift+O",), "File", "Open a session"),
    "add_takes": Shortcut(("Ctrl+Shift+A",), "File", "Add take files to the session"),
    "close_take": Shortcut(("Ctrl+W",), "File", "Close the shown take (a session take is saved)"),
    "export": Shortcut(("Ctrl+Shift+E",), "File", "Export the shown take (C3D, TRC, CSV, BVH, glTF)"),
    "export_angles": Shortcut(("Ctrl+E",), "File", "Export the IK solve's joint angles as CSV"),
    "screenshot": Shortcut(("Ctrl+Shift+S",), "File", "Save a screenshot of the window"),
    "quit": Shortcut(("Ctrl+Q",), "File", "Quit"),
    # Edit
    "undo": Shortcut(("Ctrl+Z",), "Edit", "Undo (also during a re-solve: it is cancelled)"),
    "redo": Shortcut(("Ctrl+Shift+Z", "Ctrl+Y"), "Edit", "Redo"),
    "assign": Shortcut(("L",), "Edit", "Give the selected point a label (type to find it)"),
    "swap": Shortcut(("W",), "Edit", "Swap the selected label with another (type to find it)"),
    "unlabel": Shortcut(("U",), "Edit", "Remove the selected point's label"),
    "ghost": Shortcut(("Shift+G",), "Edit", "Mark the selected point as a ghost (a stray reflection)"),
    "range_in": Shortcut(("I",), "Edit", "Mark the start of a frame range here"),
    "range_out": Shortcut(("O",), "Edit", "Mark the end of a frame range here"),
    "clear_range": Shortcut(("Shift+I",), "Edit", "Clear the marked range"),
    "trim": Shortcut(("Ctrl+T",), "Edit", "Trim the take to the marked range"),
    # Review
    "auto_label": Shortcut(("Ctrl+L",), "Review", "Label the take's raw points automatically"),
    "rigid_body": Shortcut(("Ctrl+B",), "Review", "Define a rigid body from the Ctrl+clicked points"),
    "next_problem": Shortcut(("F3",), "Review", "Go to the next problem (gap, swap suspect, doubt)"),
    "previous_problem": Shortcut(("Shift+F3",), "Review", "Go to the previous problem"),
    "fill_short_gaps": Shortcut(("Ctrl+Shift+F",), "Review", "Fill every open gap up to N frames"),
    "add_event": Shortcut(("Ctrl+M",), "Review", "Add an event (a named frame) here"),
    "next_event": Shortcut(("Ctrl+Right",), "Review", "Go to the next event"),
    "previous_event": Shortcut(("Ctrl+Left",), "Review", "Go to the previous event"),
    # View
    "marker_names": Shortcut(("N",), "View", "Show every marker's name"),
    "hand_mesh": Shortcut(("M",), "View", "Show the hand's surface"),
    "effectors": Shortcut(("E",), "View", "Show the model's markers and their distance to the data"),
    "grid": Shortcut(("G",), "View", "Show the ground grid"),
    "frame_hand": Shortcut(("F",), "View", "Point the camera at the hand"),
    "plots": Shortcut(("Ctrl+Shift+P",), "View", "Show the trajectory plots"),
    # Playback
    "first_frame": Shortcut(("Home",), "Playback", "First frame"),
    "previous_frame": Shortcut(("Left",), "Playback", "Previous frame"),
    "play": Shortcut(("Space",), "Playback", "Play / pause"),
    "next_frame": Shortcut(("Right",), "Playback", "Next frame"),
    "last_frame": Shortcut(("End",), "Playback", "Last frame"),
    # Solve
    "solve": Shortcut(("Ctrl+R",), "Solve", "Solve the take with inverse kinematics"),
    "cancel": Shortcut(("Esc",), "Solve", "Cancel what the progress bar shows"),
    # Tools
    "calibrate_scan": Shortcut(("Ctrl+Shift+K",), "Tools", "Calibrate a hand scan"),
    "marker_layouts": Shortcut(("Ctrl+Shift+L",), "Tools", "Marker layouts"),
    # Camera
    "camera_earlier": Shortcut(("Ctrl+Alt+Left",), "Camera", "Camera clock one camera frame earlier"),
    "camera_later": Shortcut(("Ctrl+Alt+Right",), "Camera", "Camera clock one camera frame later"),
    "camera_earlier_fine": Shortcut(("Alt+Left",), "Camera", "Camera clock one mocap frame earlier"),
    "camera_later_fine": Shortcut(("Alt+Right",), "Camera", "Camera clock one mocap frame later"),
    # Calibration wizard (its own window)
    "wizard_undo": Shortcut(("Ctrl+Z",), "Calibration wizard", "Undo the last landmark picked, skipped or loaded"),
    # Help
    "shortcuts": Shortcut(("F1",), "Help", "This list of keyboard shortcuts"),
}


def shortcut(name: str) -> Shortcut:
    """The table's entry ``name`` (KeyError: not in the table)."""
    return SHORTCUTS[name]


def key_sequences(name: str) -> list[QKeySequence]:
    """The keys of command ``name`` as Qt key sequences."""
    return [QKeySequence(key) for key in SHORTCUTS[name].keys]


def key_text(name: str) -> str:
    """The keys of command ``name`` as the platform writes them ("Ctrl+Shift+Z or Ctrl+Y")."""
    return " or ".join(sequence.toString(QKeySequence.SequenceFormat.NativeText) for sequence in key_sequences(name))


def bind(action: QAction, name: str, tooltip: str | None = None) -> QAction:
    """Give ``action`` the keys of command ``name`` (its menu shows the first) and a tooltip naming them:
    ``tooltip`` (default the table's words) followed by the keys."""
    action.setShortcuts(key_sequences(name))
    action.setToolTip(f"{tooltip or SHORTCUTS[name].what} ({key_text(name)})")
    action.setProperty("shortcut_name", name)
    return action


def rows() -> list[tuple[str, str, str]]:
    """``(section, keys, what)`` of every shortcut, section by section in :data:`SECTIONS` order."""
    entries = [(entry.section, key_text(name), entry.what) for name, entry in SHORTCUTS.items()]
    return sorted(entries, key=lambda row: SECTIONS.index(row[0]) if row[0] in SECTIONS else len(SECTIONS))
