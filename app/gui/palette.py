"""The dark colour theme of every window of the application."""

from __future__ import annotations

from PySide6.QtGui import QColor, QPalette
from PySide6.QtWidgets import QApplication, QWidget

#: the outline of check boxes in item views (Fusion draws it from the window colour, darkened: on the dark theme
#: that is the list's own background colour, so an empty box could not be seen)
INDICATOR_WINDOW = QColor(120, 124, 132)


def apply_dark_palette(app: QApplication) -> None:
    """A dark theme like the mocap tools operators know (disabled controls greyed out)."""
    palette = QPalette()
    role = QPalette.ColorRole
    colours = {
        role.Window: QColor(45, 47, 52), role.WindowText: QColor(225, 225, 225),
        role.Base: QColor(32, 34, 38), role.AlternateBase: QColor(40, 42, 47),
        role.Text: QColor(225, 225, 225), role.Button: QColor(55, 58, 64),
        role.ButtonText: QColor(225, 225, 225), role.Highlight: QColor(60, 120, 200),
        role.HighlightedText: QColor(255, 255, 255), role.ToolTipBase: QColor(55, 58, 64),
        role.ToolTipText: QColor(225, 225, 225), role.PlaceholderText: QColor(140, 140, 140),
        role.Link: QColor(110, 170, 240), role.Mid: QColor(70, 73, 80), role.Dark: QColor(25, 26, 29),
    }
    for colour_role, colour in colours.items():
        palette.setColor(colour_role, colour)
    for colour_role in (role.WindowText, role.Text, role.ButtonText):
        palette.setColor(QPalette.ColorGroup.Disabled, colour_role, QColor(115, 118, 125))
    palette.setColor(QPalette.ColorGroup.Disabled, role.Highlight, QColor(70, 73, 80))
    app.setPalette(palette)


def visible_check_boxes(view: QWidget) -> None:
    """Make the check boxes of the items of ``view`` (a list the operator ticks) visible on the dark theme: their
    outline is drawn from the window colour, which this lightens for ``view`` alone."""
    palette = view.palette()
    for group in (QPalette.ColorGroup.Active, QPalette.ColorGroup.Inactive):
        palette.setColor(group, QPalette.ColorRole.Window, INDICATOR_WINDOW)
    view.setPalette(palette)
