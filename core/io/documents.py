"""The one bounded reader of every JSON and TOML file a user gives: layouts and lab templates, scene specs,
landmarks, pipelines, camera files, board marker files.

:func:`read_document` checks, in this order and before anything large is allocated: that the path is a
regular file (not a FIFO, a device or a folder) of at most ``max_bytes``; that it is UTF-8; that its
brackets nest at most ``max_depth`` deep (counted on the text, so that neither parser recurses into a
hostile file); then parses it (JSON without NaN or infinities; TOML), checks the parsed document's depth
again (TOML's dotted keys and tables nest too) and that every number is finite, and finally checks the
type of every field against a JSON Schema (compiled once with ``fastjsonschema``). Every failure is one
:class:`DocumentError` line naming the file and, for a schema failure, the field::

    layout.json: not a marker layout: 'markers[3].along' must be a number, not 'x'

The schemas live with the readers that use them (:mod:`core.io.input_schemas`); they type every field
the program reads and leave unknown fields alone (a newer file keeps loading), except where a reader
refuses unknown fields itself (pipelines).
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import fastjsonschema

from handmocap.core.errors import InputError

#: default largest file (bytes) and deepest nesting of a document
MAX_BYTES = 1_000_000
MAX_DEPTH = 32

_JSON_STRINGS = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"?', re.DOTALL)
_TOML_SKIPPED = re.compile(r'"""[\s\S]*?(?:"""|$)|\'\'\'[\s\S]*?(?:\'\'\'|$)|"[^"\\\n]*(?:\\.[^"\\\n]*)*"?'
                           r"|'[^'\n]*'?|#[^\n]*")
_BRACKETS = re.compile(r"[\[\]{}]")
_VALIDATORS: dict[int, tuple[dict, Callable[[Any], Any]]] = {}
_TYPE_TEXT = {"integer": "a whole number", "number": "a number", "string": "text", "boolean": "true or false",
              "array": "a list", "object": "an object", "null": "null"}


class DocumentError(InputError):
    """A JSON/TOML input that cannot be used: missing, too large, too deep, malformed or of the wrong form."""


def read_document(path: str | os.PathLike[str], what: str, schema: dict | None = None, *,
                  max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH, kind: str | None = None,
                  source: str | None = None) -> Any:
    """The parsed JSON (or TOML: ``kind="toml"``, or a ``.toml`` suffix when ``kind`` is None) document in
    ``path``, checked as the module docstring says; ``what`` names the document in messages ("marker
    layout"), ``source`` the file (default: its name). :class:`DocumentError` (one line) for anything that
    is not such a document."""
    path = Path(path)
    kind = kind or ("toml" if path.suffix.lower() == ".toml" else "json")
    data = read_limited(path, what, max_bytes)
    return parse_document(data, source or path.name, what, schema, max_depth=max_depth, kind=kind)


def read_limited(path: Path, what: str, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path`` (at most ``max_bytes``; never blocks on a FIFO or a device)."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise DocumentError(f"cannot read the {what} {path} (no such file)") from None
    except OSError as error:
        raise DocumentError(f"cannot read the {what} {path} ({error.strerror or error})") from None
    if not stat.S_ISREG(info.st_mode):
        raise DocumentError(f"{path}: not a file (a {what} is a file)")
    if info.st_size > max_bytes:
        raise DocumentError(f"{path.name}: {info.st_size} bytes is too large for a {what} (limit {max_bytes})")
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(descriptor, "rb") as stream:
            if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
                raise DocumentError(f"{path}: not a file (a {what} is a file)")
            data = stream.read(max_bytes + 1)
    except OSError as error:
        raise DocumentError(f"cannot read the {what} {path} ({error.strerror or error})") from None
    if len(data) > max_bytes:
        raise DocumentError(f"{path.name}: more than {max_bytes} bytes is too large for a {what}")
    return data


def parse_document(data: bytes | str, source: str, what: str, schema: dict | None = None, *,
                   max_depth: int = MAX_DEPTH, kind: str = "json") -> Any:
    """Parse and check a JSON or TOML document given as bytes or text (:func:`read_document` without the
    file); ``source`` names it in messages."""
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as error:
            raise DocumentError(f"{source}: not a {what} (not UTF-8 text: byte {error.start})") from None
    else:
        text = data
    depth = text_depth(text, kind)
    if depth > max_depth:
        raise DocumentError(f"{source}: not a {what} (nested {depth} deep; at most {max_depth})")
    try:
        if kind == "toml":
            document: Any = tomllib.loads(text)
        else:
            document = finite_json(text)
    except (ValueError, RecursionError, MemoryError) as error:
        first = (str(error).splitlines() or [type(error).__name__])[0][:160]
        raise DocumentError(f"{source}: not a valid {'TOML' if kind == 'toml' else 'JSON'} {what} ({first})"
                            ) from None
    check_tree(document, source, what, max_depth)
    if schema is not None:
        check_document(document, schema, source, what)
    return document


def text_depth(text: str, kind: str = "json") -> int:
    """The deepest bracket nesting (``[`` and ``{``) of JSON or TOML ``text``, outside strings and comments;
    unclosed brackets count (linear time, no recursion)."""
    stripped = (_TOML_SKIPPED if kind == "toml" else _JSON_STRINGS).sub("", text)
    depth = deepest = 0
    for bracket in _BRACKETS.findall(stripped):
        if bracket in "[{":
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth = max(0, depth - 1)
    return deepest


def check_tree(document: Any, source: str, what: str, max_depth: int = MAX_DEPTH) -> None:
    """DocumentError when ``document`` nests deeper than ``max_depth`` or holds a number that is not finite
    (iterative: any depth is safe to check)."""
    stack: list[tuple[Any, int, Any]] = [(document, 0, None)]
    while stack:
        value, depth, where = stack.pop()
        if isinstance(value, dict | list):
            if depth >= max_depth:
                raise DocumentError(f"{source}: not a {what} (nested deeper than {max_depth})")
            items = value.items() if isinstance(value, dict) else enumerate(value)
            stack.extend((child, depth + 1, (where, key)) for key, child in items)
        elif isinstance(value, float) and not math.isfinite(value):
            raise DocumentError(f"{source}: not a {what}: {_field(where)} must be a finite number, not {value}")


def _field(where: Any) -> str:
    """``'a.b[2]'`` from the linked path ``((None, 'a'), 'b'), 2)`` of :func:`check_tree`."""
    parts: list[str] = []
    while where is not None:
        where, key = where
        parts.append(f"[{key}]" if isinstance(key, int) else f".{key}")
    text = "".join(reversed(parts)).lstrip(".")
    return f"'{text[:80]}'" if text else "the document"


def check_document(document: Any, schema: dict, source: str, what: str) -> None:
    """DocumentError (one line naming the field) unless ``document`` matches the JSON Schema ``schema``.
    ``document`` must be bounded already (:func:`check_tree`)."""
    validate = _validator(schema)
    try:
        validate(document)
    except fastjsonschema.JsonSchemaValueException as error:
        raise DocumentError(f"{source}: not a {what}: {schema_message(error)}") from None
    except (RecursionError, TypeError, ValueError) as error:  # data a JSON parser never makes (e.g. TOML dates)
        raise DocumentError(f"{source}: not a {what} ({type(error).__name__})") from None


def _validator(schema: dict) -> Callable[[Any], Any]:
    cached = _VALIDATORS.get(id(schema))
    if cached is None or cached[0] is not schema:
        cached = (schema, fastjsonschema.compile(schema))
        _VALIDATORS[id(schema)] = cached
    return cached[1]


def schema_message(error: fastjsonschema.JsonSchemaValueException) -> str:
    """A short sentence for a schema failure: the field as ``hands.left.markers[2].along`` and what it must be."""
    field = (error.name or "data")[len("data"):].lstrip(".")
    where = f"'{field}'" if field else "the document"
    rule, definition = error.rule, error.rule_definition
    custom = (error.definition or {}).get("x-message") if isinstance(error.definition, dict) else None
    value = _short(error.value)
    if custom and rule != "required":
        return f"{where} {custom}, not {value}"
    if rule == "type":
        kinds = definition if isinstance(definition, list) else [definition]
        return f"{where} must be {' or '.join(_TYPE_TEXT.get(kind, str(kind)) for kind in kinds)}, not {value}"
    if rule == "required":
        present = error.value if isinstance(error.value, dict) else {}
        missing = [name for name in definition if name not in present]
        return f"{where} needs '{missing[0] if missing else definition[0]}'"
    if rule == "enum":
        return f"{where} must be one of {', '.join(repr(item) for item in definition)}, not {value}"
    if rule == "const":
        return f"{where} must be {definition!r}, not {value}"
    if rule in ("minItems", "maxItems"):
        return f"{where} must have at {'least' if rule == 'minItems' else 'most'} {definition} items"
    if rule in ("minProperties", "maxProperties"):
        return f"{where} must have at {'least' if rule == 'minProperties' else 'most'} {definition} entries"
    if rule in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        relation = {"minimum": "at least", "exclusiveMinimum": "more than", "maximum": "at most",
                    "exclusiveMaximum": "less than"}[rule]
        return f"{where} must be {relation} {definition}, not {value}"
    if rule in ("minLength", "maxLength"):
        return f"{where} must be {'at least' if rule == 'minLength' else 'at most'} {definition} characters long"
    if rule == "additionalProperties":
        extra = sorted(set(error.value) - set((error.definition or {}).get("properties", {}))) \
            if isinstance(error.value, dict) else []
        return f"{where} has an unknown field {_short(extra[0]) if extra else ''}".rstrip()
    return f"{where} {error.message.split(' ', 1)[-1][:120]}"


def _short(value: Any) -> str:
    """``repr`` of a value cut to 40 characters (a hostile value may be huge)."""
    if isinstance(value, dict | list):
        return f"{'an object' if isinstance(value, dict) else 'a list'} of {len(value)}"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def finite_json(text: str | bytes) -> Any:
    """``json.loads`` refusing NaN, Infinity and numbers too large for a float (ValueError)."""
    return json.loads(text, parse_constant=_no_constant, parse_float=_finite)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number")


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text[:20]} is too large a number")
    return value
