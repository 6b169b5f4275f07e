"""OpenCV ``FileStorage`` files (YAML and XML) read and written without OpenCV, within bounds.

``cv2.FileStorage`` is not safe on a file a user was given: a parse error escapes as ``SystemError``, a
file of unclosed ``[`` overflows its stack (SIGSEGV) and a matrix header of a few bytes makes it allocate
what the header claims. This module reads the subset of YAML and XML that FileStorage writes (and people
write by hand for a camera): mappings, sequences (block and flow), scalars, ``!!opencv-matrix`` /
``type_id="opencv-matrix"`` (and ``opencv-nd-matrix``) nodes. Before anything is allocated it checks the
file's size, the nesting depth (:data:`MAX_DEPTH`), each scalar's length and each matrix's dimensions
against its data (at most :data:`MAX_MATRIX_VALUES` values). Anything else (anchors and aliases, other
tags such as ``!!binary``, block scalars, several documents, DTDs and entities) is refused. Every failure
is one :class:`StorageError` line naming the file and the line.

:func:`write_storage` writes YAML or XML the way FileStorage does, so OpenCV reads our files back.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from handmocap.core.errors import InputError

#: deepest nesting of mappings and sequences (a camera file needs 3)
MAX_DEPTH = 16
#: most values one matrix may hold (a camera matrix has 9; per-view errors of a calibration a few thousand)
MAX_MATRIX_VALUES = 1_000_000
#: longest scalar (characters)
MAX_SCALAR = 10_000
#: OpenCV's element type codes and the numpy types they read as
DEPTHS = {"u": np.uint8, "c": np.int8, "w": np.uint16, "s": np.int16, "i": np.int32, "f": np.float32,
          "d": np.float64, "h": np.float16}

_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_HEX = re.compile(r"[-+]?0x[0-9a-fA-F]+")
_FLOAT = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_SPECIAL = {".nan": math.nan, ".NaN": math.nan, ".NAN": math.nan, ".inf": math.inf, ".Inf": math.inf,
            ".INF": math.inf, "+.inf": math.inf, "-.inf": -math.inf, "-.Inf": -math.inf, "-.INF": -math.inf}
_MATRIX_TAGS = ("opencv-matrix", "opencv-nd-matrix")
_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")
#: a plain scalar in a flow collection: up to a ',', ']', '}' or a ': '
_PLAIN = re.compile(r"[^,\]}:]*(?::(?! )[^,\]}:]*)*")


class StorageError(InputError):
    """An OpenCV calibration file outside the subset read here, or damaged; one line naming the file."""


class _Refused(Exception):
    """A problem at a line of the file (turned into a StorageError naming the file)."""

    def __init__(self, line: int, problem: str) -> None:
        super().__init__(f"line {line}: {problem}" if line else problem)


# --------------------------------------------------------------------------- reading


def read_storage(path: str | Path, text: str | None = None) -> dict[str, Any]:
    """The top-level mapping of the OpenCV YAML or XML file ``path`` (``text``: its content, already read):
    scalars as int/float/str, sequences as lists, mappings as dicts, matrices as float64 arrays of their
    shape (``(rows, cols)``, or ``(rows, cols, channels)``). StorageError (one line) otherwise."""
    path = Path(path)
    if text is None:
        try:
            text = path.read_bytes().decode("utf-8-sig")
        except OSError as error:
            raise StorageError(f"cannot read {path} ({error.strerror or error})") from None
        except UnicodeDecodeError as error:
            raise StorageError(f"{path.name}: not an OpenCV calibration file (not UTF-8 text: byte "
                               f"{error.start})") from None
    if "\x00" in text:
        raise StorageError(f"{path.name}: not an OpenCV calibration file (it holds NUL bytes)")
    stripped = text.lstrip()
    xml = stripped.startswith("<") or (not stripped and path.suffix.lower() == ".xml")
    try:
        root = _XmlReader(text).read() if xml else _YamlReader(text).read()
    except _Refused as error:
        raise StorageError(f"{path.name}: not a readable OpenCV calibration file "
                           f"({'XML' if xml else 'YAML'} {error})") from None
    return root


def _scalar(token: str, line: int, quoted: bool = False) -> Any:
    """A plain or quoted scalar as int, float or str."""
    if len(token) > MAX_SCALAR:
        raise _Refused(line, f"a value of {len(token)} characters")
    if quoted:
        return token
    if _INT.fullmatch(token):
        return int(token) if len(token) < 20 else float(token)
    if _HEX.fullmatch(token):
        return int(token, 16) if len(token) < 20 else math.nan
    if _FLOAT.fullmatch(token) and any(ch.isdigit() for ch in token):
        return float(token)
    if token in _SPECIAL:
        return _SPECIAL[token]
    return token


def _matrix(node: Any, tag: str, line: int) -> np.ndarray:
    """A matrix node (``rows``, ``cols``, ``dt``, ``data``; nd: ``sizes``, ``dt``, ``data``) as a float64
    array, its dimensions checked against its data before the array is made."""
    if not isinstance(node, dict):
        raise _Refused(line, f"a {tag} must be a mapping of rows, cols, dt and data")
    dt = node.get("dt")
    match = re.fullmatch(r"([1-9]?)([ucwsifdh])", dt) if isinstance(dt, str) else None
    if match is None:
        raise _Refused(line, f"matrix type dt {str(dt)[:20]!r} is not one of OpenCV's (e.g. d, f, 3u)")
    channels = int(match.group(1) or 1)
    if tag == "opencv-nd-matrix":
        sizes = node.get("sizes")
        if not isinstance(sizes, list) or not 1 <= len(sizes) <= 8:
            raise _Refused(line, "an nd-matrix needs 'sizes', a list of 1 to 8 whole numbers")
        shape = sizes
    else:
        shape = [node.get("rows"), node.get("cols")]
    if not all(isinstance(size, int) and not isinstance(size, bool) and 0 <= size <= MAX_MATRIX_VALUES
               for size in shape):
        raise _Refused(line, f"matrix dimensions {str(shape)[:60]} are not whole numbers within "
                             f"0..{MAX_MATRIX_VALUES}")
    count = channels
    for size in shape:
        count *= size
        if count > MAX_MATRIX_VALUES:
            raise _Refused(line, f"a matrix of {'x'.join(str(s) for s in shape)} values is larger than "
                                 f"{MAX_MATRIX_VALUES} values")
    data = node.get("data", [])
    if not isinstance(data, list):
        data = [data]
    if len(data) != count:
        raise _Refused(line, f"the matrix header says {count} values but its data has {len(data)}")
    if not all(isinstance(value, int | float) and not isinstance(value, bool) for value in data):
        raise _Refused(line, "matrix data must be numbers")
    full_shape = tuple(shape) + ((channels,) if channels > 1 else ())
    return np.asarray(data, dtype=np.float64).reshape(full_shape)


class _YamlReader:
    """The YAML subset of the module docstring, by lines and indentation."""

    def __init__(self, text: str) -> None:
        self.lines: list[tuple[int, int, str]] = []   # (line number, indent, content without comment)
        started = False
        for number, raw in enumerate(text.splitlines(), start=1):
            if "\t" in raw[: len(raw) - len(raw.lstrip())]:
                raise _Refused(number, "a tab in the indentation")
            content = _strip_comment(raw, number).rstrip()
            if not content.strip():
                continue
            if content.startswith("%"):
                if started or not re.fullmatch(r"%YAML[: ]1\.[0-9]+", content.strip()):
                    raise _Refused(number, f"unsupported directive {content.strip()[:30]!r}")
                continue
            if content.strip() == "---" or content.startswith("--- "):
                if started:
                    raise _Refused(number, "a second document")
                started = True
                rest = content[3:].strip()
                if rest:
                    self.lines.append((number, 4, rest))
                continue
            if content.strip() == "...":
                break
            started = True
            self.lines.append((number, len(content) - len(content.lstrip(" ")), content.strip()))
        self.position = 0

    def read(self) -> dict[str, Any]:
        if not self.lines:
            return {}
        first = self.lines[0]
        if first[2].startswith("{"):   # a flow mapping as the whole document
            value = self._flow_value(0)
            if not isinstance(value, dict):
                raise _Refused(first[0], "the document is not a mapping")
            root: dict[str, Any] = value
        else:
            root = self._block_mapping(first[1], 1)
        if self.position < len(self.lines):
            number, _, content = self.lines[self.position]
            raise _Refused(number, f"unexpected {content[:30]!r} (indentation?)")
        return root

    def _block_mapping(self, indent: int, depth: int) -> dict[str, Any]:
        if depth > MAX_DEPTH:
            raise _Refused(self.lines[self.position][0], f"nested deeper than {MAX_DEPTH}")
        mapping: dict[str, Any] = {}
        while self.position < len(self.lines):
            number, line_indent, content = self.lines[self.position]
            if line_indent < indent:
                break
            if line_indent > indent:
                raise _Refused(number, "unexpected indentation")
            if content.startswith("- ") or content == "-":
                raise _Refused(number, "a sequence item where a key was expected")
            key, rest = _split_key(content, number)
            if key in mapping:
                raise _Refused(number, f"key {key!r} appears twice")
            self.position += 1
            mapping[key] = self._value_after_key(rest, indent, number, depth)
        return mapping

    def _value_after_key(self, rest: str, indent: int, number: int, depth: int) -> Any:
        tag = None
        if rest.startswith("!"):
            tag_text, _, rest = rest.partition(" ")
            tag = tag_text.lstrip("!")
            if tag not in _MATRIX_TAGS:
                raise _Refused(number, f"unsupported tag {tag_text[:30]!r}")
            rest = rest.strip()
        if rest:
            value = self._inline(rest, number, depth)
        elif self.position < len(self.lines) and self.lines[self.position][1] > indent:
            child_indent = self.lines[self.position][1]
            child = self.lines[self.position][2]
            if child.startswith("- ") or child == "-":
                value = self._block_sequence(child_indent, depth + 1)
            else:
                value = self._block_mapping(child_indent, depth + 1)
        elif (self.position < len(self.lines) and self.lines[self.position][1] == indent
              and (self.lines[self.position][2].startswith("- ") or self.lines[self.position][2] == "-")):
            value = self._block_sequence(indent, depth + 1)   # "key:\n- a\n- b" (items at the key's indent)
        else:
            value = None
        return _matrix(value, tag, number) if tag else value

    def _block_sequence(self, indent: int, depth: int) -> list[Any]:
        if depth > MAX_DEPTH:
            raise _Refused(self.lines[self.position][0], f"nested deeper than {MAX_DEPTH}")
        items: list[Any] = []
        while self.position < len(self.lines):
            number, line_indent, content = self.lines[self.position]
            if line_indent != indent or not (content.startswith("- ") or content == "-"):
                if line_indent > indent:
                    raise _Refused(number, "unexpected indentation")
                break
            rest = content[1:].strip()
            if not rest:
                self.position += 1
                if self.position < len(self.lines) and self.lines[self.position][1] > indent:
                    child_indent, child = self.lines[self.position][1], self.lines[self.position][2]
                    items.append(self._block_sequence(child_indent, depth + 1)
                                 if child.startswith("- ") or child == "-"
                                 else self._block_mapping(child_indent, depth + 1))
                else:
                    items.append(None)
            elif _looks_like_key(rest):   # "- key: value": a mapping whose keys sit after the dash
                child_indent = indent + (len(content) - len(rest))
                self.lines[self.position] = (number, child_indent, rest)
                items.append(self._block_mapping(child_indent, depth + 1))
            else:
                self.position += 1
                if rest.startswith("!"):
                    raise _Refused(number, f"unsupported tag {rest.split()[0][:30]!r}")
                items.append(self._inline(rest, number, depth + 1))
        return items

    def _inline(self, rest: str, number: int, depth: int) -> Any:
        """A value on the key's line: a flow collection (which may go on over the next lines) or a scalar."""
        if rest[0] in "[{":
            self.position -= 1   # the flow reader starts from the current line's value
            return self._flow_value(depth, rest)
        if rest[0] in "&*|>?@`%":
            raise _Refused(number, f"unsupported YAML {rest[:20]!r} (anchors, aliases and block scalars are not "
                                   "OpenCV's)")
        if rest[0] in "\"'":
            value, end = _quoted(rest, 0, number)
            if rest[end:].strip():
                raise _Refused(number, f"text after a quoted value: {rest[end:end + 20]!r}")
            return value
        return _scalar(rest, number)

    def _flow_value(self, depth: int, first: str | None = None) -> Any:
        """A flow collection starting at the current line (its value part ``first``), over as many lines as
        its brackets need."""
        number = self.lines[self.position][0]
        parts = [first if first is not None else self.lines[self.position][2]]
        self.position += 1
        balance, quote = _bracket_balance(parts[0], number, depth, 0, "")
        while balance > 0:
            if self.position >= len(self.lines):
                raise _Refused(number, "a '[' or '{' that is never closed")
            parts.append(self.lines[self.position][2])
            self.position += 1
            balance, quote = _bracket_balance(parts[-1], number, depth, balance, quote)
        text = " ".join(parts)
        value, end = _FlowParser(text, number, depth).parse()
        if text[end:].strip():
            raise _Refused(number, f"text after a closed bracket: {text[end:end + 20]!r}")
        return value


