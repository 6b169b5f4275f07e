"""Fuzz every file reader: seeded mutations of C3D, TSV, TRC, CSV (ours and the Vicon Nexus, Motive and NOKOV
exports of ``tests/io/fixtures``), PLY, OBJ, glTF, GLB and .npz files; and of the inputs of issue 22
(:data:`INPUT_FORMATS`): OpenCV camera files (YAML, XML) and our camera JSON, videos, folders of colour and of
depth frames, batch pipelines (TOML, JSON), marker layouts and lab templates, scene specs, landmark files and
session folders.

Each case must load or raise :class:`core.errors.InputError`. Cases run in a worker process limited to
``--memory-gb`` of address space; a case that takes longer than ``--timeout`` seconds is a hang, a worker
killed by a signal is a crash, and either way a new worker goes on with the next case.

Mutators are our own (atheris is not used).

Run: python tests/bench/fuzz_readers.py [--cases 5400] [--seed 0] [--formats c3d,tsv,...|inputs|all] [--timeout 30]
(``--formats inputs``: the formats of :data:`INPUT_FORMATS`; the default is the file formats of :data:`FORMATS`)
"""

import argparse
import json
import os
import random
import re
import resource
import select
import struct
import subprocess
import sys
import tempfile
import time
import traceback
import zipfile
import zlib
from pathlib import Path

import numpy as np

from handmocap.core.evaluation.data import SHARED_DATA

FORMATS = ("c3d", "tsv", "trc", "csv", "ply", "obj", "gltf", "glb", "npz")
#: the inputs of issue 22 (each read by its own reader; see :func:`read_input`)
INPUT_FORMATS = ("camera_yaml", "camera_xml", "camera_json", "video", "frames", "depth", "pipeline", "layout",
                 "scene", "landmarks", "session")
#: the vendor text exports (Vicon Nexus, OptiTrack Motive, NOKOV) the CSV cases also start from
VENDOR_FIXTURES = Path(__file__).resolve().parents[1] / "io" / "fixtures"
INTERESTING_TEXT = ["", "0", "-1", "1e308", "-1e308", "nan", "inf", "9" * 30, "18446744073709551616",
                    "9223372036854775808", "x", "\t\t\t", "1e-320", "2147483648", "65535", " "]
INTERESTING_JSON = [-1, 0, 1, 3, 255, 2 ** 31, 2 ** 63, -2 ** 63, 1e308, -4, 0.5, "x", "", None, True, [], {},
                    [0], [[[[[[]]]]]], {"a": 1}, "data:application/octet-stream;base64,AAAA", "/etc/passwd",
                    "/dev/zero", "../outside.bin", "link.bin", "%2e%2e/outside.bin", "file:///etc/passwd"]


# --------------------------------------------------------------------------- seeds


