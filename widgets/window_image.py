"""Screenshots of windows holding 3D views: Qt's ``grab()`` misses what VTK draws through OpenGL, so
each view's own rendering is painted over its place in the grabbed image; saving one as a durable image file."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtGui import QImage, QPainter
from PySide6.QtWidgets import QWidget

from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_path

if TYPE_CHECKING:
    from handmocap.widgets.deferred_viewport import DeferredViewport
    from handmocap.widgets.viewport import HandViewport


def window_image(window: QWidget, views: Iterable[HandViewport | DeferredViewport]) -> QImage:
    """``window`` as an image with each visible 3D view in ``views`` drawn in (without an OpenGL
    context, e.g. on the offscreen platform, the views stay as Qt grabbed them)."""
    image = window.grab().toImage()
    ratio = image.devicePixelRatio()
    painter = QPainter(image)
    for view in views:
        if not view.isVisible():
            continue
        view.render_now()
        try:
            pixels = view.plotter.screenshot(return_img=True)
        except (RuntimeError, ValueError):
            break
        assert pixels is not None      # pyvista returns None only when return_img is False
        height, width = pixels.shape[:2]
        rendered = QImage(np.ascontiguousarray(pixels[:, :, :3]).data, width, height, 3 * width,
                          QImage.Format.Format_RGB888).copy()
        target = view.rect().translated(view.mapTo(window, view.rect().topLeft()))
        painter.drawImage(target, rendered.scaled(int(target.width() * ratio), int(target.height() * ratio)))
    painter.end()
    return image


def save_screenshot(image: QImage, path: str | Path, show_error: Callable[[str, str], None]) -> bool:
    """Write ``image`` to ``path`` (a durable write; Qt picks the format from the suffix); False after
    ``show_error(title, message)`` when it cannot."""
    try:
        with durable_path(path) as temporary:  # same suffix as path
            if not image.save(str(temporary)):
                raise InputError(f"{path}: could not write the image")
    except InputError as error:
        show_error("Cannot save the screenshot", str(error))
        return False
    return True