def _bracket_balance(text: str, line: int, depth: int, balance: int, quote: str) -> tuple[int, str]:
    """Open brackets and the open quote after a line of flow text, given those before it; refuses nesting
    deeper than :data:`MAX_DEPTH`."""
    if not quote and not any(char in text for char in "[]{}\"'"):
        return balance, quote
    for char in text:
        if quote:
            if char == quote:
                quote = ""
        elif char in "\"'":
            quote = char
        elif char in "[{":
            balance += 1
            if depth + balance > MAX_DEPTH:
                raise _Refused(line, f"nested deeper than {MAX_DEPTH}")
        elif char in "]}":
            balance -= 1
            if balance < 0:
                raise _Refused(line, f"a '{char}' without its opening bracket")
            if balance == 0:
                break
    return balance, quote


def _strip_comment(raw: str, line: int) -> str:
    """The line without a ``#`` comment (outside quotes)."""
    if "#" not in raw:
        return raw
    quote = ""
    for index, char in enumerate(raw):
        if quote:
            if char == quote:
                quote = ""
        elif char in "\"'":
            quote = char
        elif char == "#" and (index == 0 or raw[index - 1] in " \t"):
            return raw[:index]
    return raw


def _looks_like_key(text: str) -> bool:
    match = _KEY.match(text) or re.match(r'"[^"]*"', text)
    if match is None:
        return False
    return text[match.end():].startswith(": ") or text[match.end():] == ":"


