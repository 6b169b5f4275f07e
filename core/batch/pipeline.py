"""The pipeline file of a batch: which steps run on every take and with which settings.

One flat TOML (or JSON) table, written by the GUI and read by ``handmocap batch``::

    steps = ["label", "calibrate", "fill", "solve", "export"]   # any of them, in this order
    layout = "glove-13"          # marker layout (name or JSON file) the labeller uses
    hands = "auto"               # auto, right, left or both
    objects = ""                 # rigid objects spec JSON ("" none)
    online = false               # causal labelling only
    relabel = false              # ignore the labels the file already has
    max_gap = 20                 # longest gap filled (frames)
    fill_method = "auto"
    solve_method = "layered"
    exports = ["c3d", "angles-csv", "bvh"]   # any registered export format (core.review.export_formats)
    output = "exports"           # folder of the exports ("" = <session>/exports)
    rate = 120.0                 # frame rate (Hz) of the takes whose file states none (NOKOV CSV); 0: none

Relative file names (``layout`` when it names a file, ``objects``, ``output``) are relative to the
pipeline file's folder. Every error is one line naming the file and the setting. ``rate`` is used when a
take is added to the session (a folder of takes): a take keeps the rate it was added with, so the rate is
not part of what decides whether a take is redone. ``exports`` are the names ``handmocap export --format``
takes: "csv" is the labelled markers (as in a Vicon Nexus or Motive CSV export), "angles-csv" the joint angles
(before :data:`PIPELINE_VERSION` 2, "csv" was the joint angles).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from handmocap.core.errors import InputError
from handmocap.core.gaps import fill_choices
from handmocap.core.io.documents import read_document
from handmocap.core.io.input_schemas import PIPELINE
from handmocap.core.review.export_formats import export_format_names

STEPS = ("label", "calibrate", "fill", "solve", "export")
HANDS = ("auto", "right", "left", "both")
SOLVE_METHODS = ("layered", "subspace", "full")
#: changes whenever what a pipeline computes changes, so that a re-run redoes every take (2: "csv" is markers)
PIPELINE_VERSION = 2


@dataclass(frozen=True)
class Pipeline:
    """The settings of a batch (module docstring); paths are absolute once loaded."""

    steps: tuple[str, ...] = STEPS
    layout: str = "dense"
    hands: str = "auto"
    objects: str = ""
    online: bool = False
    relabel: bool = False
    max_gap: int = 20
    fill_method: str = "auto"
    solve_method: str = "layered"
    exports: tuple[str, ...] = ("c3d", "angles-csv")
    output: str = ""
    rate: float = 0.0

    def runs(self, step: str) -> bool:
        return step in self.steps

    def to_dict(self) -> dict[str, Any]:
        """The settings as plain JSON-ready values (lists for tuples)."""
        data = asdict(self)
        return {key: list(value) if isinstance(value, tuple) else value for key, value in data.items()}

    def key(self) -> str:
        """A hash of everything that decides the results: the settings, the objects spec's content and
        :data:`PIPELINE_VERSION` (hex sha256)."""
        data = self.to_dict() | {"version": PIPELINE_VERSION}
        data.pop("output")
        data.pop("rate")      # recorded with each take when it is added (module docstring)
        data["objects_content"] = hashlib.sha256(Path(self.objects).read_bytes()).hexdigest() if self.objects else ""
        if self.layout.lower().endswith(".json") and Path(self.layout).is_file():
            data["layout_content"] = hashlib.sha256(Path(self.layout).read_bytes()).hexdigest()
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


_KINDS: dict[str, type] = {"steps": list, "layout": str, "hands": str, "objects": str, "online": bool,
                           "relabel": bool, "max_gap": int, "fill_method": str, "solve_method": str,
                           "exports": list, "output": str, "rate": float}


def pipeline_from_dict(data: dict[str, Any], source: str = "pipeline", base: Path | None = None) -> Pipeline:
    """A checked :class:`Pipeline` from ``data`` (missing settings take their defaults); relative paths
    are made absolute against ``base``. InputError (one line, naming ``source``) on any bad setting."""
    if not isinstance(data, dict):
        raise InputError(f"{source}: a pipeline is a table of settings")
    unknown = sorted(set(data) - set(_KINDS))
    if unknown:
        raise InputError(f"{source}: unknown setting {_quoted(unknown[0])} (known: {', '.join(_KINDS)})")
    if type(data.get("rate")) is int:      # TOML and JSON write 120 for 120.0
        data = data | {"rate": float(data["rate"])}
    for name, value in data.items():
        kind = _KINDS[name]
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise InputError(f"{source}: setting '{name}' must be {_KIND_TEXT[kind]}, not {value!r:.40}")
    values = {name: data[name] for name in _KINDS if name in data}
    steps = _choices(values.get("steps", list(STEPS)), STEPS, "steps", source)
    values["steps"] = tuple(step for step in STEPS if step in steps)
    values["exports"] = tuple(_choices(values.get("exports", ["c3d", "angles-csv"]), export_format_names(), "exports",
                                       source))
    _one_of(values.get("hands", "auto"), HANDS, "hands", source)
    _one_of(values.get("fill_method", "auto"), fill_choices(), "fill_method", source)
    _one_of(values.get("solve_method", "layered"), SOLVE_METHODS, "solve_method", source)
    if not (math.isfinite(values.get("rate", 0.0)) and values.get("rate", 0.0) >= 0):
        raise InputError(f"{source}: setting 'rate' must be a positive number of Hz (0: none given)")
    if values.get("max_gap", 20) < 1:
        raise InputError(f"{source}: setting 'max_gap' must be at least 1 frame")
    if "export" in values["steps"] and not values["exports"]:
        raise InputError(f"{source}: the export step needs at least one of exports = {list(export_format_names())}")
    if not values.get("layout", "dense").strip():
        raise InputError(f"{source}: setting 'layout' is empty")
    base = base or Path.cwd()
    for name in ("objects", "output"):
        if values.get(name):
            values[name] = str((base / Path(values[name]).expanduser()).absolute())
    layout = values.get("layout", "dense")
    if layout.lower().endswith(".json"):
        values["layout"] = str((base / Path(layout).expanduser()).absolute())
    if values.get("objects") and not Path(values["objects"]).is_file():
        raise InputError(f"{source}: the objects spec {values['objects']} does not exist")
    return Pipeline(**values)


_KIND_TEXT = {list: "a list", str: "text", bool: "true or false", int: "a whole number", float: "a number"}


def _choices(value: list, allowed: tuple[str, ...], name: str, source: str) -> list[str]:
    for item in value:
        _one_of(item, allowed, name, source)
    return list(dict.fromkeys(value))


def _one_of(value: Any, allowed: tuple[str, ...], name: str, source: str) -> None:
    if value not in allowed:
        raise InputError(f"{source}: setting '{name}' has {_quoted(value)}; use {', '.join(allowed)}")


def _quoted(value: Any) -> str:
    """``value`` quoted on one line, cut to 40 characters (a setting may hold anything)."""
    text = f"'{value}'" if isinstance(value, str) and value.isprintable() else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def load_pipeline(path: str | Path) -> Pipeline:
    """Read a pipeline file (``.toml``, else JSON). InputError (one line) when missing or malformed."""
    path = Path(path).expanduser().absolute()
    data = read_document(path, "pipeline", PIPELINE, source=str(path))
    return pipeline_from_dict(data, str(path), path.parent)


def pipeline_toml(pipeline: Pipeline) -> str:
    """The pipeline as TOML text (the flat table of the module docstring; paths absolute)."""
    lines = ["# Hand Mocap Studio batch pipeline (handmocap batch SESSION --pipeline this.toml)"]
    for item in fields(Pipeline):
        lines.append(f"{item.name} = {_toml_value(getattr(pipeline, item.name))}")
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    # a JSON string is a valid TOML basic string once DEL is escaped too (TOML forbids it raw)
    return json.dumps(str(value), ensure_ascii=False).replace("\x7f", "\\u007f")


def save_pipeline(pipeline: Pipeline, path: str | Path) -> None:
    """Write ``pipeline`` as TOML (``.toml``) or JSON, atomically."""
    from handmocap.core.io.durable import write_text_atomic

    path = Path(path)
    text = pipeline_toml(pipeline) if path.suffix.lower() == ".toml" else json.dumps(pipeline.to_dict(), indent=2)
    write_text_atomic(path, text)
