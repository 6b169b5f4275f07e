"""A saved session damaged in many ways: the take always opens, from the newest snapshot that reads, with
every journalled edit that can be replayed; damaged values give one-line InputErrors, never raw
ValueError/TypeError/RecursionError.

The session is made by the program itself (auto-label applied, three saves, edits after the last save);
each variant damages a copy: the newest snapshot (truncated, bytes flipped, wrong JSON types, NaN, deep
nesting, huge numbers, an array header asking for terabytes), older snapshots too, journal lines, the
manifest.
"""

import copy
import io
import json
import shutil
import zipfile

import numpy as np
import pytest
from simulated_files import labelled_session

from handmocap.core.errors import InputError
from handmocap.core.review import SwapLabels, UndoStack, Unlabel
from handmocap.core.session import Session
from handmocap.core.session.journal import JOURNAL_NAME
from handmocap.core.session.storage import npz_bytes, read_npz

FRAMES = 200
TAKE = "t0001"
# the edits after the last save: each unlabels its own label over its own frames (independent of the others)
UNSAVED = [Unlabel(label=f"M{index % 5}", scope="range", start=100 + 15 * index, stop=110 + 15 * index)
           for index in range(6)]


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """(session folder, expected review, review after the last save) of a session saved three times."""
    root = tmp_path_factory.mktemp("damage")
    opened, _result = labelled_session(root, frames=FRAMES, seed=3)
    opened.save()
    opened.push(SwapLabels("M0", "M1", 0, 40))
    opened.push(Unlabel(label="M2", scope="range", start=10, stop=30))
    opened.save()
    opened.undo()
    opened.push(Unlabel(label="M3", scope="range", start=50, stop=70))
    opened.save()
    base = copy.deepcopy(opened.review)
    for command in UNSAVED:
        opened.push(command)
    expected = copy.deepcopy(opened.review)
    opened.close(save=False)  # the unsaved edits stay in the journal
    folder = root / "session" / "takes" / TAKE
    assert (folder / "review.npz").exists() and len(list(folder.glob("review-*.npz"))) == 2
    return root / "session", expected, base


def _copy(saved, tmp_path):
    folder = tmp_path / "session"
    shutil.copytree(saved[0], folder)
    return folder, folder / "takes" / TAKE


def _reopen(folder):
    opened = Session.open(folder).open_take(TAKE)
    for warning in opened.warnings:
        assert "\n" not in warning
    return opened


def _with_meta(data: bytes, change) -> bytes:
    arrays = read_npz(data, "review.npz")
    meta = json.loads(str(arrays["meta"]))
    arrays["meta"] = np.array(change(meta) if callable(change) else change)
    if not isinstance(arrays["meta"].item(), str):
        arrays["meta"] = np.array(json.dumps(arrays["meta"].item()))
    return npz_bytes(arrays)


def _as_json(change):
    def edit(meta):
        changed = change(meta)
        return json.dumps(meta if changed is None else changed)
    return edit


def _deep(depth: int) -> str:
    return "[" * depth + "]" * depth


def _huge_array_header(data: bytes) -> bytes:
    """The snapshot with its assignment array's header claiming 10^12 x 5 entries (40 TB)."""
    source = zipfile.ZipFile(io.BytesIO(data))
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for info in source.infolist():
            content = source.read(info)
            if info.filename == "assignment.npy":
                header = {"descr": "<i8", "fortran_order": False, "shape": (10**12, 5)}
                stream = io.BytesIO()
                np.lib.format.write_array_header_1_0(stream, header)
                content = stream.getvalue() + b"\0" * 64
            archive.writestr(info.filename, content)
    return buffer.getvalue()


def _nested_children(text: str, depth: int) -> str:
    """The meta JSON ``text`` with its first undo step wrapped in ``depth`` compound steps (built as text:
    the JSON encoder itself cannot nest that deep)."""
    meta = json.loads(text)
    inner = json.dumps(meta["history"]["steps"][0])
    meta["history"]["steps"][0] = "@"
    wrapper = '{"command": {"type": "compound", "text": "x", "children": []}, "span": [0, 1], "children": ['
    return json.dumps(meta).replace('"@"', wrapper * depth + inner + "]}" * depth)