def _split_key(content: str, line: int) -> tuple[str, str]:
    """``key`` and the rest of ``key: rest``."""
    if content[0] in "\"'":
        key, end = _quoted(content, 0, line)
    else:
        match = _KEY.match(content)
        if match is None:
            raise _Refused(line, f"expected 'key: value', got {content[:30]!r}")
        key, end = match.group(), match.end()
    rest = content[end:]
    if not (rest.startswith(": ") or rest == ":"):
        raise _Refused(line, f"expected 'key: value', got {content[:30]!r}")
    if len(key) > 256:
        raise _Refused(line, "a key of more than 256 characters")
    return key, rest[1:].strip()


def _quoted(text: str, start: int, line: int) -> tuple[str, int]:
    """The quoted string at ``text[start]`` and the index after its closing quote."""
    quote = text[start]
    end = text.find(quote, start + 1)
    while quote == '"' and end > 0 and text[end - 1] == "\\" and not text[start + 1:end].endswith("\\\\"):
        end = text.find(quote, end + 1)
    if end < 0:
        raise _Refused(line, "a quoted value that is never closed")
    value = text[start + 1:end]
    if quote == '"' and "\\" in value:
        value = value.replace('\\"', '"').replace("\\\\", "\\").replace("\\n", "\n").replace("\\t", "\t")
    return _scalar(value, line, quoted=True), end + 1