def c3d_bytes(labels: list[str], n_frames: int, label_dims: tuple[int, ...] | None = None) -> bytes:
    """A minimal float C3D (Intel) of ``labels`` points over ``n_frames`` frames, written byte by byte.

    Labels go 255 a parameter into POINT:LABELS, LABELS2... ; ``label_dims`` replaces them by one LABELS
    parameter of those dimensions, all spaces."""
    width = max(len(label) for label in labels)

    def entry(name: bytes, group: int, body: bytes, last: bool = False) -> bytes:
        offset = 0 if last else 2 + len(body)  # from the offset field to the next entry
        return struct.pack("<bb", len(name), group) + name + struct.pack("<h", offset) + body

    def parameter(type_code: int, dims: tuple[int, ...], data: bytes) -> bytes:
        return struct.pack("<bB", type_code, len(dims)) + bytes(dims) + data + b"\0"

    if label_dims is not None:
        label_entries = entry(b"LABELS", 1, parameter(-1, label_dims, b" " * int(np.prod(label_dims))))
    else:
        label_entries = b""
        for number, start in enumerate(range(0, len(labels), 255), 1):
            chunk = labels[start:start + 255]
            data = b"".join(label.ljust(width).encode() for label in chunk)
            name = b"LABELS" + (str(number).encode() if number > 1 else b"")
            label_entries += entry(name, 1, parameter(-1, (width, len(chunk)), data))
    entries = (entry(b"POINT", -1, b"\0") + label_entries + entry(b"UNITS", 1, parameter(-1, (2,), b"mm"))
               + entry(b"RATE", 1, parameter(4, (), struct.pack("<f", 100.0)), last=True))
    section = bytes([1, 80, 0, 84]) + entries
    n_blocks = -(-len(section) // 512)
    section = section.ljust(512 * n_blocks, b"\0")
    section = section[:2] + bytes([n_blocks]) + section[3:]
    header = struct.pack("<BBHHHHH", 2, 0x50, len(labels), 0, 1, n_frames, 0) + struct.pack("<f", -1.0)
    header += struct.pack("<HH", 2 + n_blocks, 0) + struct.pack("<f", 100.0)
    rng = np.random.default_rng(len(labels))
    points = np.zeros((n_frames, len(labels), 4), "<f4")
    points[..., :3] = rng.normal(0.0, 100.0, (n_frames, len(labels), 3))
    return header.ljust(512, b"\0") + section + points.tobytes()


def write_seeds(folder: Path) -> dict[str, list[Path]]:
    """Seed files of every format in ``folder`` (vendor C3D and the shared glTF hands when present)."""
    from handmocap.core.calibration.scan import Scan, save_ply
    from handmocap.core.io.c3d_writer import write_c3d
    from handmocap.core.io.csv_file import write_csv
    from handmocap.core.io.take import Take
    from handmocap.core.io.trc import write_trc
    from handmocap.core.model.gltf import load_gltf_hand, save_gltf_hand
    from handmocap.core.model.hand_model import HandModel
    from handmocap.core.prior.pca_prior import PosturePrior
    from handmocap.core.simulate.take import save_truth

    rng = np.random.default_rng(0)
    names = ["thumb_tip", "index_tip", "wrist", "Unlabeled 1"]
    positions = rng.normal(0.0, 100.0, (6, len(names), 3))
    positions[2, 1] = np.nan
    take = Take(names, positions, 120.0, first_frame=5)
    seeds: dict[str, list[Path]] = {fmt: [] for fmt in FORMATS}

    def add(fmt: str, name: str, data: bytes | None = None) -> Path:
        path = folder / name
        if data is not None:
            path.write_bytes(data)
        seeds[fmt].append(path)
        return path

    write_c3d(take, add("c3d", "own.c3d"))
    add("c3d", "crafted.c3d", c3d_bytes(["A", "B", "A"], 4))
    if (SHARED_DATA / "c3d").is_dir():
        for vendor in sorted((SHARED_DATA / "c3d").glob("*.c3d")):
            if vendor.stat().st_size < 400_000:
                add("c3d", "vendor_" + vendor.name, vendor.read_bytes())
    write_trc(take, add("trc", "own.trc"))
    write_csv(take, add("csv", "own.csv"))
    for fixture in sorted(VENDOR_FIXTURES.glob("*.csv")):
        add("csv", "vendor_" + fixture.name, fixture.read_bytes())
    if (VENDOR_FIXTURES / "vicon_nexus.csv").is_file():
        add("csv", "vendor_vicon_nexus.txt", (VENDOR_FIXTURES / "vicon_nexus.csv").read_bytes())
    rows = "\n".join("\t".join([str(f + 1), f"{f / 120:.4f}"] + [f"{v:.3f}" for v in row.ravel()])
                     for f, row in enumerate(np.nan_to_num(positions)))
    header = (f"NO_OF_FRAMES\t6\nNO_OF_CAMERAS\t8\nNO_OF_MARKERS\t{len(names)}\nFREQUENCY\t120\n"
              f"DATA_INCLUDED\t3D\nMARKER_NAMES\t" + "\t".join(names) + "\n")
    columns = "Frame\tTime\t" + "\t".join(f"{n} {a}" for n in names for a in "XYZ") + "\n"
    add("tsv", "columns.tsv", (header + columns + rows + "\n").encode())
    add("tsv", "plain.tsv", (header + rows + "\n").encode())
    real_tsv = SHARED_DATA / "real" / "dfki_glove_right_hand_frames_0001_3000.tsv"
    if real_tsv.is_file():
        with real_tsv.open("rb") as stream:
            add("tsv", "real_head.tsv", b"".join(stream.readline() for _ in range(40)))

    cloud = rng.normal(0.0, 40.0, (30, 3))
    faces = np.array([[i, i + 1, i + 2] for i in range(0, 27)])
    save_ply(Scan(points=cloud, normals=cloud / np.linalg.norm(cloud, axis=1, keepdims=True), faces=faces),
             add("ply", "binary.ply"))
    ascii_ply = ["ply", "format ascii 1.0", "element vertex 30", "property float x", "property float y",
                 "property float z", "element face 27", "property list uchar int vertex_indices", "end_header"]
    ascii_ply += [" ".join(f"{v:.3f}" for v in point) for point in cloud]
    ascii_ply += ["3 " + " ".join(map(str, face)) for face in faces]
    add("ply", "ascii.ply", ("\n".join(ascii_ply) + "\n").encode())
    obj = [f"v {x:.3f} {y:.3f} {z:.3f}" for x, y, z in cloud] + ["vn 0 0 1"] * 30
    obj += [f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}" for a, b, c in faces] + ["f 1 2 3 4", "f -1 -2 -3"]
    add("obj", "mesh.obj", ("\n".join(obj) + "\n").encode())

    template = SHARED_DATA / "templates" / "webxr_generic_hand_right.glb"
    model = load_gltf_hand(template) if template.is_file() else HandModel.load(
        Path(__file__).resolve().parents[2] / "resources" / "template" / "right_hand.npz")
    save_gltf_hand(model, add("glb", "own.glb"))
    save_gltf_hand(model, add("gltf", "own.gltf"))
    if template.is_file():
        add("glb", "webxr.glb", template.read_bytes())
    model.save(add("npz", "model.npz"))
    PosturePrior.load(Path(__file__).resolve().parents[2] / "resources" / "priors" / "default_prior.npz").save(
        add("npz", "prior.npz"))
    save_truth({"joint_angles": rng.normal(0.0, 1.0, (6, 26)), "marker_positions": positions,
                "marker_names": np.array(names), "visible": np.isfinite(positions[..., 0])}, add("npz", "truth.npz"))
    np.savez(add("npz", "result.npz"), joint_angles=rng.normal(0.0, 1.0, (5, 26)))
    return seeds


# --------------------------------------------------------------------------- mutators


def mutate_bytes(data: bytes, rng: random.Random) -> bytes:
    """One byte-level mutation: flips, boundary values, a big integer, truncation, insertion, duplication."""
    data = bytearray(data)
    kind = rng.choice(["flip", "set", "int", "truncate", "insert", "duplicate"])
    if not data or kind == "insert":
        position = rng.randrange(len(data) + 1)
        data[position:position] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 16)))
    elif kind == "flip":
        for _ in range(rng.randrange(1, 9)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    elif kind == "set":
        for _ in range(rng.randrange(1, 5)):
            data[rng.randrange(len(data))] = rng.choice([0, 1, 0x7F, 0x80, 0xFF])
    elif kind == "int":
        value = rng.choice([0, 0xFFFF, 0x7FFF, 0x8000, 0xFFFFFFFF, 0x7FFFFFFF, 1 << 20])
        position = rng.randrange(len(data))
        data[position:position + 4] = struct.pack("<I", value)
    elif kind == "truncate":
        del data[rng.randrange(len(data)):]
    else:
        start = rng.randrange(len(data))
        piece = data[start:start + rng.randrange(1, 4096)]
        position = rng.randrange(len(data) + 1)
        data[position:position] = piece * rng.randrange(1, 20)
    return bytes(data)


def mutate_text(data: bytes, rng: random.Random) -> bytes:
    """One text mutation: a cell replaced by a huge or odd value, names duplicated, lines repeated or dropped,
    or the whole file in UTF-16."""
    lines = data.split(b"\n")
    kind = rng.choice(["cell", "cell", "names", "repeat", "drop", "long", "utf16"])
    index = rng.randrange(len(lines))
    if kind == "utf16":
        return data.decode("latin-1").encode(rng.choice(["utf-16", "utf-16-le", "utf-16-be"]))
    if kind == "names":  # every cell of a line becomes the same name
        cells = lines[index].split(b"\t" if b"\t" in lines[index] else b",")
        first = cells[min(2, len(cells) - 1)]
        lines[index] = (b"\t" if b"\t" in lines[index] else b",").join(cells[:1] + [first] * (len(cells) - 1))
    elif kind == "repeat":
        lines[index:index] = [lines[index]] * rng.randrange(1, 2000)
    elif kind == "drop":
        del lines[index]
    elif kind == "long":
        lines[index] = lines[index] + b"\t" * rng.randrange(1, 100_000)
    else:
        separator = b"\t" if b"\t" in lines[index] else b","
        cells = lines[index].split(separator)
        cells[rng.randrange(len(cells))] = rng.choice(INTERESTING_TEXT).encode()
        lines[index] = separator.join(cells)
    return b"\n".join(lines)


def mutate_json(document: object, rng: random.Random) -> object:
    """One structural mutation of a glTF JSON: a value replaced, a key deleted, a stride, URI, count or
    child link made hostile."""
    if isinstance(document, dict) and rng.random() < 0.5:
        targeted = rng.choice(["stride", "uri", "count", "cycle", "index"])
        if targeted == "stride" and document.get("bufferViews"):
            rng.choice(document["bufferViews"])["byteStride"] = rng.choice([-4, -12, 1, 3, 2 ** 31, 0, 4])
            return document
        if targeted == "uri" and document.get("buffers"):
            rng.choice(document["buffers"])["uri"] = rng.choice(INTERESTING_JSON[-8:])
            return document
        if targeted == "count" and document.get("accessors"):
            rng.choice(document["accessors"])[rng.choice(["count", "byteOffset", "componentType", "type"])] = (
                rng.choice(INTERESTING_JSON))
            return document
        if targeted == "cycle" and document.get("nodes"):
            nodes = document["nodes"]
            rng.choice(nodes).setdefault("children", []).append(rng.randrange(len(nodes)))
            return document
    containers = []

    def walk(value: object, depth: int) -> None:
        if isinstance(value, dict | list) and depth < 8:
            containers.append(value)
            for child in (value.values() if isinstance(value, dict) else value):
                walk(child, depth + 1)

    walk(document, 0)
    target = rng.choice(containers)
    if not target:
        return document
    key = rng.choice(list(target)) if isinstance(target, dict) else rng.randrange(len(target))
    if isinstance(target, dict) and rng.random() < 0.2:
        del target[key]
    else:
        target[key] = rng.choice(INTERESTING_JSON)
    return document


def glb_parts(data: bytes) -> tuple[object, bytes]:
    """The JSON and binary chunk of a well-formed GLB."""
    json_length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + json_length])
    binary = data[20 + json_length + 8:]
    return document, binary


