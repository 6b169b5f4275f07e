"""Events of a take (named frames: grasp on, grasp off, a foot strike...) in the C3D ``EVENT`` parameter group.

The group, as Vicon Nexus, Qualisys and Motion Analysis write it: ``USED`` (the count), ``LABELS`` (the name,
e.g. "Foot Strike"), ``CONTEXTS`` ("Left", "Right", "General"; some programs put the name there and leave the
label empty), ``DESCRIPTIONS``, ``SUBJECTS``, ``ICON_IDS``, ``GENERIC_FLAGS`` and ``TIMES`` (2 x N: minutes
and seconds). A time is measured from the first frame of the acquisition, frame number 1: frame number
``round(time x rate) + 1`` (the convention of Nexus and btk), whatever the file's first frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

GROUP = "EVENT"
CONTEXTS = ("General", "Left", "Right")


@dataclass(frozen=True)
class TakeEvent:
    """A named frame of a take: ``name``, the file's ``frame_number`` (as the timeline shows it), its
    ``context`` ("General", "Left", "Right" or a program's own) and a ``description``."""

    name: str
    frame_number: int
    context: str = "General"
    description: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "frame_number": self.frame_number, "context": self.context,
                "description": self.description}

    @staticmethod
    def from_dict(values: dict[str, Any]) -> TakeEvent:
        return TakeEvent(str(values["name"]), int(values["frame_number"]), str(values.get("context", "General")),
                         str(values.get("description", "")))


def _strings(group: dict[str, Any], key: str, count: int) -> list[str]:
    values = group.get(key, [])
    values = [values] if isinstance(values, str) else [str(value) for value in list(values)]
    return [value.strip() for value in values[:count]] + [""] * max(0, count - len(values))


def read_events(parameters: dict[str, dict[str, Any]], frame_rate: float) -> list[TakeEvent]:
    """The events of a take's C3D parameters (module docstring), by frame; none when the group is missing or
    holds no usable time (a damaged group is read as far as it is whole)."""
    group = parameters.get(GROUP) or parameters.get(GROUP.lower()) or {}
    if not isinstance(group, dict) or frame_rate <= 0:
        return []
    try:
        times = np.asarray(group.get("TIMES", []), dtype=np.float64)
    except (TypeError, ValueError):
        return []
    if times.ndim == 2 and times.shape[0] == 2:
        seconds = 60.0 * times[0] + times[1]
    elif times.ndim == 1:
        seconds = times
    else:
        return []
    try:
        used = int(np.asarray(group.get("USED", len(seconds))).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        used = len(seconds)
    count = max(0, min(used, len(seconds)))
    labels, contexts = _strings(group, "LABELS", count), _strings(group, "CONTEXTS", count)
    descriptions = _strings(group, "DESCRIPTIONS", count)
    events = []
    for index in range(count):
        if not np.isfinite(seconds[index]):
            continue
        name = labels[index] or contexts[index] or f"event {index + 1}"
        context = contexts[index] if labels[index] and contexts[index] else "General"
        events.append(TakeEvent(name, int(round(seconds[index] * frame_rate)) + 1, context, descriptions[index]))
    return sorted(events, key=lambda event: (event.frame_number, event.name))


def event_group(events: list[TakeEvent], frame_rate: float) -> dict[str, Any]:
    """The C3D ``EVENT`` group of ``events`` (module docstring); empty (no group) when there are none."""
    if not events:
        return {}
    seconds = np.array([(event.frame_number - 1) / frame_rate for event in events])
    minutes = np.floor(seconds / 60.0)
    return {"USED": len(events), "LABELS": [event.name for event in events],
            "CONTEXTS": [event.context for event in events],
            "DESCRIPTIONS": [event.description or " " for event in events],
            "SUBJECTS": [" " for _ in events], "TIMES": np.stack([minutes, seconds - 60.0 * minutes]),
            "ICON_IDS": np.zeros(len(events), dtype=np.int16), "GENERIC_FLAGS": np.zeros(len(events), dtype=np.int16)}
