"""Hostile inputs of issue 22: OpenCV camera files, deeply nested JSON/TOML inputs, landmarks of the wrong type,
frame memory bombs; each ends in one InputError line (or loads), never a traceback, a signal or a hang.

The seeded fuzzing is the driver of ``tests/bench/fuzz_readers.py`` (``--formats inputs``) with fewer cases;
the named cases are the issue's reproducers.
"""

from __future__ import annotations

import importlib.util
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from handmocap.core.batch.pipeline import load_pipeline
from handmocap.core.calibration.landmarks import load_landmarks
from handmocap.core.camera.files import load_camera, save_camera
from handmocap.core.camera.frames import ImageFolderFrames, open_frames
from handmocap.core.camera.model import CameraClock
from handmocap.core.camera.opencv_storage import MAX_MATRIX_VALUES, read_storage
from handmocap.core.errors import InputError
from handmocap.core.model import load_layout
from handmocap.core.model.lab_template import load_lab_template
from handmocap.core.model.objects import load_scene_spec
from handmocap.core.simulate.camera import random_camera

HANDMOCAP = [sys.executable, "-m", "handmocap.app.cli.main"]

_SPEC = importlib.util.spec_from_file_location(
    "fuzz_readers", Path(__file__).resolve().parents[1] / "bench" / "fuzz_readers.py")
fuzz = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(fuzz)
ROOT = Path(__file__).resolve().parents[2]


def test_fuzzed_inputs_of_every_kind_load_or_fail_cleanly():
    fuzz.check_clean([(fmt, index) for index in range(150) for fmt in fuzz.INPUT_FORMATS], seed=2200)


