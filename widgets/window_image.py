"""Screenshots of windows holding 3D views: Qt's ``grab()`` misses what VTK draws through OpenGL, so
each view's own rendering is painted over its place in the grabbed image."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from PySide6.QtGui import QImage, QPainter
from PySide6.QtWidgets import QWidget

from widgets.viewport import HandViewport


def window_image(window: QWidget, views: Iterable[HandViewport]) -> QImage:
    """``window`` as an image with each visible 3D view in ``views`` drawn in (without an OpenGL
    context, e.g. on the offscreen platform, the views stay as Qt grabbed them)."""
    image = window.grab().toImage()
    ratio = image.devicePixelRatio()
    painter = QPainter(image)
    for view in views:
        if not view.isVisible():
            continue
        view.render()
        try:
            pixels = view.plotter.screenshot(return_img=True)
        except (RuntimeError, ValueError):
            break
        height, width = pixels.shape[:2]
        rendered = QImage(np.ascontiguousarray(pixels[:, :, :3]).data, width, height, 3 * width,
                          QImage.Format.Format_RGB888).copy()
        target = view.rect().translated(view.mapTo(window, view.rect().topLeft()))
        painter.drawImage(target, rendered.scaled(int(target.width() * ratio), int(target.height() * ratio)))
    painter.end()
    return image