def _snapshot_variants(data: bytes) -> dict[str, tuple[bytes, bool]]:
    """Damaged versions of the snapshot ``data``: name -> (bytes, whether it must be reported damaged; a
    flipped byte may land where the archive does not check)."""
    size = len(data)
    variants = {f"truncated to {n}": data[:n] for n in (0, 10, 100, size // 3, size // 2, size - 1)}
    for fraction in np.linspace(0.02, 0.98, 14):
        offset = int(fraction * size)
        variants[f"byte {offset} flipped"] = data[:offset] + bytes([data[offset] ^ 0xFF]) + data[offset + 1:]
    variants["zeros in the middle"] = data[: size // 4] + b"\0" * 512 + data[size // 4 + 512:]
    variants["not a zip"] = b"this is not a snapshot" * 10
    must_warn = {name: not name.startswith("byte") for name in variants}
    must_warn.update({"undo steps nested 50 deep": False, "undo steps nested 400 deep": False})
    json_changes = {
        "meta is a list": lambda meta: [meta],
        "journal_seq is text": lambda meta: meta.update(journal_seq="7"),
        "journal_seq is huge": lambda meta: meta.update(journal_seq=10**30),
        "journal_seq is negative": lambda meta: meta.update(journal_seq=-4),
        "hands is an object": lambda meta: meta.update(hands={}),
        "label_names is a number": lambda meta: meta.update(label_names=5),
        "a hand's labels out of range": lambda meta: meta["hands"].append({"name": "x", "side": "right",
                                                                           "labels": [10**20]}),
        "settings has text": lambda meta: meta.update(settings={"low_confidence_mm": "x"}),
        "settings has an unknown key": lambda meta: meta.update(settings={"colour": 1}),
        "history is a list": lambda meta: meta.update(history=[]),
        "history step is a number": lambda meta: meta["history"].update(steps=[3]),
        "history index is huge": lambda meta: meta["history"].update(index=10**40),
        "history step span is huge": lambda meta: meta["history"]["steps"][1].update(span=[0, 10**40]),
        "take shape is text": lambda meta: meta.update(take="frames"),
        "health entry malformed": lambda meta: meta.update(health=[{"x": 1}]),
        "format is wrong": lambda meta: meta.update(format="something"),
    }
    for name, change in json_changes.items():
        variants[name] = _with_meta(data, _as_json(change))
    text = str(read_npz(data, "review.npz")["meta"])
    variants["noise_mm is NaN"] = _with_meta(data, text.replace('"noise_mm": null', '"noise_mm": NaN')
                                             .replace('"journal_seq": ', '"noise_mm2": NaN, "journal_seq": '))
    variants["journal_seq is 1e400"] = _with_meta(data, text.replace('"journal_seq": ', '"journal_seq": 1e400, "x": '))
    variants["meta deeply nested"] = _with_meta(data, text[:-1] + ', "deep": ' + _deep(100_000) + "}")
    variants["meta is a number"] = _with_meta(data, "12")
    for depth in (50, 400, 2000):
        variants[f"undo steps nested {depth} deep"] = _with_meta(data, _nested_children(text, depth))
    variants["assignment header asks for 40 TB"] = _huge_array_header(data)
    return {name: (damaged, must_warn.get(name, True)) for name, damaged in variants.items()}


def test_a_damaged_newest_snapshot_falls_back_to_an_older_one_with_every_edit(saved, tmp_path):
    variants = _snapshot_variants((saved[0] / "takes" / TAKE / "review.npz").read_bytes())
    assert len(variants) >= 30
    failures = []
    for number, (name, (data, must_warn)) in enumerate(variants.items()):
        folder, take_folder = _copy(saved, tmp_path / str(number))
        (take_folder / "review.npz").write_bytes(data)
        try:
            opened = _reopen(folder)
        except Exception as error:  # noqa: BLE001 -- every variant must open; collect what did not
            failures.append(f"{name}: {type(error).__name__}: {error}")
            continue
        if not opened.review.same_state(saved[1]):
            failures.append(f"{name}: opened with another state ({opened.warnings})")
        if must_warn and not any(warning.startswith("review.npz: ") for warning in opened.warnings):
            failures.append(f"{name}: damaged without a warning ({opened.warnings})")
        opened.close()
        again = Session.open(folder).open_take(TAKE)  # what was recovered was saved
        if not again.review.same_state(saved[1]) or again.warnings:
            failures.append(f"{name}: not kept after the recovery ({again.warnings})")
        again.close()
    assert not failures, "\n".join(failures)


def test_two_damaged_snapshots_fall_back_to_the_oldest(saved, tmp_path):
    folder, take_folder = _copy(saved, tmp_path)
    newest = sorted(take_folder.glob("review-*.npz"), key=lambda path: -int(path.stem.split("-")[1]))[0]
    (take_folder / "review.npz").write_bytes(b"")
    newest.write_bytes(newest.read_bytes()[:500])
    opened = _reopen(folder)
    assert opened.review.same_state(saved[1])
    assert sum("damaged" in warning or "cannot read" in warning for warning in opened.warnings) == 2


def test_every_snapshot_damaged_opens_from_the_raw_take_and_says_what_is_missing(saved, tmp_path):
    folder, take_folder = _copy(saved, tmp_path)
    for path in [take_folder / "review.npz", *take_folder.glob("review-*.npz")]:
        path.write_bytes(b"PK\x03\x04 damaged")
    opened = _reopen(folder)  # the journal before the oldest kept snapshot is gone: some edits are missing
    assert any("raw file" in warning for warning in opened.warnings)
    assert any("missing" in warning for warning in opened.warnings)


def _expected_without(saved, skipped: int):
    review = copy.deepcopy(saved[2])
    stack = UndoStack(review)
    for index, command in enumerate(UNSAVED):
        if index != skipped:
            stack.push(copy.deepcopy(command))
    return review


JOURNAL_LINE_DAMAGE = {
    "garbage": lambda line: b"garbage",
    "cut in half": lambda line: line[: len(line) // 2],
    "seq is text": lambda line: line.replace(b'"seq":', b'"seq":"1", "x":'),
    "seq is 1e400": lambda line: line.replace(b'"seq":', b'"seq":1e400, "x":'),
    "seq is huge": lambda line: line.replace(b'"seq":', b'"seq":' + b"9" * 40 + b', "x":'),
    "op is a number": lambda line: line.replace(b'"op":"do"', b'"op":3'),
    "command is a list": lambda line: json.dumps({**json.loads(line), "command": []}).encode(),
    "command type unknown": lambda line: json.dumps({**json.loads(line), "command": {"type": "x"}}).encode(),
    "command has NaN": lambda line: line.replace(b'"start":', b'"start":NaN, "y":'),
    "command label is a list": lambda line: json.dumps(
        {**json.loads(line), "command": {**json.loads(line)["command"], "label": [1]}}).encode(),
    "deeply nested": lambda line: _deep(100_000).encode(),
    "invalid UTF-8": lambda line: b"\xff\xfe" + line,
}


@pytest.mark.parametrize("damage", sorted(JOURNAL_LINE_DAMAGE))
def test_a_damaged_journal_line_is_skipped_and_the_later_edits_replayed(saved, tmp_path, damage):
    folder, take_folder = _copy(saved, tmp_path)
    journal = take_folder / JOURNAL_NAME
    lines = journal.read_bytes().splitlines()
    assert len(lines) == len(UNSAVED)
    skipped = 2
    lines[skipped] = JOURNAL_LINE_DAMAGE[damage](lines[skipped])
    journal.write_bytes(b"\n".join(lines) + b"\n")
    opened = _reopen(folder)
    assert opened.review.same_state(_expected_without(saved, skipped)), opened.warnings
    assert opened.replayed == len(UNSAVED) - 1 and opened.warnings


@pytest.mark.parametrize("manifest", [
    '{"format": "handmocap-session", "version": "1"}',
    '{"format": "handmocap-session", "version": 1e400}',
    '{"format": "handmocap-session", "takes": {}}',
    '{"format": "handmocap-session", "takes": [{"id": "t1", "name": "a", "source": "x", "frames": "many"}]}',
    '{"format": "handmocap-session", "takes": [{"id": "t1", "name": "a", "source": "x", "frame_rate": NaN}]}',
    '{"format": "handmocap-session", "takes": [{"id": "t1", "name": "a", "source": "x", "hands": [1]}]}',
    '{"format": "handmocap-session", "takes": [{"id": "t1", "name": "a", "source": "x", "exports": {"c3d": 1}}]}',
    '{"format": "handmocap-session", "subjects": [[1]]}',
    '{"format": "handmocap-session", "name": ' + _deep(100_000) + "}",
    '{"format": "handmocap-session", "version": ' + "9" * 5000 + "}",
    "[1, 2]",
])
def test_a_malformed_manifest_is_one_input_error(saved, tmp_path, manifest):
    folder, _ = _copy(saved, tmp_path)
    (folder / "session.json").write_text(manifest)
    with pytest.raises(InputError) as raised:
        Session.open(folder)
    assert "\n" not in str(raised.value) and len(str(raised.value)) < 400
    assert (folder / "session.json").read_text() == manifest  # left untouched
