"""Fuzz every file reader: seeded mutations of C3D, TSV, TRC, CSV (ours and the Vicon Nexus, Motive and NOKOV
exports of ``tests/io/fixtures``), PLY, OBJ, glTF, GLB and .npz files.

Each case must load or raise :class:`core.errors.InputError`. Cases run in a worker process limited to
``--memory-gb`` of address space; a case that takes longer than ``--timeout`` seconds is a hang, a worker
killed by a signal is a crash, and either way a new worker goes on with the next case.

Mutators are our own (atheris is not used).

Run: python tests/bench/fuzz_readers.py [--cases 5400] [--seed 0] [--formats c3d,tsv,...] [--timeout 30]
"""

import argparse
import json
import random
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

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from core.evaluation.data import SHARED_DATA  # noqa: E402

FORMATS = ("c3d", "tsv", "trc", "csv", "ply", "obj", "gltf", "glb", "npz")
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
    from core.calibration.scan import Scan, save_ply
    from core.io.c3d_writer import write_c3d
    from core.io.csv_file import write_csv
    from core.io.take import Take
    from core.io.trc import write_trc
    from core.model.gltf import load_gltf_hand, save_gltf_hand
    from core.model.hand_model import HandModel
    from core.prior.pca_prior import PosturePrior
    from core.simulate.take import save_truth

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
    """One .npz mutation: a member's .npy header claims another shape or type, or the zip bytes change."""
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


def make_case(fmt: str, seeds: list[Path], seed: int, index: int, folder: Path) -> Path:
    """Write case ``index`` of ``fmt`` into ``folder`` (empty) and return the file to read."""
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
            try:
                data = mutate_npz(data, rng)
            except (zipfile.BadZipFile, ValueError, KeyError, EOFError, RuntimeError, zlib.error):
                data = mutate_bytes(data, rng)
        else:
            data = mutate_bytes(data, rng)
    path.write_bytes(data)
    return path


# --------------------------------------------------------------------------- worker


def read_case(path: Path) -> None:
    """Read ``path`` with the reader its format and seed name call for."""
    from core.calibration.scan import load_scan
    from core.io.loader import load_take
    from core.model.gltf import load_gltf_hand
    from core.model.hand_model import HandModel
    from core.model.joint_angles import read_result_joint_angles
    from core.prior.pca_prior import PosturePrior
    from core.simulate.take import load_truth

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

    from core.errors import InputError

    resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    seeds = json.loads((seed_folder / "seeds.json").read_text())
    seeds = {fmt: [Path(p) for p in paths] for fmt, paths in seeds.items()}
    for fmt, index in json.loads((seed_folder / "cases.json").read_text()):
        print(json.dumps(["start", fmt, index]), flush=True)
        with tempfile.TemporaryDirectory() as folder:
            path = make_case(fmt, seeds[fmt], seed, index, Path(folder))
            size = path.stat().st_size
            started = time.perf_counter()
            try:
                read_case(path)
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


def run(cases: list[tuple[str, int]], seed: int, timeout: float, memory_bytes: int) -> dict:
    """Run ``cases`` in worker processes; the figures per format and the problems found."""
    results = {fmt: {"cases": 0, "loaded": 0, "clean": 0, "unexpected": 0, "signals": 0, "hangs": 0}
               for fmt, _ in cases}
    problems: list[str] = []
    peak_mb, slowest = 0.0, (0.0, "")
    with tempfile.TemporaryDirectory() as folder:
        seeds = write_seeds(Path(folder))
        (Path(folder) / "seeds.json").write_text(json.dumps({k: [str(p) for p in v] for k, v in seeds.items()}))
        remaining = list(cases)
        while remaining:
            (Path(folder) / "cases.json").write_text(json.dumps(remaining))
            process = subprocess.Popen(
                [sys.executable, __file__, "--worker", folder, "--seed", str(seed), "--memory-bytes",
                 str(memory_bytes)], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True)
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
    formats = arguments.formats.split(",")
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