def glb_bytes(document: object, binary: bytes) -> bytes:
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(binary), 0x004E4942) + binary)


def mutate_npz(data: bytes, rng: random.Random) -> bytes:
    """One .npz mutation: a member's .npy header claims another shape or type, or the zip bytes change (also
    when ``data`` is not a readable .npz)."""
    try:
        return _mutate_npz_member(data, rng)
    except (zipfile.BadZipFile, ValueError, KeyError, EOFError, RuntimeError, zlib.error):
        return mutate_bytes(data, rng)


def _mutate_npz_member(data: bytes, rng: random.Random) -> bytes:
    import io

    if rng.random() < 0.4:
        return mutate_bytes(data, rng)
    source = zipfile.ZipFile(io.BytesIO(data))
    members = {info.filename: source.read(info) for info in source.infolist()}
    name = rng.choice(list(members))
    header = {"descr": "<f8", "fortran_order": False, "shape": (3,)}
    header["shape"] = rng.choice([(2 ** 40,), (10 ** 6, 10 ** 6), (-1,), (0,), (3, 2 ** 62), ()])
    header["descr"] = rng.choice(["<f8", "|O", "<U100000000", "|V0", ">i4", "<f8"])
    stream = io.BytesIO()
    np.lib.format.write_array_header_1_0(stream, header)
    members[name] = stream.getvalue() + members[name][-24:]
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", rng.choice([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED])) as target:
        for member, content in members.items():
            target.writestr(member, content)
    return out.getvalue()


