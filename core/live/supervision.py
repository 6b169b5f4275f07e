"""What the operator is told while the subject performs: per hand and object, from the live labels.

Per model (a hand or a rigid object of the scene) :class:`Supervisor` keeps, over the last second: the
labelled share (markers labelled / markers of the model), the markers missing now and since when, the swap
suspects (markers labelled with a confidence margin below :data:`SWAP_MARGIN_MM` in more than a fifth of the
frames: two candidates nearly as good, the labels may exchange), the noise (RMS of the fit residuals, mm),
and a traffic light: red when the model is lost (fewer than half its markers) for more than
:data:`LOST_SECONDS` or labels under 60 %, amber under 90 %, with a marker unseen for ``unseen_seconds``,
swap suspects or a noisy fit, green otherwise. Alarms: a hand lost for more than :data:`LOST_SECONDS`, a
marker not seen for ``unseen_seconds`` (it fell off?). :meth:`Supervisor.summary` at the end names what
should make the operator retake ("ring tip missing 38 % of the take: retake?").
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

LOST_SECONDS = 0.5
UNSEEN_SECONDS = 3.0
SWAP_MARGIN_MM = 1.0
NOISY_MM = 3.0
RETAKE_MISSING = 0.2
LIGHTS = ("green", "amber", "red")


@dataclass
class ModelStatus:
    """The state of one model now (module docstring)."""

    name: str
    kind: str
    labelled_share: float = 0.0
    missing: dict[str, float] = field(default_factory=dict)      # marker -> seconds missing
    swap_suspects: list[str] = field(default_factory=list)
    noise_mm: float | None = None
    light: str = "red"
    lost_seconds: float = 0.0
    tracked: bool = False

    def as_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "labelled_share": round(self.labelled_share, 3),
                "missing": {name: round(seconds, 2) for name, seconds in self.missing.items()},
                "swap_suspects": list(self.swap_suspects),
                "noise_mm": None if self.noise_mm is None else round(self.noise_mm, 2), "light": self.light,
                "lost_seconds": round(self.lost_seconds, 2)}


def readable(name: str) -> str:
    """``ring_tip`` -> ``ring tip`` (for the operator)."""
    return name.replace("_", " ").strip()


class Supervisor:
    """Keeps the status of each model from the live labels of each frame (module docstring).

    ``models``: (name, kind, marker slice) of the scene in marker order; ``marker_names`` (M,)."""

    def __init__(self, models: list[tuple[str, str, slice]], marker_names: list[str], frame_rate: float,
                 unseen_seconds: float = UNSEEN_SECONDS) -> None:
        self.models, self.marker_names = models, list(marker_names)
        self.frame_rate = float(frame_rate) if frame_rate and frame_rate > 0 else 100.0
        self.unseen_seconds = unseen_seconds
        window = max(1, round(self.frame_rate))
        self.labelled: deque[np.ndarray] = deque(maxlen=window)
        self.residuals: deque[np.ndarray] = deque(maxlen=window)
        self.ambiguous: deque[np.ndarray] = deque(maxlen=window)
        count = len(marker_names)
        self.missing_run = np.zeros(count, dtype=np.int64)
        self.missing_total = np.zeros(count, dtype=np.int64)
        self.lost_run = np.zeros(len(models), dtype=np.int64)
        self.lost_total = np.zeros(len(models), dtype=np.int64)
        self.first_tracked = np.full(len(models), -1, dtype=np.int64)
        self.frames = 0
        self.alarms: list[str] = []
        self._alarmed: set[str] = set()

    def update(self, assignment: np.ndarray, residuals: np.ndarray, confidence: np.ndarray) -> list[str]:
        """Add one frame's live labels; returns the alarms raised by it (one line each)."""
        labelled = assignment >= 0
        self.labelled.append(labelled)
        self.residuals.append(np.where(labelled, residuals, np.nan))
        self.ambiguous.append(labelled & (np.nan_to_num(confidence, nan=np.inf) < SWAP_MARGIN_MM))
        raised = []
        for number, (name, kind, markers) in enumerate(self.models):
            share = labelled[markers].mean() if markers.stop > markers.start else 0.0
            if share > 0 and self.first_tracked[number] < 0:
                self.first_tracked[number] = self.frames
            tracked = self.first_tracked[number] >= 0
            lost = tracked and share < 0.5
            self.lost_run[number] = self.lost_run[number] + 1 if lost else 0
            self.lost_total[number] += int(lost)
            if tracked:
                self.missing_run[markers] = np.where(labelled[markers], 0, self.missing_run[markers] + 1)
                self.missing_total[markers] += ~labelled[markers]
            key = f"lost:{name}"
            what = "hand" if kind in ("right", "left") else "object"
            if self.lost_run[number] / self.frame_rate > LOST_SECONDS:
                if key not in self._alarmed:
                    self._alarmed.add(key)
                    raised.append(f"the {name} {what} is lost (fewer than half its markers for more than "
                                  f"{LOST_SECONDS:g} s)")
            else:
                self._alarmed.discard(key)
            for marker in range(markers.start, markers.stop):
                key = f"unseen:{marker}"
                if self.missing_run[marker] / self.frame_rate >= self.unseen_seconds:
                    if key not in self._alarmed:
                        self._alarmed.add(key)
                        raised.append(f"{readable(self.marker_names[marker])} ({name}) not seen for "
                                      f"{self.unseen_seconds:g} s: has the marker fallen off?")
                elif self.missing_run[marker] == 0:
                    self._alarmed.discard(key)
        self.frames += 1
        self.alarms += raised
        return raised

    def status(self) -> list[ModelStatus]:
        """The status of each model now."""
        if not self.labelled:
            return [ModelStatus(name, kind) for name, kind, _ in self.models]
        labelled = np.array(self.labelled)
        residuals = np.array(self.residuals)
        ambiguous = np.array(self.ambiguous)
        statuses = []
        for number, (name, kind, markers) in enumerate(self.models):
            block = labelled[:, markers]
            share = float(block.mean()) if block.size else 0.0
            values = residuals[:, markers]
            noise = float(np.sqrt(np.nanmean(values ** 2))) if np.isfinite(values).any() else None
            missing = {self.marker_names[marker]: self.missing_run[marker] / self.frame_rate
                       for marker in range(markers.start, markers.stop) if self.missing_run[marker] > 0}
            swaps = [self.marker_names[marker] for marker in range(markers.start, markers.stop)
                     if ambiguous[:, marker].mean() > 0.2]
            lost = self.lost_run[number] / self.frame_rate
            unseen = any(seconds >= self.unseen_seconds for seconds in missing.values())
            if lost > LOST_SECONDS or share < 0.6:
                light = "red"
            elif share < 0.9 or unseen or swaps or (noise is not None and noise > NOISY_MM):
                light = "amber"
            else:
                light = "green"
            statuses.append(ModelStatus(name, kind, share, missing, swaps, noise, light, lost,
                                        bool(self.first_tracked[number] >= 0)))
        return statuses

    def summary(self) -> list[str]:
        """What to tell the operator at the end of the capture (empty when all went well)."""
        lines = []
        for number, (name, kind, markers) in enumerate(self.models):
            what = "hand" if kind in ("right", "left") else "object"
            first = self.first_tracked[number]
            if first < 0:
                lines.append(f"the {name} {what} was never found: retake?")
                continue
            span = max(self.frames - first, 1)
            lost = self.lost_total[number] / span
            if lost > RETAKE_MISSING:
                lines.append(f"the {name} {what} was lost {100 * lost:.0f} % of the take: retake?")
            for marker in range(markers.start, markers.stop):
                share = self.missing_total[marker] / span
                if share > RETAKE_MISSING:
                    lines.append(f"{readable(self.marker_names[marker])} missing {100 * share:.0f} % of the take: "
                                 "retake?")
        return lines