class _FlowParser:
    """``[a, b, [c]]`` and ``{k: v, ...}`` (with ``!!opencv-matrix`` before a mapping), iteratively bounded
    by :data:`MAX_DEPTH` (the brackets were counted before)."""

    def __init__(self, text: str, line: int, depth: int) -> None:
        self.text, self.line, self.depth, self.index = text, line, depth, 0

    def _skip(self) -> None:
        while self.index < len(self.text) and self.text[self.index] in " \t":
            self.index += 1

    def parse(self) -> tuple[Any, int]:
        value = self._value(self.depth)
        return value, self.index

    def _value(self, depth: int) -> Any:
        if depth > MAX_DEPTH:
            raise _Refused(self.line, f"nested deeper than {MAX_DEPTH}")
        self._skip()
        if self.index >= len(self.text):
            raise _Refused(self.line, "a value is missing")
        char = self.text[self.index]
        if char == "!":
            match = re.match(r"!!?([A-Za-z0-9_-]+)", self.text[self.index:])
            tag = match.group(1) if match else ""
            if tag not in _MATRIX_TAGS or match is None:
                raise _Refused(self.line, f"unsupported tag {self.text[self.index:self.index + 20]!r}")
            self.index += match.end()
            return _matrix(self._value(depth), tag, self.line)
        if char == "[":
            return self._sequence(depth)
        if char == "{":
            return self._mapping(depth)
        if char in "\"'":
            value, self.index = _quoted(self.text, self.index, self.line)
            return value
        if char in "&*|>?@`%":
            raise _Refused(self.line, f"unsupported YAML {self.text[self.index:self.index + 20]!r}")
        match = _PLAIN.match(self.text, self.index)
        end = match.end() if match else self.index
        token = self.text[self.index:end].strip()
        self.index = end
        if not token:
            raise _Refused(self.line, "an empty value")
        return _scalar(token, self.line)

    def _sequence(self, depth: int) -> list[Any]:
        self.index += 1
        items: list[Any] = []
        while True:
            self._skip()
            if self.index < len(self.text) and self.text[self.index] == "]":
                self.index += 1
                return items
            items.append(self._value(depth + 1))
            self._skip()
            if self.index < len(self.text) and self.text[self.index] == ",":
                self.index += 1
            elif not (self.index < len(self.text) and self.text[self.index] == "]"):
                raise _Refused(self.line, "expected ',' or ']' in a sequence")

    def _mapping(self, depth: int) -> dict[str, Any]:
        self.index += 1
        mapping: dict[str, Any] = {}
        while True:
            self._skip()
            if self.index < len(self.text) and self.text[self.index] == "}":
                self.index += 1
                return mapping
            key = self._value(depth + 1)
            self._skip()
            if not (isinstance(key, str) and self.index < len(self.text) and self.text[self.index] == ":"):
                raise _Refused(self.line, "expected 'key: value' in a mapping")
            self.index += 1
            if key in mapping:
                raise _Refused(self.line, f"key {key[:30]!r} appears twice")
            mapping[key] = self._value(depth + 1)
            self._skip()
            if self.index < len(self.text) and self.text[self.index] == ",":
                self.index += 1
            elif not (self.index < len(self.text) and self.text[self.index] == "}"):
                raise _Refused(self.line, "expected ',' or '}' in a mapping")