# --------------------------------------------------------------------------- the inputs of issue 22

INTERESTING_YAML = ["[", "]", "{", "}", "- ", "-", ",", ":", "!!binary AAAA", "!!opencv-matrix", "!!str", "!x",
                    "&a", "*a", "|", ">", "? ", "%YAML:1.0", "---", "...", "'", '"', "#", "rows: 99999999",
                    "cols: 2147483647", "rows: -1", "dt: 3d", "dt: z", "dt: 9f", "data: [ ]", "data: 1", "1e999",
                    "-0", ".nan", ".inf", "9" * 400, "\t", "   ", "\n   ", "\n- ", "x" * 20000, "[" * 50000,
                    "{a: [" * 40, "0x7fffffffffffffff", "sizes: [ 99999, 99999, 99999 ]", "!!opencv-nd-matrix"]
INTERESTING_XML = ["<", ">", "</", "<a>", "</a>", "<_>", "</_>", "<!DOCTYPE x [<!ENTITY a 'b'>]>", "&a;", "&#0;",
                   "&#x110000;", "&", "<![CDATA[x]]>", "<?x?>", ' type_id="opencv-matrix"', ' type_id="x"',
                   "<rows>99999999</rows>", "<cols>-1</cols>", "<dt>3u</dt>", "<dt>q</dt>", '"', "<!--", "-->",
                   "1e999", "nan", "9" * 400, "<a>" * 50000, "<a/>", "<opencv_storage>", "</opencv_storage>",
                   "<sizes>99999 99999 99999</sizes>", ' type_id="opencv-nd-matrix"', "x" * 20000]
INTERESTING_TOML = ["[", "]", "{", "}", "[[a]]", "[steps]", "a.b.c.d = 1", '"""', "'" * 3, "nan", "inf", "-inf",
                    "1979-05-27T07:32:00Z", "= ", "\\u0000", "0x7f", "9" * 5000, "true", "[[[[[[[[1]]]]]]]]",
                    "=" * 40, "x = [" * 2000, "steps = " + "[" * 50000, '"\\"', "\x7f", "#", "\r\n"]


def mutate_markup(data: bytes, rng: random.Random, interesting: list[str]) -> bytes:
    """One text mutation of a YAML, XML or TOML file: an interesting token replaces a word or goes in
    somewhere, a line is repeated or dropped, the file is cut, or nested deeply."""
    text = data.decode("utf-8", "replace")
    kind = rng.choice(["replace", "replace", "insert", "insert", "repeat", "drop", "cut", "nest", "number"])
    if kind == "replace":
        words = list(re.finditer(r"[^\s\[\]{}<>,:=\"']+", text))
        if words:
            word = rng.choice(words)
            return (text[:word.start()] + rng.choice(interesting) + text[word.end():]).encode()
    if kind == "number":
        numbers = list(re.finditer(r"-?[0-9][0-9.e+-]*", text))
        if numbers:
            number = rng.choice(numbers)
            value = rng.choice(["1e309", "-1", "0", "99999999999", "2147483648", "nan", "1" * 4400, "0.5", "-0."])
            return (text[:number.start()] + value + text[number.end():]).encode()
    lines = text.split("\n")
    index = rng.randrange(len(lines))
    if kind == "repeat":
        lines[index:index] = [lines[index]] * rng.randrange(1, 3000)
    elif kind == "drop":
        del lines[index]
    elif kind == "cut":
        return data[:rng.randrange(len(data) + 1)]
    elif kind == "nest":
        opener = rng.choice([token for token in interesting if len(token) <= 4 and token[:1] in "[{<"] or ["["])
        lines[index] = lines[index] + opener * rng.choice([20, 200, 5000, 60000])
    else:
        position = rng.randrange(len(lines[index]) + 1)
        lines[index] = lines[index][:position] + rng.choice(interesting) + lines[index][position:]
    return "\n".join(lines).encode()


