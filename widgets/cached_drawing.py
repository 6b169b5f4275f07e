"""Plot items that paint from a cached pixmap: a cursor moving over them (a frame step) repaints no curve,
lane or band, only the pixmap's strip under the cursor."""

from __future__ import annotations

from PySide6.QtWidgets import QGraphicsItem


def paint_from_cache(*items: QGraphicsItem) -> None:
    """Cache each item's drawing, and its child items' (a pyqtgraph PlotDataItem draws through its curve), in
    device coordinates (redrawn when the view's range or size changes)."""
    for item in items:
        for part in (item, *item.childItems()):
            part.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