_XML_TOKEN = re.compile(r"<!--.*?-->|<\?.*?\?>|<!\[CDATA\[|<!|</?[^<>]*>|[^<]+|<", re.DOTALL)
_XML_TAG = re.compile(r"<(/?)([A-Za-z_][A-Za-z0-9_.\-]*)((?:\s+[A-Za-z_:][A-Za-z0-9_.:\-]*\s*=\s*"
                      r"(?:\"[^\"<]*\"|'[^'<]*'))*)\s*(/?)>")
_XML_ATTRIBUTE = re.compile(r"([A-Za-z_:][A-Za-z0-9_.:\-]*)\s*=\s*(?:\"([^\"<]*)\"|'([^'<]*)')")
_ENTITIES = {"lt": "<", "gt": ">", "amp": "&", "quot": '"', "apos": "'"}


class _XmlReader:
    """The XML of FileStorage: ``<opencv_storage>`` holding elements; an element holds text (a scalar or a
    sequence of scalars separated by spaces), or elements (a mapping, or a sequence when they are ``<_>``);
    ``type_id="opencv-matrix"`` marks a matrix."""

    def __init__(self, text: str) -> None:
        self.text = text

    def _tokens(self) -> Iterator[tuple[int, str]]:
        line = 1
        for match in _XML_TOKEN.finditer(self.text):
            token = match.group()
            yield line, token
            line += token.count("\n")

    def read(self) -> dict[str, Any]:
        # stack of (tag, attributes, children [(tag, value)], texts, line)
        stack: list[tuple[str, dict[str, str], list[tuple[str, Any]], list[str], int]] = []
        root: Any = None
        for line, token in self._tokens():
            if token.startswith("<!--") or (token.startswith("<?") and not stack and root is None):
                continue
            if token.startswith("<![CDATA[") or token.startswith("<!") or token.startswith("<?"):
                raise _Refused(line, f"unsupported XML {token[:20]!r} (no DTD, entity, CDATA or instruction)")
            if token.startswith("<"):
                match = _XML_TAG.fullmatch(token)
                if match is None:
                    raise _Refused(line, f"malformed tag {token[:30]!r}")
                closing, tag, attributes, empty = match.groups()
                if closing:
                    if not stack or stack[-1][0] != tag or attributes or empty:
                        raise _Refused(line, f"unexpected closing tag </{tag[:30]}>")
                    value = self._element_value(*stack.pop())
                    if stack:
                        stack[-1][2].append((tag, value))
                    else:
                        root = value
                    continue
                if root is not None:
                    raise _Refused(line, "text after the root element")
                if len(stack) >= MAX_DEPTH:
                    raise _Refused(line, f"nested deeper than {MAX_DEPTH}")
                fields = {name: first or second for name, first, second in _XML_ATTRIBUTE.findall(attributes)}
                if empty:
                    value = self._element_value(tag, fields, [], [], line)
                    if stack:
                        stack[-1][2].append((tag, value))
                    else:
                        root = value
                else:
                    stack.append((tag, fields, [], [], line))
                continue
            if token.strip():
                if not stack:
                    raise _Refused(line, f"text outside the root element: {token.strip()[:20]!r}")
                stack[-1][3].append(token)
        if stack:
            raise _Refused(stack[-1][4], f"<{stack[-1][0][:30]}> is never closed")
        if root is None:
            raise _Refused(0, "no root element")
        if root in ("", []):
            return {}
        if not isinstance(root, dict):
            raise _Refused(0, "the root element holds no mapping")
        return root

    def _element_value(self, tag: str, attributes: dict[str, str], children: list[tuple[str, Any]],
                       texts: list[str], line: int) -> Any:
        type_id = attributes.get("type_id")
        text = _unescape("".join(texts), line).strip()
        if children and text:
            raise _Refused(line, f"<{tag[:30]}> holds both text and elements")
        if children:
            if all(name == "_" for name, _ in children):
                value: Any = [item for _, item in children]
            else:
                value = {}
                for name, item in children:
                    if name in value:
                        raise _Refused(line, f"<{name[:30]}> appears twice in <{tag[:30]}>")
                    value[name] = item
        else:
            value = _xml_text(text, line)
        if type_id is not None:
            if type_id not in _MATRIX_TAGS:
                raise _Refused(line, f"unsupported type_id {type_id[:30]!r}")
            return _matrix(value, type_id, line)
        return value


