"""The ``SYSTEM_LABELS`` parameter group of a take recorded live (:mod:`core.live.recorder` writes it): what the
capture system's own labels were, read back for ``handmocap info`` without the live capture's imports."""

from __future__ import annotations

import numpy as np

SYSTEM_GROUP = "SYSTEM_LABELS"


def system_labels_summary(group: object) -> dict | None:
    """What a take's ``SYSTEM_LABELS`` parameter group (a live recording: the capture system's own labels)
    says: ``source``, ``labels`` (count), ``labelled_share`` (of the points) and the sidecar ``file`` holding
    them per point; None without the group or when its values are not what a recording writes."""
    if not isinstance(group, dict):
        return None

    def text(value: object) -> str:
        items = value if isinstance(value, list | tuple) else [value]
        return str(items[0]).strip() if items and isinstance(items[0], str) else ""

    def number(value: object) -> float | None:
        try:
            values = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            return None
        return float(values[0]) if values.size and np.isfinite(values[0]) else None

    share, count = number(group.get("SHARE")), number(group.get("COUNT"))
    if share is None or count is None:
        return None
    return {"source": text(group.get("SOURCE")) or "the capture system", "labels": int(count),
            "labelled_share": round(share, 4), "file": text(group.get("FILE"))}