def one_line(call) -> str:
    with pytest.raises(InputError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message and message
    return message


# --------------------------------------------------------------------------- camera files


@pytest.mark.parametrize(("name", "content", "expected"), [
    ("binary.yaml", b"%YAML:1.0\n---\nx: !!binary AAAA\n", "!!binary"),            # 31 bytes: SystemError before
    ("unclosed.yaml", b"%YAML:1.0\n---\nx: " + b"[" * 50_000, "nested deeper"),    # SIGSEGV before
    ("bomb.yaml", b"%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n"
                  b"   rows: 100000\n   cols: 100000\n   dt: d\n   data: [ 1. ]\n", "larger than"),   # 80 GB before
    ("bomb.xml", b'<?xml version="1.0"?>\n<opencv_storage>\n<camera_matrix type_id="opencv-matrix">'
                 b"<rows>100000</rows><cols>100000</cols><dt>d</dt><data>1.</data></camera_matrix>\n"
                 b"</opencv_storage>\n", "larger than"),
    ("short.yaml", b"camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1, 2 ]\n",
     "says 9 values"),
    ("alias.yaml", b"a: &x [1, 2]\nb: *x\n", "anchors"),
    ("entity.xml", b'<?xml version="1.0"?><!DOCTYPE a [<!ENTITY b "c">]><opencv_storage/>', "DTD"),
    ("deep.xml", b"<opencv_storage>" + b"<a>" * 50_000, "nested deeper"),
    ("text.yaml", b"\xff\xfe\x00", "UTF-8"),
    ("nomatrix.yaml", b"image_width: 640\nimage_height: 480\n", "no camera matrix"),
    ("nan.yaml", b"image_width: 640\nimage_height: 480\ncamera_matrix: [ .nan, 0, 1, 0, 1, 0, 0, 0, 1 ]\n", "finite"),
])
def test_hostile_opencv_camera_files_give_one_line(tmp_path, name, content, expected):
    path = tmp_path / name
    path.write_bytes(content)
    started = time.perf_counter()
    assert expected in one_line(lambda: load_camera(path))
    assert time.perf_counter() - started < 2.0


def test_the_unclosed_bracket_file_does_not_kill_the_process(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_bytes(b"x: " + b"[" * 50_000)
    result = subprocess.run(HANDMOCAP + ["camera", "overlay", "take.c3d", "video.avi",
                             "--camera", str(path), "--out", str(tmp_path / "o.avi")], cwd=ROOT,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "nested deeper" in result.stderr


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".xml"])
def test_camera_files_we_write_are_read_by_opencv_and_by_us(tmp_path, suffix):
    camera = random_camera(7).with_clock(CameraClock(-0.125, 0.999))
    path = tmp_path / f"camera{suffix}"
    save_camera(camera, path)
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        assert storage.isOpened()
        np.testing.assert_array_equal(storage.getNode("camera_matrix").mat(), camera.matrix)
        np.testing.assert_array_equal(storage.getNode("distortion_coefficients").mat().ravel(), camera.distortion)
        np.testing.assert_array_equal(storage.getNode("R").mat(), camera.rotation)
        np.testing.assert_array_equal(storage.getNode("T").mat().ravel(), camera.translation)
        assert storage.getNode("image_width").real() == camera.size[0]
        assert storage.getNode("time_offset_s").real() == -0.125
    finally:
        storage.release()
    again = load_camera(path)
    np.testing.assert_array_equal(again.matrix, camera.matrix)
    np.testing.assert_array_equal(again.rotation, camera.rotation)
    assert again.registered and again.clock == camera.clock and again.size == camera.size


@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_files_opencv_writes_are_read_without_opencv(tmp_path, suffix):
    path = tmp_path / f"opencv{suffix}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("name", "cam one")
    storage.write("image_width", 640)
    storage.write("rate", 1.5)
    storage.write("matrix", np.arange(6, dtype=np.float32).reshape(2, 3))
    storage.write("channels", np.ones((1, 2, 3), np.uint8))
    storage.startWriteStruct("views", cv2.FileNode_SEQ)
    for value in (1, 2.5):
        storage.write("", value)
    storage.endWriteStruct()
    storage.startWriteStruct("board", cv2.FileNode_MAP)
    storage.write("squares", 7)
    storage.endWriteStruct()
    storage.release()
    data = read_storage(path)
    assert data["name"] == "cam one" and data["image_width"] == 640 and data["rate"] == 1.5
    np.testing.assert_array_equal(data["matrix"], np.arange(6).reshape(2, 3))
    assert data["channels"].shape == (1, 2, 3)
    assert data["views"] == [1, 2.5] and data["board"] == {"squares": 7}
    assert MAX_MATRIX_VALUES >= 10 ** 6


# --------------------------------------------------------------------------- JSON and TOML inputs


def _deep(kind: str) -> str:
    return ("[" * 100_000 + "]" * 100_000) if kind == "json" else ("steps = " + "[" * 100_000 + "]" * 100_000)


@pytest.mark.parametrize(("reader", "name"), [
    (load_layout, "layout.json"), (load_lab_template, "template.json"), (load_scene_spec, "objects.json"),
    (load_landmarks, "landmarks.json"), (load_pipeline, "p.json"), (load_pipeline, "p.toml"),
    (load_camera, "camera.json"),
])
def test_deep_nesting_is_one_line_not_a_recursion_error(tmp_path, reader, name):
    path = tmp_path / name
    path.write_text(_deep("toml" if name.endswith(".toml") else "json"))
    assert "nested" in one_line(lambda: reader(path))


def test_toml_tables_nested_by_dotted_keys_are_bounded(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("a" + ".a" * 5000 + " = 1\n")
    assert "nested" in one_line(lambda: load_pipeline(path))


@pytest.mark.parametrize("units", [["mm"], {"a": 1}, 3, None])
def test_landmark_units_of_the_wrong_type_are_one_line(tmp_path, units):
    path = tmp_path / "landmarks.json"
    path.write_text(json.dumps({"units": units, "landmarks": {}}))
    assert "units" in one_line(lambda: load_landmarks(path))


def test_layout_and_template_fields_are_typed(tmp_path):
    layout = load_layout("glove-13").to_json()
    layout["markers"][3]["along"] = "x"
    path = tmp_path / "layout.json"
    path.write_text(json.dumps(layout))
    assert "'markers[3].along' must be a number" in one_line(lambda: load_layout(path))
    template = {"name": "lab", "markers": load_layout("glove-13").to_json()["markers"],
                "hands": {"left": {"markers": load_layout("glove-13").to_json()["markers"],
                                   "statistics": {"pairs": [{"a": "x", "b": "y", "mean_mm": [1], "sd_mm": 1}]}}}}
    path.write_text(json.dumps(template))
    assert "'hands.left.statistics.pairs[0].mean_mm' must be a number" in one_line(lambda: load_lab_template(path))
    template["hands"]["left"]["statistics"] = {"pairs": []}
    template["objects"] = [{"name": "cup", "markers": {"a": [0, 0]}}]
    path.write_text(json.dumps(template))
    assert "'objects[0].markers.a' must be [x, y, z]" in one_line(lambda: load_lab_template(path))


@pytest.mark.parametrize("special", ["fifo", "folder", "device", "huge"])
def test_inputs_that_are_no_regular_file_are_one_line(tmp_path, special):
    path = tmp_path / "layout.json"
    if special == "fifo":
        os.mkfifo(path)
    elif special == "folder":
        path.mkdir()
    elif special == "device":
        path.symlink_to("/dev/zero")
    else:
        path.write_bytes(b" " * 17_000_000)
    started = time.perf_counter()
    one_line(lambda: load_layout(path))
    assert time.perf_counter() - started < 2.0


def test_pipeline_values_with_line_breaks_stay_one_line(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text('hands = "a\\nb"\n"x\\ny" = 1\n')
    one_line(lambda: load_pipeline(path))


# --------------------------------------------------------------------------- frames


def _huge_png_folder(folder: Path, count: int) -> None:
    folder.mkdir()
    data = cv2.imencode(".png", np.zeros((16384, 16384), np.uint8))[1].tobytes()
    for index in range(count):
        (folder / f"frame_{index:03d}.png").write_bytes(data)


def test_frames_larger_than_the_memory_budget_are_refused_before_decoding(tmp_path):
    _huge_png_folder(tmp_path / "frames", 3)
    for depth in (None, 1.0):
        started = time.perf_counter()
        assert "memory budget" in one_line(lambda depth=depth: open_frames(tmp_path / "frames", depth_unit_mm=depth))
        assert time.perf_counter() - started < 1.0


def test_the_cache_keeps_frames_within_its_budget(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for index in range(12):
        (folder / f"frame_{index}.png").write_bytes(cv2.imencode(".png", np.full((100, 100, 3), index, np.uint8))[1])
    frames = ImageFolderFrames(folder, memory_budget=4 * 100 * 100 * 3)
    for index in range(12):
        assert frames.frame(index)[0, 0, 0] == index
    assert len(frames._cache) == 4 and frames._cached_bytes <= frames.memory_budget
    with pytest.raises(InputError, match="memory budget"):
        ImageFolderFrames(folder, memory_budget=100 * 100 * 3)


def test_memory_bomb_of_frames_with_a_matching_camera_is_one_line_within_memory(tmp_path):
    """3.8 MB of 16384x16384 PNG frames and a camera of that size: 2.9 GB and a cv2.error before."""
    from handmocap.core.camera.model import Camera
    from handmocap.core.io import save_take
    from handmocap.core.simulate import simulate_take

    _huge_png_folder(tmp_path / "rgbd", 8)
    camera = Camera(np.array([[9000.0, 0, 8192], [0, 9000.0, 8192], [0, 0, 1]]), np.zeros(5), (16384, 16384),
                    np.eye(3), np.zeros(3), registered=True)
    save_camera(camera, tmp_path / "camera.json")
    save_take(simulate_take(layout="glove-13", n_frames=20, seed=3).take, tmp_path / "take.c3d")

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2 ** 30, 4 * 2 ** 30))

    result = subprocess.run(HANDMOCAP + ["fuse", str(tmp_path / "take.c3d"), "--camera",
                             str(tmp_path / "camera.json"), "--rgbd", str(tmp_path / "rgbd"), "--out",
                             str(tmp_path / "fused.npz")], cwd=ROOT, capture_output=True, text=True, timeout=300,
                            preexec_fn=limit)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().count("\n") == 0 and "memory budget" in result.stderr
    assert not (tmp_path / "fused.npz").exists()
