"""Hostile input: every reader loads a file or raises InputError (one line), within time and memory limits.

The seeded fuzzing is the driver of ``tests/bench/fuzz_readers.py`` with fewer cases; the named cases are the
ones issue 12 found (glTF strides and URIs, node cycles, OBJ indices, C3D and .npz size bombs, quadratic
name handling, text takes in UTF-16 or of short rows).
"""

import importlib.util
import io
import json
import struct
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from handmocap.core.calibration.scan import load_scan
from handmocap.core.errors import InputError
from handmocap.core.io.loader import load_take
from handmocap.core.model.gltf import load_gltf_hand
from handmocap.core.model.joint_angles import read_result_joint_angles

_SPEC = importlib.util.spec_from_file_location(
    "fuzz_readers", Path(__file__).resolve().parents[1] / "bench" / "fuzz_readers.py")
fuzz = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(fuzz)


def test_fuzzed_files_of_every_format_load_or_fail_cleanly():
    fuzz.check_clean([(fmt, index) for index in range(200) for fmt in fuzz.FORMATS], seed=12)


@pytest.fixture(scope="module")
def gltf_document(tmp_path_factory) -> tuple[dict, bytes]:
    """The JSON and binary of a glTF hand written by our exporter."""
    from handmocap.core.model.gltf import save_gltf_hand
    from handmocap.core.model.hand_model import HandModel

    folder = tmp_path_factory.mktemp("gltf")
    model = HandModel.load(Path(__file__).resolve().parents[2] / "resources" / "template" / "right_hand.npz")
    save_gltf_hand(model, folder / "hand.glb")
    return fuzz.glb_parts((folder / "hand.glb").read_bytes())


def _write_gltf(folder: Path, document: dict, binary: bytes) -> Path:
    """``hand.gltf`` with its buffer in ``hand.bin`` (unless the document names another URI)."""
    (folder / "hand.bin").write_bytes(binary)
    document["buffers"][0].setdefault("uri", "hand.bin")
    path = folder / "hand.gltf"
    path.write_text(json.dumps(document))
    return path


def test_gltf_with_an_external_buffer_loads(tmp_path, gltf_document):
    document, binary = gltf_document
    model = load_gltf_hand(_write_gltf(tmp_path, json.loads(json.dumps(document)), binary))
    assert len(model.vertices) > 1000


@pytest.mark.parametrize("stride", [-12, -4, 1, 3, 2 ** 31])
def test_gltf_byte_stride_smaller_than_an_element_or_past_the_buffer_is_refused(tmp_path, gltf_document, stride):
    document = json.loads(json.dumps(gltf_document[0]))
    document["bufferViews"][0]["byteStride"] = stride
    with pytest.raises(InputError, match="byteStride|runs past"):
        load_gltf_hand(_write_gltf(tmp_path, document, gltf_document[1]))


@pytest.mark.parametrize("uri", ["/etc/passwd", "/dev/zero", "../hand.bin", "%2e%2e/hand.bin", "file:///etc/passwd",
                                 "link.bin", "fifo.bin", "folder"])
def test_gltf_buffers_come_only_from_files_inside_its_folder(tmp_path, gltf_document, uri):
    import os

    inner = tmp_path / "inner"
    inner.mkdir()
    (inner / "link.bin").symlink_to(tmp_path / "hand.bin")   # a link out of the glTF's folder
    os.mkfifo(inner / "fifo.bin")
    (inner / "folder").mkdir()
    (tmp_path / "hand.bin").write_bytes(gltf_document[1])
    document = json.loads(json.dumps(gltf_document[0]))
    document["buffers"][0]["uri"] = uri
    path = _write_gltf(inner, document, b"")
    started = time.perf_counter()
    with pytest.raises(InputError, match="external buffer"):
        load_gltf_hand(path)
    assert time.perf_counter() - started < 5.0


def test_gltf_node_cycle_and_bad_indices_are_refused(tmp_path, gltf_document):
    document = json.loads(json.dumps(gltf_document[0]))
    del document["skins"][0]["inverseBindMatrices"]          # bind pose from the node hierarchy
    document["nodes"][3]["children"] = [0]
    with pytest.raises(InputError, match="two parents|cycle"):
        load_gltf_hand(_write_gltf(tmp_path, document, gltf_document[1]))
    document = json.loads(json.dumps(gltf_document[0]))
    document["skins"][0]["joints"][2] = 10 ** 6
    with pytest.raises(InputError, match="out of range"):
        load_gltf_hand(_write_gltf(tmp_path, document, gltf_document[1]))
    path = tmp_path / "deep.gltf"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="not a glTF file"):
        load_gltf_hand(path)


