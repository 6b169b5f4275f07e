"""JSON Schemas of the JSON/TOML files users give (read through :func:`core.io.documents.read_document`).

Each types every field its reader uses; unknown fields are left alone unless said otherwise (a file a newer
version wrote keeps loading). What a schema cannot say well (a joint name, the surface distance of an
object's markers, a pipeline's choices) the reader checks after it, with its own one-line message.
"""

from __future__ import annotations

NUMBER = {"type": "number"}
TEXT = {"type": "string"}
#: ("x-message": what the reader says when the value is not of this form)
POINT = {"type": "array", "items": {"type": "number", "x-message": "must be [x, y, z] numbers (mm)"},
         "minItems": 3, "maxItems": 3, "x-message": "must be [x, y, z] numbers (mm)"}
MATRIX3 = {"type": "array", "items": POINT, "minItems": 3, "maxItems": 3}

#: one marker of a layout: on a mesh vertex, or between two joints (:mod:`core.model.markers`)
MARKER = {
    "type": "object",
    "required": ["name"],
    "properties": {
        "name": TEXT,
        "vertex": {"type": "integer", "minimum": 0},
        "between": {"type": "array", "items": TEXT, "minItems": 2, "maxItems": 2},
        "along": NUMBER,
        "side": {"type": ["string", "array"], "items": NUMBER, "minItems": 3, "maxItems": 3},
        "offset_mm": NUMBER,
        "digit": TEXT,
        "segment": {"type": "integer"},
    },
}

#: one rigid object of a scene spec or a lab template (:mod:`core.model.objects`)
OBJECT = {
    "type": "object",
    "required": ["name", "markers"],
    "properties": {
        "name": TEXT,
        "type": TEXT,
        "markers": {"type": "object", "additionalProperties": POINT},
        "size_mm": POINT,
        "radius_mm": NUMBER,
        "height_mm": NUMBER,
    },
}

SCENE_SPEC = {
    "type": "object",
    "required": ["objects"],
    "properties": {"objects": {"type": "array", "items": OBJECT}},
}

_TEMPLATE_HAND = {
    "type": "object",
    "required": ["markers"],
    "properties": {
        "markers": {"type": "array", "items": MARKER},
        "statistics": {
            "type": ["object", "null"],
            "properties": {"pairs": {"type": "array", "items": {
                "type": "object",
                "required": ["a", "b", "mean_mm", "sd_mm"],
                "properties": {"a": TEXT, "b": TEXT, "mean_mm": NUMBER, "sd_mm": NUMBER},
            }}},
        },
    },
}

#: a marker layout, or a lab's labelling template (a layout with hands, objects and statistics:
#: :mod:`core.model.lab_template`)
LAYOUT = {
    "type": "object",
    "properties": {
        "name": TEXT,
        "description": TEXT,
        "markers": {"type": "array", "items": MARKER},
        "template_version": {"type": "integer"},
        "learned_from": {"type": "array", "items": TEXT},
        "noise_mm": {"type": ["number", "null"]},
        "hands": {"type": "object", "properties": {"right": _TEMPLATE_HAND, "left": _TEMPLATE_HAND}},
        "objects": {"type": "array", "items": OBJECT},
    },
}

#: a landmark file of scan calibration (:mod:`core.calibration.landmarks`)
#: (the reader says which units and how many coordinates)
LANDMARKS = {
    "type": "object",
    "properties": {
        "units": TEXT,
        "landmarks": {"type": "object", "additionalProperties": {"type": ["array", "null"], "items": NUMBER}},
    },
}

#: a batch pipeline (:mod:`core.batch.pipeline`; the reader refuses unknown settings itself)
PIPELINE = {
    "type": "object",
    "properties": {
        "steps": {"type": "array", "items": TEXT},
        "layout": TEXT,
        "hands": TEXT,
        "objects": TEXT,
        "online": {"type": "boolean"},
        "relabel": {"type": "boolean"},
        "max_gap": {"type": "integer"},
        "fill_method": TEXT,
        "solve_method": TEXT,
        "exports": {"type": "array", "items": TEXT},
        "output": TEXT,
        "rate": NUMBER,
    },
}

#: our camera JSON (:mod:`core.camera.files`; ``format`` and ``version`` are checked by its reader)
CAMERA = {
    "type": "object",
    "required": ["image_size", "camera_matrix"],
    "properties": {
        "name": TEXT,
        "image_size": {"type": "array", "items": NUMBER, "minItems": 2, "maxItems": 2},
        "camera_matrix": MATRIX3,
        "distortion": {"type": "array", "items": NUMBER, "maxItems": 14},
        "registered": {"type": "boolean"},
        "rotation": MATRIX3,
        "translation_mm": POINT,
        "time_offset_s": NUMBER,
        "rate_ratio": NUMBER,
        "report": {"type": "object"},
    },
}

#: a marked board's markers (the camera wizard): ``{"markers": {"<take marker>": [x, y, z] mm}}``
BOARD_MARKERS = {
    "type": "object",
    "required": ["markers"],
    "properties": {"markers": {"type": "object", "additionalProperties": POINT, "minProperties": 3}},
}
