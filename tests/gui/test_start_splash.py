"""The start-up splash (issue 25, start-up): on screen and drawn when ``show_now`` returns, with the line it is
told, and gone when the window shows."""

from __future__ import annotations

import pytest
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.launch import _splash_picture, application_icon
from handmocap.widgets.start_splash import StartSplash

pytestmark = pytest.mark.gui


def test_the_splash_is_on_screen_with_its_message_when_show_now_returns(qtbot):
    splash = StartSplash(_splash_picture(application_icon()))
    qtbot.addWidget(splash)
    splash.show_now()
    assert splash.isVisible() and splash.windowHandle().isExposed()
    splash.tell("Starting Hand Mocap Studio…")
    assert splash.message() == "Starting Hand Mocap Studio…"
    image = splash.grab().toImage()
    bottom = [image.pixelColor(x, image.height() - 14).lightness() for x in range(image.width())]
    assert max(bottom) > 200                # the white line of text is drawn near the bottom
    screen = QApplication.primaryScreen().availableGeometry()
    assert screen.contains(splash.geometry())
    splash.close()