def _deepen(document: object, rng: random.Random) -> object:
    """``document`` with a deeply nested list or object put in one of its places."""
    deep: object = [] if rng.random() < 0.5 else {}
    for _ in range(rng.choice([40, 1000, 20000])):
        deep = [deep] if rng.random() < 0.5 else {"a": deep}
    if isinstance(document, dict) and document:
        document[rng.choice(list(document))] = deep
        return document
    return deep


def _deep_json(document: object, rng: random.Random) -> bytes:
    """JSON text of ``document`` with a deep nesting in it, written without recursion."""
    depth = rng.choice([40, 1000, 20000])
    opener, closer = ("[", "]") if rng.random() < 0.5 else ('{"a": ', "}")
    deep = opener * depth + "0" + closer * depth
    if isinstance(document, dict) and document:
        key = rng.choice(list(document))
        document = dict(document)
        document[key] = "@@DEEP@@"
        return json.dumps(document).replace('"@@DEEP@@"', deep).encode()
    return deep.encode()


def write_input_seeds(folder: Path) -> dict[str, list[Path]]:
    """Seeds of :data:`INPUT_FORMATS` in ``folder``: files, or folders (frames, depth, sessions)."""
    import cv2

    from handmocap.core.batch.pipeline import Pipeline, save_pipeline
    from handmocap.core.batch.state import write_state
    from handmocap.core.calibration.landmarks import save_landmarks
    from handmocap.core.camera.files import save_camera
    from handmocap.core.camera.writers import write_depth_frames, write_video
    from handmocap.core.io import save_take
    from handmocap.core.model import load_layout
    from handmocap.core.model.objects import object_from_json, save_scene_spec
    from handmocap.core.model.template_mesh import LANDMARK_NAMES
    from handmocap.core.session.cameras import add_camera
    from handmocap.core.session.session import Session
    from handmocap.core.simulate.camera import random_camera
    from handmocap.core.simulate.take import simulate_take

    seeds: dict[str, list[Path]] = {fmt: [] for fmt in INPUT_FORMATS}
    rng = np.random.default_rng(22)
    camera = random_camera(3)
    for suffix, fmt in ((".yaml", "camera_yaml"), (".xml", "camera_xml"), (".json", "camera_json")):
        save_camera(camera, folder / f"registered{suffix}")
        seeds[fmt].append(folder / f"registered{suffix}")
    for suffix, fmt in ((".yaml", "camera_yaml"), (".xml", "camera_xml")):   # as OpenCV writes them
        storage = cv2.FileStorage(str(folder / f"opencv{suffix}"), cv2.FILE_STORAGE_WRITE)
        storage.write("calibration_time", "Mon Jan 1 2024")
        storage.write("image_width", 640)
        storage.write("image_height", 480)
        storage.write("camera_matrix", camera.matrix)
        storage.write("distortion_coefficients", camera.distortion.reshape(1, -1))
        storage.write("per_view_errors", rng.random((12, 1)))
        storage.startWriteStruct("board", cv2.FileNode_MAP)
        storage.write("squares", 7)
        storage.endWriteStruct()
        storage.startWriteStruct("views", cv2.FileNode_SEQ)
        for value in (1, 2.5, 3):
            storage.write("", value)
        storage.endWriteStruct()
        storage.release()
        seeds[fmt].append(folder / f"opencv{suffix}")
    (folder / "flow.yaml").write_text("%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: "
                                      "{ rows: 3, cols: 3, dt: d, data: [ 600, 0, 320, 0, 600, 240, 0, 0, 1 ] }\n"
                                      "distortion_coefficients: [ 0.1, -0.2, 0, 0, 0 ]\nR:\n  - 0\n  - 0\n  - 0\n"
                                      "T: [ 0, 0, 500 ]\n")
    seeds["camera_yaml"].append(folder / "flow.yaml")

    frames = [np.full((48, 64, 3), 40 * k, np.uint8) for k in range(4)]
    for name in ("video.avi", "video.mp4"):
        write_video(folder / name, frames, 30.0, (64, 48))
        seeds["video"].append(folder / name)
    for suffix in (".png", ".jpg"):
        colour = folder / f"colour{suffix[1:]}"
        colour.mkdir()
        for k, image in enumerate(frames):
            (colour / f"frame_{k}{suffix}").write_bytes(cv2.imencode(suffix, image)[1].tobytes())
        seeds["frames"].append(colour)
    depth = folder / "depth"
    depth.mkdir()
    write_depth_frames(depth, [rng.uniform(300, 900, (48, 64)) for _ in range(3)], 1.0)
    seeds["depth"].append(depth)

    objects = folder / "objects.json"
    cup = object_from_json({"name": "cup", "type": "cylinder", "radius_mm": 40, "height_mm": 100,
                            "markers": {"cup1": [40, 0, 30], "cup2": [0, 40, 10], "cup3": [-40, 0, -20]}})
    box = object_from_json({"name": "block", "type": "box", "size_mm": [80, 60, 40],
                            "markers": {"b1": [40, 0, 10], "b2": [0, 30, 0], "b3": [-40, 10, 20]}})
    save_scene_spec([cup, box], objects)
    seeds["scene"].append(objects)
    for name in ("p.toml", "p.json"):
        save_pipeline(Pipeline(layout="glove-13", hands="both", objects=str(objects), exports=("c3d", "bvh"),
                               output=str(folder / "out"), rate=120.0), folder / name)
        seeds["pipeline"].append(folder / name)

    layout = load_layout("glove-13").to_json()
    (folder / "layout.json").write_text(json.dumps(layout))
    hand = [dict(marker, digit="index", segment=2) for marker in layout["markers"]]
    names = [marker["name"] for marker in hand]

    def side_hand(prefix: str) -> dict:
        return {"markers": [dict(marker, name=f"{prefix}{marker['name']}") for marker in hand],
                "statistics": {"pairs": [{"a": f"{prefix}{a}", "b": f"{prefix}{b}", "mean_mm": 30.0, "sd_mm": 1.5}
                                         for a, b in zip(names, names[1:], strict=False)]}}

    template = {"name": "lab", "description": "", "template_version": 1, "learned_from": ["a.csv"], "noise_mm": 0.2,
                "markers": side_hand("R_")["markers"], "hands": {"right": side_hand("R_"), "left": side_hand("L_")},
                "objects": [cup.to_json()]}
    (folder / "template.json").write_text(json.dumps(template))
    seeds["layout"] += [folder / "layout.json", folder / "template.json"]

    save_landmarks({name: rng.normal(0, 50, 3) for name in LANDMARK_NAMES}, folder / "landmarks.json")
    seeds["landmarks"].append(folder / "landmarks.json")

    session_folder = folder / "session"
    session = Session.create(session_folder)
    (session_folder / "raw").mkdir()
    save_take(simulate_take(layout="glove-13", n_frames=40, seed=1, unlabelled=True).take,
              session_folder / "raw" / "take.c3d")
    entry = session.add_take(session_folder / "raw" / "take.c3d", layout="glove-13")
    opened = session.open_take(entry.id)
    opened.save()
    opened.close()
    add_camera(session, entry.id, camera, folder / "video.avi", depth, 1.0)
    write_state(session_folder, entry.id, "done", "k" * 64, summary={"outputs": {}})
    session.close()
    seeds["session"].append(session_folder)
    return seeds