def _unescape(text: str, line: int) -> str:
    if "&" not in text:
        return text

    def entity(match: re.Match[str]) -> str:
        name = match.group(1)
        if name in _ENTITIES:
            return _ENTITIES[name]
        try:
            code = int(name[2:], 16) if name[:2] in ("#x", "#X") else int(name[1:]) if name[:1] == "#" else -1
        except ValueError:
            code = -1
        if not 0 < code < 0x110000:
            raise _Refused(line, f"unsupported entity &{name[:20]};")
        return chr(code)

    unescaped = re.sub(r"&([^;&\s]{1,12});", entity, text)
    if "&" in re.sub(r"&([^;&\s]{1,12});", "", text):
        raise _Refused(line, "a '&' that is no entity")
    return unescaped


def _xml_text(text: str, line: int) -> Any:
    """An element's text: a quoted string, one scalar, or a sequence of scalars separated by spaces."""
    if not text:
        return ""
    if text[0] == '"' and text.endswith('"') and len(text) >= 2 and '"' not in text[1:-1]:
        return _scalar(text[1:-1], line, quoted=True)
    parts = text.split()
    if len(parts) == 1:
        return _scalar(parts[0], line)
    if len(parts) > MAX_MATRIX_VALUES:
        raise _Refused(line, f"a sequence of more than {MAX_MATRIX_VALUES} values")
    return [_scalar(part, line) for part in parts]


