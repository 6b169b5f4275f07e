"""A lab's labelling template: its marker set per hand side, its names, its statistics and its objects.

What QTM calls an AIM model and Nexus a labelling skeleton template, learned from takes the lab labelled
(:mod:`core.labelling.templates`). The JSON file is a marker layout (:mod:`core.model.markers`) with more
fields, so every reader of layouts still reads it (its ``markers`` are those of its first hand)::

    {"name": "guitar-lab", "description": "...", "template_version": 1,
     "learned_from": ["arpeggio.csv"], "noise_mm": 0.21,
     "markers": [... the first hand's markers, as in "hands" ...],
     "hands": {
        "left":  {"markers": [{"name": "L-A1", "between": ["thumb_ip", "thumb_tip"], "along": 0.62,
                               "side": [0.1, 0.0, -0.99], "offset_mm": 5.1, "digit": "thumb",
                               "segment": 3}, ...],
                  "statistics": {"pairs": [{"a": "L-A1", "b": "L-A2", "mean_mm": 28.6, "sd_mm": 1.7}, ...]}},
        "right": {...}},
     "objects": [{"name": "Marker", "type": "rigid", "markers": {"Marker1": [x, y, z], ...}}]}

- ``hands``: one entry per side the lab's takes show (``right``, ``left``). Each marker's ``name`` is the
  lab's own name, written back exactly in every output; its placement (``between``/``along``/``side``/
  ``offset_mm``) is the layout form of :mod:`core.model.markers`, fitted per side (a subject's two hands are
  not mirror images); ``digit`` (thumb … little, or ``palm``) and ``segment`` (1 proximal … 3 distal, 0 on
  the palm) say where it was found to sit.
- ``statistics.pairs``: for every pair of markers of the hand, the mean and standard deviation (mm) of
  their distance over the learning takes; the labeller uses them to tell markers apart and to judge
  whole-take hypotheses.
- ``objects``: rigid objects in the scene-spec form of :mod:`core.model.objects` (marker positions in mm in
  the object's own frame).
- ``noise_mm``: the marker noise σ (mm) measured on the learning takes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.documents import read_document
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.input_schemas import LAYOUT
from handmocap.core.model.markers import MAX_LAYOUT_BYTES, MarkerLayout, layout_folders, load_layout
from handmocap.core.model.objects import ObjectSpec, check_unique_names, object_from_json

TEMPLATE_VERSION = 1
SIDES = ("right", "left")


@dataclass(frozen=True, eq=False)
class PairStatistics:
    """Distances between the markers of one hand: ``names (M,)``, ``mean_mm (M,M)`` and ``sd_mm (M,M)``
    (NaN where a pair was never seen together; the diagonal is 0)."""

    names: tuple[str, ...]
    mean_mm: np.ndarray
    sd_mm: np.ndarray

    def to_json(self) -> dict:
        pairs = []
        for a in range(len(self.names)):
            for b in range(a + 1, len(self.names)):
                if np.isfinite(self.mean_mm[a, b]):
                    pairs.append({"a": self.names[a], "b": self.names[b],
                                  "mean_mm": round(float(self.mean_mm[a, b]), 3),
                                  "sd_mm": round(float(self.sd_mm[a, b]), 3)})
        return {"pairs": pairs}

    @classmethod
    def from_json(cls, data: object, names: list[str], source: str) -> PairStatistics:
        """Parse ``{"pairs": [...]}`` for the markers ``names``; :class:`InputError` when malformed."""
        count = len(names)
        mean, sd = np.full((count, count), np.nan), np.full((count, count), np.nan)
        np.fill_diagonal(mean, 0.0)
        np.fill_diagonal(sd, 0.0)
        if data is None:
            return cls(tuple(names), mean, sd)
        index = {name: i for i, name in enumerate(names)}
        if not isinstance(data, dict) or not isinstance(data.get("pairs", []), list):
            raise InputError(f"{source}: 'statistics' must be {{\"pairs\": [...]}}")
        for pair in data.get("pairs", []):
            try:
                a, b = index[str(pair["a"])], index[str(pair["b"])]
                mean_mm, sd_mm = float(pair["mean_mm"]), float(pair["sd_mm"])
            except (KeyError, TypeError, ValueError):
                raise InputError(f"{source}: a statistics pair needs 'a', 'b' (marker names of the hand), "
                                 "'mean_mm' and 'sd_mm'") from None
            if not (np.isfinite(mean_mm) and np.isfinite(sd_mm) and mean_mm >= 0 and sd_mm >= 0):
                raise InputError(f"{source}: statistics of {pair['a']}-{pair['b']} must be finite and >= 0")
            mean[a, b] = mean[b, a] = mean_mm
            sd[a, b] = sd[b, a] = sd_mm
        return cls(tuple(names), mean, sd)


@dataclass(frozen=True, eq=False)
class TemplateHand:
    """One side of a template: its ``layout`` (the lab's marker names and their fitted placement), where
    each marker was found to sit (``digits``, ``segments``, per marker) and its pair ``statistics``."""

    side: str
    layout: MarkerLayout
    digits: tuple[str, ...]
    segments: tuple[int, ...]
    statistics: PairStatistics

    @property
    def names(self) -> list[str]:
        """The lab's names of this hand's markers."""
        return self.layout.names


@dataclass(frozen=True, eq=False)
class LabTemplate:
    """A lab's labelling template (module docstring): ``hands`` per side, rigid ``objects``."""

    name: str
    hands: dict[str, TemplateHand]
    objects: tuple[ObjectSpec, ...] = ()
    description: str = ""
    learned_from: tuple[str, ...] = ()
    noise_mm: float | None = None
    extra: dict = field(default_factory=dict)

    @property
    def sides(self) -> list[str]:
        """The sides the template has a hand for, right first."""
        return [side for side in SIDES if side in self.hands]

    @property
    def marker_names(self) -> list[str]:
        """Every name the template labels: the hands' then the objects' markers."""
        return [name for side in self.sides for name in self.hands[side].names] + [
            name for spec in self.objects for name in spec.marker_names]

    def layout_for(self, side: str) -> MarkerLayout:
        """The layout of ``side``; a side the template lacks gets the other side's placement (mirrored by the
        model) under the same names. The layout carries the template's name (what a labelled C3D records)."""
        hand = self.hands[side] if side in self.hands else self.hands[self.sides[0]]
        return replace(hand.layout, name=self.name)

    def to_json(self) -> dict:
        first = self.hands[self.sides[0]]
        hands = {}
        for side in self.sides:
            hand = self.hands[side]
            markers = []
            for spec, digit, segment in zip(hand.layout.markers, hand.digits, hand.segments, strict=True):
                markers.append({**spec.to_json(), "digit": digit, "segment": int(segment)})
            hands[side] = {"markers": markers, "statistics": hand.statistics.to_json()}
        data: dict = {"name": self.name, "description": self.description, "template_version": TEMPLATE_VERSION,
                      "learned_from": list(self.learned_from)}
        if self.noise_mm is not None:
            data["noise_mm"] = round(float(self.noise_mm), 4)
        data["markers"] = first.layout.to_json()["markers"]
        data["hands"] = hands
        data["objects"] = [spec.to_json() for spec in self.objects]
        return data

    @classmethod
    def from_json(cls, data: object, source: str = "template") -> LabTemplate:
        """Parse and validate a template dictionary; :class:`InputError` with one clear line."""
        if not isinstance(data, dict) or not isinstance(data.get("hands"), dict) or not data["hands"]:
            raise InputError(f"{source}: not a labelling template (it needs a \"hands\" object)")
        hands = {}
        for side, entry in data["hands"].items():
            if side not in SIDES:
                raise InputError(f"{source}: unknown hand side '{side}' (use right or left)")
            if not isinstance(entry, dict) or not isinstance(entry.get("markers"), list):
                raise InputError(f"{source}: the {side} hand needs a \"markers\" list")
            layout = MarkerLayout.from_json({"name": f"{data.get('name', source)} {side}",
                                             "markers": entry["markers"]}, source)
            digits = tuple(str(marker.get("digit", "")) for marker in entry["markers"])
            try:
                segments = tuple(int(marker.get("segment", 0)) for marker in entry["markers"])
            except (TypeError, ValueError):
                raise InputError(f"{source}: a marker's 'segment' must be a whole number") from None
            statistics = PairStatistics.from_json(entry.get("statistics"), layout.names, source)
            hands[side] = TemplateHand(side, layout, digits, segments, statistics)
        objects_data = data.get("objects", [])
        if not isinstance(objects_data, list):
            raise InputError(f"{source}: 'objects' must be a list")
        objects = tuple(object_from_json(entry, source) for entry in objects_data)
        names = [name for hand in hands.values() for name in hand.names]
        if len({name.lower() for name in names}) != len(names):
            raise InputError(f"{source}: the two hands share a marker name; each marker needs its own name")
        check_unique_names(list(objects), source, names)
        noise = data.get("noise_mm")
        try:
            noise_mm = None if noise is None else float(noise)
        except (TypeError, ValueError):
            raise InputError(f"{source}: 'noise_mm' must be a number") from None
        learned = data.get("learned_from", [])
        return cls(name=str(data.get("name", source)), hands=hands, objects=objects,
                   description=str(data.get("description", "")),
                   learned_from=tuple(str(item) for item in learned) if isinstance(learned, list) else (),
                   noise_mm=noise_mm)


def is_template_data(data: object) -> bool:
    """True when a parsed layout JSON is a labelling template (it has ``hands``)."""
    return isinstance(data, dict) and "hands" in data


def load_lab_template(name_or_path: str | Path) -> LabTemplate | None:
    """The template in a layout file (name or path, as :func:`core.model.load_layout` finds it), or None when
    that layout is a plain one. :class:`InputError` when it cannot be read or is malformed."""
    path = layout_path(name_or_path)
    if path is None:
        load_layout(name_or_path)  # says which layouts there are
        return None
    data = read_document(path, "marker layout", LAYOUT, max_bytes=MAX_LAYOUT_BYTES)
    return LabTemplate.from_json(data, path.name) if is_template_data(data) else None


def layout_path(name_or_path: str | Path) -> Path | None:
    """The file a layout name or path refers to (None when there is none)."""
    path = Path(name_or_path)
    if path.suffix:
        return path if path.is_file() else None
    return next((folder / f"{name_or_path}.json" for folder in layout_folders()
                 if (folder / f"{name_or_path}.json").is_file()), None)


def save_lab_template(template: LabTemplate, path: str | Path) -> None:
    """Write ``template`` as JSON durably (:mod:`core.io.durable`)."""
    write_text_atomic(path, json.dumps(template.to_json(), indent=1))
