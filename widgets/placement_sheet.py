"""Painting a marker placement sheet (``core.layout.placement_sheet``) on an A4 page: PNG or PDF.

Works without a screen: :func:`ensure_gui_application` starts Qt on the offscreen platform when there
is no display (the command line), and the page is painted with QPainter into a QImage or QPdfWriter.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PySide6.QtCore import QMarginsF, QPointF, QRectF, Qt
from PySide6.QtGui import (
    QColor,
    QFont,
    QGuiApplication,
    QImage,
    QPageLayout,
    QPageSize,
    QPainter,
    QPdfWriter,
    QPen,
)
from PySide6.QtWidgets import QApplication

from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_path
from handmocap.core.layout.label_placement import place_labels
from handmocap.core.layout.placement_sheet import PlacementSheet, SheetView, rasterise_view

PAGE_MM = (210.0, 297.0)          # A4 portrait
MARGIN_MM = 12.0
SKIN = np.array([232.0, 190.0, 163.0])
MARKER_FILL = QColor(20, 110, 220)
HIDDEN_MARKER = QColor(20, 110, 220)
TEXT = QColor(20, 20, 20)
MUTED = QColor(90, 90, 90)
RULE = QColor(170, 170, 170)
MARKER_RADIUS_MM = 2.4
LABEL_SIZE_MM = (5.6, 4.6)        # the white box behind a marker number
LEADER_FROM_MM = 5.5              # a number further than this from its marker gets a leader line
PNG_DPI = 200
SKIN_PIXELS_PER_MM = 12.0     # resolution of the shaded skin image (about 300 dpi on paper)


def ensure_gui_application() -> QGuiApplication:
    """The running Qt application, or a new one (offscreen when there is no display) for painting. A
    full QApplication, so that windows can still be opened later in the same process."""
    app = QGuiApplication.instance()
    if app is None:
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
        app = QApplication([])
    if not isinstance(app, QGuiApplication):
        raise RuntimeError("a Qt application without a GUI is running: a placement sheet cannot be painted")
    return app


TOP_LEFT = Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop


def _text(painter: QPainter, rect: QRectF, text: str, size_mm: float, bold: bool = False,
          colour: QColor = TEXT, flags: Qt.AlignmentFlag = TOP_LEFT) -> None:
    """Draw ``text`` in ``rect`` (mm) with a font ``size_mm`` high."""
    painter.save()
    scale = 0.1                                    # draw at 10× the size in a 0.1-scaled frame: crisp glyphs
    painter.scale(scale, scale)
    font = QFont("DejaVu Sans")
    font.setPixelSize(max(1, round(size_mm / scale)))
    font.setBold(bold)
    painter.setFont(font)
    painter.setPen(colour)
    target = QRectF(rect.x() / scale, rect.y() / scale, rect.width() / scale, rect.height() / scale)
    painter.drawText(target, int(flags) | int(Qt.TextFlag.TextWordWrap), text)
    painter.restore()


def _paint_view(painter: QPainter, view: SheetView, box: QRectF, scale: float, labelled: np.ndarray) -> None:
    """The hand of ``view`` at ``scale`` (page mm per model mm) centred in ``box`` (mm), with its markers
    (hidden ones as dashed rings); the markers with ``labelled (k,)`` True get their number, placed so
    that numbers overlap neither each other nor a marker (with a leader line when moved away)."""
    xmin, ymin, xmax, ymax = view.bounds
    centre_x = box.center().x() - scale * (xmin + xmax) / 2.0
    centre_y = box.center().y() + scale * (ymin + ymax) / 2.0

    def page(points: np.ndarray) -> np.ndarray:
        out = np.empty_like(points, dtype=float)
        out[..., 0] = centre_x + scale * points[..., 0]
        out[..., 1] = centre_y - scale * points[..., 1]
        return out

    # the painter maps mm, so its x scale is device pixels per mm; the skin image is capped at ~300 dpi
    pixels_per_mm = min(max(abs(painter.worldTransform().m11()), 4.0), SKIN_PIXELS_PER_MM)
    shade, origin = rasterise_view(view, pixels_per_mm, scale)
    painter.drawImage(QRectF(centre_x - origin[0], centre_y - origin[1], shade.shape[1] / pixels_per_mm,
                             shade.shape[0] / pixels_per_mm), _skin_image(shade))

    markers = page(view.markers)
    centroid = page(np.array([[(xmin + xmax) / 2.0, (ymin + ymax) / 2.0]]))[0]
    labels = place_labels(markers, labelled, centroid, LABEL_SIZE_MM, MARKER_RADIUS_MM)
    painter.save()
    painter.setRenderHint(QPainter.RenderHint.Antialiasing, True)
    for point, label in zip(markers, labels, strict=True):          # leader lines under everything else
        if np.isfinite(label[0]) and np.linalg.norm(label - point) > LEADER_FROM_MM:
            painter.setPen(QPen(MUTED, 0.25))
            painter.drawLine(QPointF(*point), QPointF(*label))
    for number, (point, visible, label) in enumerate(zip(markers, view.visible, labels, strict=True), start=1):
        centre = QPointF(float(point[0]), float(point[1]))
        if visible:
            painter.setPen(QPen(QColor(255, 255, 255), 0.5))
            painter.setBrush(MARKER_FILL)
        else:
            pen = QPen(HIDDEN_MARKER, 0.45)
            pen.setStyle(Qt.PenStyle.DashLine)
            painter.setPen(pen)
            painter.setBrush(Qt.BrushStyle.NoBrush)
        painter.drawEllipse(centre, MARKER_RADIUS_MM, MARKER_RADIUS_MM)
        if not np.isfinite(label[0]):
            continue
        width, height = LABEL_SIZE_MM
        halo = QRectF(float(label[0]) - width / 2.0, float(label[1]) - height / 2.0, width, height)
        painter.setPen(Qt.PenStyle.NoPen)
        painter.setBrush(QColor(255, 255, 255, 215))
        painter.drawRoundedRect(halo, 1.0, 1.0)
        _text(painter, halo, str(number), 3.2, bold=True, colour=TEXT if visible else MUTED,
              flags=Qt.AlignmentFlag.AlignCenter)
    painter.restore()
    _text(painter, QRectF(box.x(), box.bottom() + 1.0, box.width(), 6.0), view.title, 3.6, bold=True,
          flags=Qt.AlignmentFlag.AlignHCenter | Qt.AlignmentFlag.AlignTop)


def _skin_image(shade: np.ndarray) -> QImage:
    """Skin-coloured RGBA image of a shade image ``(H, W)`` (NaN = transparent)."""
    inside = np.isfinite(shade)
    rgba = np.zeros((*shade.shape, 4), dtype=np.uint8)
    rgba[..., :3] = np.clip(SKIN * np.where(inside, shade, 0.0)[..., None], 0, 255).astype(np.uint8)
    rgba[..., 3] = np.where(inside, 255, 0)
    height, width = shade.shape
    return QImage(np.ascontiguousarray(rgba).data, width, height, 4 * width, QImage.Format.Format_RGBA8888).copy()


def paint_sheet(painter: QPainter, sheet: PlacementSheet) -> None:
    """Paint ``sheet`` on an A4 page; ``painter`` must already map millimetres (origin top left)."""
    width, height = PAGE_MM
    left, right = MARGIN_MM, width - MARGIN_MM
    painter.fillRect(QRectF(0, 0, width, height), QColor(255, 255, 255))
    _text(painter, QRectF(left, MARGIN_MM, right - left - 40, 10), sheet.title, 6.5, bold=True)
    _text(painter, QRectF(right - 40, MARGIN_MM + 1.5, 40, 6), sheet.date, 4.0, colour=MUTED,
          flags=Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignTop)
    _text(painter, QRectF(left, MARGIN_MM + 10, right - left, 10), sheet.subtitle, 3.3, colour=MUTED)
    painter.setPen(QPen(RULE, 0.3))
    painter.drawLine(QPointF(left, MARGIN_MM + 21), QPointF(right, MARGIN_MM + 21))

    rows = sheet.rows
    row_height = 6.0 if len(rows) <= 16 else max(3.4, 96.0 / len(rows))
    list_height = 10.0 + row_height * len(rows)
    views_top = MARGIN_MM + 27
    views_bottom = height - MARGIN_MM - list_height - 14
    widths = [view.bounds[2] - view.bounds[0] for view in sheet.views]
    heights = [view.bounds[3] - view.bounds[1] for view in sheet.views]
    gap = 14.0
    scale = min((right - left - gap * (len(widths) - 1)) / sum(widths),
                (views_bottom - views_top) / max(heights))
    x = left + ((right - left) - scale * sum(widths) - gap * (len(widths) - 1)) / 2.0
    seen = np.any([view.visible for view in sheet.views], axis=0)     # numbered where seen; else everywhere
    for view, view_width in zip(sheet.views, widths, strict=True):
        box = QRectF(x, views_top, scale * view_width, views_bottom - views_top)
        _paint_view(painter, view, box, scale, view.visible | ~seen)
        x += scale * view_width + gap

    bar_top = views_bottom + 8.0
    bar = 50.0 * scale                                # a 50 mm bar at the drawing's scale
    painter.setPen(QPen(TEXT, 0.4))
    painter.drawLine(QPointF(left, bar_top), QPointF(left + bar, bar_top))
    for tick in (left, left + bar):
        painter.drawLine(QPointF(tick, bar_top - 1.2), QPointF(tick, bar_top + 1.2))
    _text(painter, QRectF(left + bar + 2, bar_top - 2.2, right - left - bar - 2, 5),
          f"50 mm (drawing scale 1:{1 / scale:.1f}); dashed rings: hidden in this view, numbered in the other",
          3.0, colour=MUTED)

    top = height - MARGIN_MM - list_height
    columns = (left, left + 9, left + 42)
    for column, title in zip(columns, ("#", "Name", "Where"), strict=True):
        _text(painter, QRectF(column, top, 60, 6), title, 3.4, bold=True)
    painter.setPen(QPen(RULE, 0.3))
    painter.drawLine(QPointF(left, top + 6.5), QPointF(right, top + 6.5))
    size = min(3.1, row_height * 0.55)
    for index, row in enumerate(rows):
        y = top + 8.0 + index * row_height
        if index % 2:
            painter.fillRect(QRectF(left, y - 0.8, right - left, row_height), QColor(243, 245, 248))
        _text(painter, QRectF(columns[0], y, 10, row_height), str(row.number), size, bold=True)
        _text(painter, QRectF(columns[1], y, columns[2] - columns[1] - 1, row_height), row.name, size)
        _text(painter, QRectF(columns[2], y, right - columns[2], row_height), row.location, size)
    _text(painter, QRectF(left, height - MARGIN_MM + 3, right - left, 5),
          "Hand Mocap Studio — place each marker centre on the skin point shown; rest pose, fingers extended.",
          2.6, colour=MUTED)


def paint_full_scale_page(painter: QPainter, sheet: PlacementSheet) -> None:
    """Paint the back view of ``sheet`` at 1:1 on an A4 page (``painter`` maps millimetres), with a
    50 mm bar to check the print scale: a template to hold the subject's hand against."""
    width, height = PAGE_MM
    left, right = MARGIN_MM, width - MARGIN_MM
    view = sheet.views[0]
    seen = np.any([each.visible for each in sheet.views], axis=0)
    painter.fillRect(QRectF(0, 0, width, height), QColor(255, 255, 255))
    _text(painter, QRectF(left, MARGIN_MM - 4, right - left, 8), f"{sheet.title} — {view.title.lower()}, 1:1",
          5.0, bold=True)
    _text(painter, QRectF(left, MARGIN_MM + 3.5, right - left, 5),
          "Print at 100 % (no \"fit to page\"): the bar at the bottom must measure 50 mm.", 3.0, colour=MUTED)
    view_height = view.bounds[3] - view.bounds[1]
    box = QRectF(left, MARGIN_MM + 11, right - left, view_height)
    _paint_view(painter, view, box, 1.0, view.visible | ~seen)
    bar_top = height - MARGIN_MM - 4
    painter.setPen(QPen(TEXT, 0.4))
    painter.drawLine(QPointF(left, bar_top), QPointF(left + 50.0, bar_top))
    for tick in range(6):
        painter.drawLine(QPointF(left + 10.0 * tick, bar_top - (1.6 if tick % 5 == 0 else 0.9)),
                         QPointF(left + 10.0 * tick, bar_top + (1.6 if tick % 5 == 0 else 0.9)))
    _text(painter, QRectF(left + 53, bar_top - 2.2, right - left - 53, 5),
          "50 mm; numbers as on the first page", 3.0, colour=MUTED)