def make_input_case(fmt: str, seeds: list[Path], seed: int, index: int, folder: Path) -> Path:
    """Case ``index`` of an input format: a mutated copy of a seed file or folder, in ``folder``."""
    import shutil

    rng = random.Random(f"{seed}:{fmt}:{index}")
    source = seeds[index % len(seeds)]
    if source.is_dir():
        target = folder / source.name
        shutil.copytree(source, target, symlinks=True)
        files = sorted(path for path in target.rglob("*") if path.is_file() and not path.name.endswith(".lock"))
        victim = rng.choice(files)
        if rng.random() < 0.12:   # a hostile entry in place of the file
            victim.unlink()
            hostile = rng.choice(["/proc/self/mem", "/etc/passwd", "/dev/zero", "fifo", "folder", "empty", "loop"])
            if hostile == "fifo":
                os.mkfifo(victim)
            elif hostile == "folder":
                victim.mkdir()
            elif hostile == "empty":
                victim.write_bytes(b"")
            elif hostile == "loop":
                victim.symlink_to(victim.name)
            else:
                victim.symlink_to(hostile)
            return target
        path = victim
    else:
        path = folder / f"case_{source.stem}{source.suffix}"
        shutil.copyfile(source, path)
    data = path.read_bytes()
    suffix = path.suffix.lower()
    for _ in range(rng.randrange(1, 4)):
        if suffix in (".yaml", ".yml") and rng.random() < 0.8:
            data = mutate_markup(data, rng, INTERESTING_YAML)
        elif suffix == ".xml" and rng.random() < 0.8:
            data = mutate_markup(data, rng, INTERESTING_XML)
        elif suffix == ".toml" and rng.random() < 0.8:
            data = mutate_markup(data, rng, INTERESTING_TOML)
        elif suffix == ".json" and rng.random() < 0.85:
            try:
                document = json.loads(data)
                data = _deep_json(document, rng) if rng.random() < 0.15 else json.dumps(
                    mutate_json(document, rng)).encode()
            except (ValueError, RecursionError):
                data = mutate_bytes(data, rng)
        elif suffix == ".npz":
            data = mutate_npz(data, rng)
        elif suffix == ".png" and len(data) >= 24 and rng.random() < 0.3:   # a header claiming another size
            header = bytearray(data)
            struct.pack_into(">II", header, 16, rng.choice([16384, 65535, 0, 1, 2 ** 31]),
                             rng.choice([16384, 65535, 0, 1, 2 ** 31]))
            data = bytes(header)
        else:
            data = mutate_bytes(data, rng)
    path.write_bytes(data)
    return folder / source.name if source.is_dir() else path