# --------------------------------------------------------------------------- writing


def _number(value: float | int | np.integer | np.floating) -> str:
    """A number the way FileStorage reads it back: ints as they are, floats with a '.' or an exponent."""
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        return str(int(value))
    value = float(value)
    if not math.isfinite(value):
        return ".Nan" if math.isnan(value) else (".Inf" if value > 0 else "-.Inf")
    text = repr(value)
    return text if any(char in text for char in ".en") else text + "."


def storage_text(entries: dict[str, Any], xml: bool) -> str:
    """The FileStorage text (YAML, or XML when ``xml``) of ``entries``: ``str``, ``int``, ``float`` or
    2-D float ``np.ndarray`` (written as ``opencv-matrix`` of doubles) values."""
    lines = ['<?xml version="1.0"?>', "<opencv_storage>"] if xml else ["%YAML:1.0", "---"]
    for key, value in entries.items():
        if not _KEY.fullmatch(key):
            raise ValueError(f"{key!r} is not a FileStorage key")
        if isinstance(value, np.ndarray):
            matrix = np.atleast_2d(np.asarray(value, dtype=np.float64))
            if matrix.ndim != 2:
                raise ValueError(f"{key}: only 2-D matrices are written")
            data = [_number(float(v)) for v in matrix.ravel()]
            if xml:
                lines += [f'<{key} type_id="opencv-matrix">', f"  <rows>{matrix.shape[0]}</rows>",
                          f"  <cols>{matrix.shape[1]}</cols>", "  <dt>d</dt>",
                          "  <data>", "    " + " ".join(data) + f"</data></{key}>"]
            else:
                lines += [f"{key}: !!opencv-matrix", f"   rows: {matrix.shape[0]}", f"   cols: {matrix.shape[1]}",
                          "   dt: d", "   data: [ " + ", ".join(data) + " ]"]
        elif isinstance(value, str):
            escaped = value.replace("\\", "\\\\").replace('"', '\\"')
            if "\n" in value or "\r" in value:
                raise ValueError(f"{key}: a FileStorage string is one line")
            if xml:
                escaped = value.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
                lines.append(f'<{key}>"{escaped}"</{key}>')
            else:
                lines.append(f'{key}: "{escaped}"')
        elif isinstance(value, bool):
            lines.append(f"<{key}>{int(value)}</{key}>" if xml else f"{key}: {int(value)}")
        elif isinstance(value, int | float | np.integer | np.floating):
            lines.append(f"<{key}>{_number(value)}</{key}>" if xml else f"{key}: {_number(value)}")
        else:
            raise ValueError(f"{key}: cannot write a {type(value).__name__} to a FileStorage file")
    if xml:
        lines.append("</opencv_storage>")
    return "\n".join(lines) + "\n"