def render_sheet_image(sheet: PlacementSheet, dpi: int = PNG_DPI, full_scale: bool = False) -> QImage:
    """``sheet`` as an A4 image at ``dpi``: the overview page, or with ``full_scale`` the 1:1 page."""
    ensure_gui_application()
    per_mm = dpi / 25.4
    image = QImage(round(PAGE_MM[0] * per_mm), round(PAGE_MM[1] * per_mm), QImage.Format.Format_RGB32)
    image.setDotsPerMeterX(round(per_mm * 1000))
    image.setDotsPerMeterY(round(per_mm * 1000))
    image.fill(QColor(255, 255, 255))
    painter = QPainter(image)
    painter.setRenderHint(QPainter.RenderHint.TextAntialiasing, True)
    painter.scale(per_mm, per_mm)
    (paint_full_scale_page if full_scale else paint_sheet)(painter, sheet)
    painter.end()
    return image


def save_placement_sheet(sheet: PlacementSheet, path: str | Path, dpi: int = PNG_DPI) -> Path:
    """Write ``sheet`` to ``path``: ``.png`` (the overview page, A4 at ``dpi``) or ``.pdf`` (A4, vector: the
    overview and the back of the hand at 1:1). Returns the path;
    :class:`InputError` for another suffix or an unwritable path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".png", ".pdf"):
        raise InputError(f"{path.name}: a placement sheet is written as .png or .pdf")
    if not path.parent.exists():
        raise InputError(f"{path}: the folder {path.parent} does not exist")
    ensure_gui_application()
    with durable_path(path) as temporary:  # Qt writes by file name; the rename keeps the old file on failure
        if suffix == ".png":
            # PySide6's type hints want the format as bytes, but the binding takes only a str ("PNG")
            if not render_sheet_image(sheet, dpi).save(str(temporary), "PNG"):  # type: ignore[call-overload]
                raise InputError(f"{path}: could not write the image")
        else:
            writer = QPdfWriter(str(temporary))
            writer.setResolution(600)
            writer.setTitle(sheet.title)
            writer.setCreator("Hand Mocap Studio")
            writer.setPageLayout(QPageLayout(QPageSize(QPageSize.PageSizeId.A4), QPageLayout.Orientation.Portrait,
                                             QMarginsF(0, 0, 0, 0), QPageLayout.Unit.Millimeter))
            painter = QPainter()
            if not painter.begin(writer):
                raise InputError(f"{path}: could not write the PDF")
            per_mm = writer.resolution() / 25.4
            painter.scale(per_mm, per_mm)
            paint_sheet(painter, sheet)
            writer.newPage()
            paint_full_scale_page(painter, sheet)
            painter.end()
            if temporary.stat().st_size == 0:
                raise InputError(f"{path}: could not write the PDF")
    return path