def read_input(fmt: str, path: Path) -> None:
    """Read an input case of ``fmt`` the way the program does."""
    from handmocap.core.batch.pipeline import load_pipeline
    from handmocap.core.batch.state import read_state
    from handmocap.core.calibration.landmarks import load_landmarks
    from handmocap.core.camera.files import load_camera
    from handmocap.core.camera.frames import open_frames
    from handmocap.core.model import load_layout
    from handmocap.core.model.lab_template import load_lab_template
    from handmocap.core.model.objects import load_scene_spec
    from handmocap.core.session.cameras import take_cameras
    from handmocap.core.session.session import Session

    if fmt.startswith("camera"):
        load_camera(path)
    elif fmt in ("video", "frames", "depth"):
        with open_frames(path, depth_unit_mm=1.0 if fmt == "depth" else None) as frames:
            for index in range(min(len(frames), 6)):
                frames.frame(index)
    elif fmt == "pipeline":
        load_pipeline(path)
    elif fmt == "layout":
        load_layout(path)
        load_lab_template(path)
    elif fmt == "scene":
        load_scene_spec(path)
    elif fmt == "landmarks":
        load_landmarks(path)
    else:
        session = Session.open(path)
        try:
            for entry in session.takes:
                read_state(session.folder, [entry.id])
                take_cameras(session, entry.id)
                opened = session.open_take(entry.id)
                opened.close(save=False)
        finally:
            session.close()


def make_case(fmt: str, seeds: list[Path], seed: int, index: int, folder: Path) -> Path:
    """Write case ``index`` of ``fmt`` into ``folder`` (empty) and return the file to read."""
    if fmt in INPUT_FORMATS:
        return make_input_case(fmt, seeds, seed, index, folder)
    rng = random.Random(f"{seed}:{fmt}:{index}")
    source = seeds[index % len(seeds)]
    data = source.read_bytes()
    path = folder / f"case_{source.stem}{source.suffix}"
    (folder / "link.bin").symlink_to("/etc/passwd")
    for _ in range(rng.randrange(1, 4)):
        if fmt in ("tsv", "trc", "csv", "obj") or (fmt == "ply" and b"ascii" in data[:40]):
            data = mutate_text(data, rng) if rng.random() < 0.7 else mutate_bytes(data, rng)
        elif fmt == "gltf" and rng.random() < 0.8:
            try:
                data = json.dumps(mutate_json(json.loads(data), rng)).encode()
            except ValueError:
                data = mutate_bytes(data, rng)
        elif fmt == "glb" and rng.random() < 0.7:
            try:
                document, binary = glb_parts(data)
                data = glb_bytes(mutate_json(document, rng), binary)
            except (ValueError, struct.error):
                data = mutate_bytes(data, rng)
        elif fmt == "npz":
            data = mutate_npz(data, rng)
        else:
            data = mutate_bytes(data, rng)
    path.write_bytes(data)
    return path


# --------------------------------------------------------------------------- worker


def read_case(path: Path, fmt: str = "") -> None:
    """Read ``path`` with the reader its format and seed name call for."""
    if fmt in INPUT_FORMATS:
        read_input(fmt, path)
        return
    from handmocap.core.calibration.scan import load_scan
    from handmocap.core.io.loader import load_take
    from handmocap.core.model.gltf import load_gltf_hand
    from handmocap.core.model.hand_model import HandModel
    from handmocap.core.model.joint_angles import read_result_joint_angles
    from handmocap.core.prior.pca_prior import PosturePrior
    from handmocap.core.simulate.take import load_truth

    suffix = path.suffix.lower()
    if suffix in (".c3d", ".tsv", ".trc", ".csv", ".txt"):
        load_take(path, frame_rate=100.0 if "nokov" in path.name else None)   # a NOKOV export has no rate
    elif suffix in (".ply", ".obj"):
        load_scan(path)
    elif suffix in (".glb", ".gltf"):
        load_gltf_hand(path)
    elif "model" in path.name:
        HandModel.load(path)
    elif "prior" in path.name:
        PosturePrior.load(path)
    elif "truth" in path.name:
        load_truth(path)
    else:
        read_result_joint_angles(path)


def worker(seed_folder: Path, seed: int, memory_bytes: int) -> None:
    """Run the cases listed in ``cases.json`` of the seed folder, printing JSON start and result lines."""
    import logging
    import warnings

    from handmocap.core.errors import InputError

    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    seeds = json.loads((seed_folder / "seeds.json").read_text())
    seeds = {fmt: [Path(p) for p in paths] for fmt, paths in seeds.items()}
    if set(seeds) & set(INPUT_FORMATS):   # the readers' imports are not the first case's time
        import handmocap.core.batch.pipeline
        import handmocap.core.calibration.landmarks
        import handmocap.core.camera.files
        import handmocap.core.camera.frames
        import handmocap.core.model.lab_template
        import handmocap.core.session.cameras  # noqa: F401
    for fmt, index in json.loads((seed_folder / "cases.json").read_text()):
        print(json.dumps(["start", fmt, index]), flush=True)
        with tempfile.TemporaryDirectory() as folder:
            path = make_case(fmt, seeds[fmt], seed, index, Path(folder))
            size = path.lstat().st_size
            started = time.perf_counter()
            try:
                read_case(path, fmt)
                status, detail = "loaded", ""
            except InputError as error:
                status, detail = "clean", str(error)
                if "\n" in detail:
                    status = "unexpected"
            except BaseException as error:  # noqa: B036 - every other exception is what the fuzzing looks for
                status, detail = "unexpected", "".join(traceback.format_exception(error))
        seconds = time.perf_counter() - started
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(json.dumps(["done", fmt, index, status, detail[-3000:], seconds, peak_mb, size]), flush=True)


# --------------------------------------------------------------------------- driver