@pytest.mark.parametrize("face", ["f 1 2 9223372036854775808", "f 1 2 -9223372036854775809", "f 1 2 4",
                                  "f 0 1 2", "f 1 2 -4", "f 1 2 " + "9" * 5000])
def test_obj_face_indices_out_of_range_are_refused(tmp_path, face):
    path = tmp_path / "scan.obj"
    path.write_text(f"v 0 0 0\nv 100 0 0\nv 0 100 0\n{face}\n")
    with pytest.raises(InputError, match="face"):
        load_scan(path)


def test_ply_face_indices_too_big_for_int64_are_refused(tmp_path):
    path = tmp_path / "scan.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n100 0 0\n0 100 0\n3 0 1 99999999999999999999\n")
    with pytest.raises(InputError, match="face"):
        load_scan(path)


def test_c3d_char_parameter_with_a_zero_dimension_is_no_time_bomb(tmp_path):
    path = tmp_path / "bomb.c3d"
    path.write_bytes(fuzz.c3d_bytes(["A"], 2, label_dims=(0, 255, 255, 255, 255)))
    assert path.stat().st_size < 2048
    started = time.perf_counter()
    take = load_take(path)
    assert time.perf_counter() - started < 2.0
    assert take.marker_names == ["*1"]   # a point without a name is an unlabelled point


def test_many_duplicate_marker_names_load_in_linear_time(tmp_path):
    c3d = tmp_path / "names.c3d"
    c3d.write_bytes(fuzz.c3d_bytes(["A"] * 25_000, 1))   # 99 LABELS parameters of 255, the most a C3D has
    names = "\t".join(["A"] * 20_000)
    tsv = tmp_path / "names.tsv"
    tsv.write_text(f"FREQUENCY\t100\nMARKER_NAMES\t{names}\nFrame\tTime\t"
                   + "\t".join(f"A {axis}" for _ in range(20_000) for axis in "XYZ")
                   + "\n1\t0\t" + "\t".join(["1"] * 60_000) + "\n")
    started = time.perf_counter()
    assert load_take(c3d).marker_names[:3] == ["A", "A_2", "A_3"]
    assert load_take(tsv).marker_names[-1] == "A_20000"
    assert time.perf_counter() - started < 10.0


def test_npz_header_claiming_terabytes_is_refused_before_loading(tmp_path):
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (2 ** 40, 26)})
    path = tmp_path / "result.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("joint_angles.npy", header.getvalue() + bytes(64))
    with pytest.raises(InputError, match="claims"):
        read_result_joint_angles(path)


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be"])
def test_utf16_takes_are_read(tmp_path, encoding):
    text = ("FREQUENCY\t100\nMARKER_NAMES\tthumb_tip\twrist\nFrame\tTime\tthumb_tip X\tthumb_tip Y\tthumb_tip Z\t"
            "wrist X\twrist Y\twrist Z\n1\t0\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\t2\t3\t\t\t\n")
    path = tmp_path / "take.tsv"
    path.write_bytes(text.encode(encoding))
    take = load_take(path)
    assert take.marker_names == ["thumb_tip", "wrist"]
    assert take.n_frames == 2 and np.isnan(take.marker_positions[1, 1]).all()


def test_text_take_of_short_rows_is_refused_before_allocating(tmp_path):
    columns = ",".join(f"m{index}_{axis}" for index in range(20_000) for axis in "xyz")
    path = tmp_path / "short.csv"
    path.write_text(f"# frame_rate=100\n{columns}\n" + "1\n" * 50_000)   # 3 * 10**9 cells from 0.6 MB
    with pytest.raises(InputError, match="more cells than the file has bytes"):
        load_take(path)


def test_glb_chunk_lengths_past_the_end_are_refused(tmp_path, gltf_document):
    data = bytearray(fuzz.glb_bytes(*gltf_document))
    struct.pack_into("<I", data, 12, 2 ** 32 - 1)
    path = tmp_path / "hand.glb"
    path.write_bytes(bytes(data))
    with pytest.raises(InputError):
        load_gltf_hand(path)