def check_clean(cases: list[tuple[str, int]], seed: int) -> None:
    """The tests' check: every one of ``cases`` loads or fails cleanly (30 s and 4 GiB per case), all within a
    minute."""
    started = time.perf_counter()
    report = run(cases, seed=seed, timeout=30.0, memory_bytes=4 * 2 ** 30)
    assert report["problems"] == []
    assert sum(figures["cases"] for figures in report["formats"].values()) == len(cases)
    assert time.perf_counter() - started < 60.0


def run(cases: list[tuple[str, int]], seed: int, timeout: float, memory_bytes: int) -> dict:
    """Run ``cases`` in worker processes; the figures per format and the problems found."""
    results = {fmt: {"cases": 0, "loaded": 0, "clean": 0, "unexpected": 0, "signals": 0, "hangs": 0}
               for fmt, _ in cases}
    problems: list[str] = []
    peak_mb, slowest = 0.0, (0.0, "")
    with tempfile.TemporaryDirectory() as folder:
        formats = {fmt for fmt, _ in cases}
        seeds = write_seeds(Path(folder)) if formats & set(FORMATS) else {}
        if formats & set(INPUT_FORMATS):
            (Path(folder) / "inputs").mkdir()
            seeds |= write_input_seeds(Path(folder) / "inputs")
        (Path(folder) / "seeds.json").write_text(json.dumps({k: [str(p) for p in v] for k, v in seeds.items()}))
        remaining = list(cases)
        while remaining:
            (Path(folder) / "cases.json").write_text(json.dumps(remaining))
            process = subprocess.Popen(
                [sys.executable, __file__, "--worker", folder, "--seed", str(seed), "--memory-bytes",
                 str(memory_bytes)], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                text=True)  # FFmpeg, libpng and OpenCV talk on stderr about every damaged frame
            current = None
            deadline = time.monotonic() + 120.0  # the worker's start-up: imports and numba
            while True:
                ready, _, _ = select.select([process.stdout], [], [], max(0.0, deadline - time.monotonic()))
                if not ready:
                    process.kill()
                    process.wait()
                    if current is not None:
                        results[current[0]]["hangs"] += 1
                        results[current[0]]["cases"] += 1
                        problems.append(f"hang: {current[0]} case {current[1]} (over {timeout} s)")
                        remaining.remove(current)
                    break
                line = process.stdout.readline()
                if not line:
                    code = process.wait()
                    if current is not None:
                        results[current[0]]["signals" if code < 0 else "unexpected"] += 1
                        results[current[0]]["cases"] += 1
                        problems.append(f"worker ended (code {code}): {current[0]} case {current[1]}")
                        remaining.remove(current)
                    break
                message = json.loads(line)
                if message[0] == "start":
                    current = (message[1], message[2])
                    deadline = time.monotonic() + timeout
                    continue
                _, fmt, index, status, detail, seconds, case_peak, _ = message
                results[fmt]["cases"] += 1
                results[fmt][status] += 1
                if status == "unexpected":
                    problems.append(f"{fmt} case {index}:\n{detail}")
                peak_mb = max(peak_mb, case_peak)
                slowest = max(slowest, (seconds, f"{fmt} case {index}"))
                remaining.remove(current)
                current = None
    return {"formats": results, "problems": problems, "peak_mb": peak_mb, "slowest": slowest}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=5400, help="cases in all, shared by the formats")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--formats", default=",".join(FORMATS))
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds a case may take")
    parser.add_argument("--memory-gb", type=float, default=4.0)
    parser.add_argument("--worker", metavar="SEED_FOLDER", help=argparse.SUPPRESS)
    parser.add_argument("--memory-bytes", type=int, help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    if arguments.worker:
        worker(Path(arguments.worker), arguments.seed, arguments.memory_bytes)
        return
    formats = {"inputs": list(INPUT_FORMATS), "all": list(FORMATS + INPUT_FORMATS)}.get(
        arguments.formats, arguments.formats.split(","))
    cases = [(fmt, index) for index in range(-(-arguments.cases // len(formats))) for fmt in formats]
    started = time.perf_counter()
    report = run(cases[:arguments.cases], arguments.seed, arguments.timeout, int(arguments.memory_gb * 2 ** 30))
    print(f"{len(cases[:arguments.cases])} cases, seed {arguments.seed}, own mutators, "
          f"{time.perf_counter() - started:.0f} s")
    print(f"{'format':8} {'cases':>6} {'loaded':>7} {'clean':>6} {'unexpected':>10} {'signals':>8} {'hangs':>6}")
    for fmt, figures in report["formats"].items():
        print(f"{fmt:8} {figures['cases']:6d} {figures['loaded']:7d} {figures['clean']:6d} "
              f"{figures['unexpected']:10d} {figures['signals']:8d} {figures['hangs']:6d}")
    print(f"peak memory of a worker: {report['peak_mb']:.0f} MB; slowest case: {report['slowest'][0]:.2f} s "
          f"({report['slowest'][1]})")
    for problem in report["problems"][:5]:
        print("\n" + problem)
    if report["problems"]:
        print(f"\n{len(report['problems'])} problems")
        sys.exit(1)


if __name__ == "__main__":
    main()
