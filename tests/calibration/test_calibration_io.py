"""Calibration files and commands: glTF hand import/export, the calibrate CLI subcommands."""

import argparse
import json

import numpy as np
import pytest

from handmocap.app.cli import calibrate as calibrate_commands
from handmocap.core.calibration.landmarks import landmarks_from_truth, save_landmarks
from handmocap.core.calibration.pipeline import calibrate_scan, load_template_file
from handmocap.core.calibration.scan import save_ply
from handmocap.core.calibration.synthetic_scan import synthetic_scan
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.evaluation.data import GLTF_TEMPLATES
from handmocap.core.model import HandModel, load_layout, load_template, resolve_layout, skin_vertices
from handmocap.core.model.gltf import classify_joint_name, load_gltf_hand, save_gltf_hand
from handmocap.core.model.skeleton import N_PARAMS
from handmocap.core.model.template_mesh import LANDMARK_NAMES

WEBXR = {side: GLTF_TEMPLATES / f"webxr_generic_hand_{side}.glb" for side in ("right", "left")}
needs_webxr = pytest.mark.skipif(not all(path.exists() for path in WEBXR.values()),
                                 reason="shared glTF templates not available")


# --------------------------------------------------------------------------- glTF


@pytest.mark.parametrize(("name", "expected"), [
    ("index-finger-phalanx-proximal", (1, 1, None)),
    ("pinky-finger-tip", (4, 4, None)),
    ("mixamorig:RightHandMiddle2", (2, None, "right")),
    ("thumb_03_l", (0, None, "left")),
    ("middle-finger-phalanx-intermediate", (2, 2, None)),
    ("Hand.L", (None, None, "left")),
])
def test_joint_names_are_classified(name, expected):
    assert classify_joint_name(name) == expected


@needs_webxr
@pytest.mark.parametrize("side", ["right", "left"])
def test_webxr_hands_import_onto_the_16_joint_skeleton(side):
    model = load_gltf_hand(WEBXR[side])
    assert model.side == side
    model.validate()
    positions = model.skeleton.rest_positions
    np.testing.assert_allclose(positions[0], 0.0, atol=1e-9)
    # fingers point along +Y; the thumb is on the radial side (-X right, +X left); index and little apart
    radial = -1.0 if side == "right" else 1.0
    assert np.all(model.skeleton.tip_positions[1:, 1] > 120.0)
    assert radial * positions[1, 0] > 10.0 and radial * (positions[4, 0] - positions[13, 0]) > 30.0
    assert 150.0 < model.hand_length < 210.0
    lengths = model.skeleton.bone_lengths()
    assert np.all(lengths > 8.0) and np.all(lengths < 60.0)
    assert set(model.landmarks) == set(LANDMARK_NAMES) and len(set(model.landmarks.values())) == 20
    # the tips' landmarks are the most distal skin of each finger
    for digit, name in enumerate(["index_tip", "middle_tip", "ring_tip", "little_tip"], start=1):
        assert np.linalg.norm(model.vertices[model.landmarks[name]] - model.skeleton.tip_positions[digit]) < 15.0
    # it animates: a fist moves the fingertips towards the palm, every vertex stays finite
    theta = np.zeros(N_PARAMS)
    theta[7::4] = 1.2
    posed = skin_vertices(model, theta)
    assert np.isfinite(posed).all()
    assert posed[model.landmarks["middle_tip"], 1] < model.vertices[model.landmarks["middle_tip"], 1] - 30.0
    resolve_layout(model, load_layout("glove-13"))


def test_export_reimports_exactly(tmp_path):
    model = load_template()
    for name in ("hand.glb", "hand.gltf"):
        save_gltf_hand(model, tmp_path / name)
        loaded = load_gltf_hand(tmp_path / name)
        np.testing.assert_allclose(loaded.vertices, model.vertices, atol=1e-4)
        np.testing.assert_allclose(loaded.skeleton.rest_positions, model.skeleton.rest_positions, atol=1e-4)
        np.testing.assert_allclose(loaded.skeleton.rest_rotations, model.skeleton.rest_rotations, atol=1e-6)
        np.testing.assert_allclose(loaded.skin_weights, model.skin_weights, atol=1e-6)
        assert loaded.landmarks == model.landmarks and loaded.side == "right"
    theta = np.random.default_rng(0).normal(0.0, 0.3, N_PARAMS)
    np.testing.assert_allclose(skin_vertices(loaded, theta), skin_vertices(model, theta), atol=1e-3)


def test_exported_gltf_is_valid_for_other_tools(tmp_path):
    save_gltf_hand(load_template("left"), tmp_path / "left.gltf")
    document = json.loads((tmp_path / "left.gltf").read_text())
    assert document["asset"]["version"] == "2.0"
    skin = document["skins"][0]
    assert len(skin["joints"]) == 21
    weights = document["accessors"][document["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"]]
    assert weights["componentType"] == 5126 and weights["type"] == "VEC4"
    # the heuristic importer (ignoring our extras) reads it back as a left hand with the same joints
    del document["extras"]
    (tmp_path / "plain.gltf").write_text(json.dumps(document))
    plain = load_gltf_hand(tmp_path / "plain.gltf")
    assert plain.side == "left"
    # the generic importer chooses its own rest frame (fingers along wrist -> middle knuckle): same skeleton
    # up to a rotation
    original = load_template("left").skeleton
    np.testing.assert_allclose(plain.skeleton.bone_lengths(), original.bone_lengths(), atol=0.01)

    def distances(points: np.ndarray) -> np.ndarray:
        return np.linalg.norm(points[:, None] - points[None], axis=2)

    np.testing.assert_allclose(distances(plain.skeleton.rest_positions), distances(original.rest_positions),
                               atol=0.01)


def test_bad_gltf_files(tmp_path):
    (tmp_path / "bad.glb").write_bytes(b"glTF\x01\x00\x00\x00")
    with pytest.raises(InputError):
        load_gltf_hand(tmp_path / "bad.glb")
    (tmp_path / "mesh.gltf").write_text(json.dumps({"asset": {"version": "2.0"}, "nodes": [{"name": "a"}]}))
    with pytest.raises(InputError, match="no skinned mesh"):
        load_gltf_hand(tmp_path / "mesh.gltf")
    with pytest.raises(InputError, match="not found"):
        load_gltf_hand(tmp_path / "missing.glb")
    with pytest.raises(InputError, match="unsupported template"):
        load_template_file(tmp_path / "hand.fbx")


@needs_webxr
def test_a_gltf_template_calibrates_a_scan():
    template = load_template_file(WEBXR["right"])
    scan, truth = synthetic_scan(n_points=30_000, background_points=2000, seed=2)
    result = calibrate_scan(scan, landmarks_from_truth(truth), template=template)
    assert len(result.model.vertices) == len(template.vertices)
    assert result.report.to_json()["scan_to_model_mm"]["median"] < 2.0
    assert abs(result.model.hand_length - truth["model"].hand_length) < 15.0


# --------------------------------------------------------------------------- CLI


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="handmocap")
    commands = parser.add_subparsers(dest="command")
    bench = commands.add_parser("bench").add_subparsers(dest="bench_command")
    evaluate = commands.add_parser("evaluate").add_subparsers(dest="evaluate_command")
    calibrate_commands.register(commands, bench, evaluate)
    return parser


@pytest.mark.parametrize("argv", [["calibrate", "--help"], ["bench", "calibrate", "--help"],
                                  ["evaluate", "calibration", "--help"]])
def test_help(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        _parser().parse_args(argv)
    assert exit_info.value.code == 0
    assert "usage" in capsys.readouterr().out


def test_calibrate_command_writes_model_report_and_gltf(tmp_path, capsys):
    scan, truth = synthetic_scan(n_points=25_000, background_points=2000, seed=4)
    save_ply(scan, tmp_path / "scan.ply")
    save_landmarks(landmarks_from_truth(truth), tmp_path / "lm.json")
    # a glTF template when the shared one is there (its 1 159 vertices keep the test fast)
    template = ["--template", str(WEBXR["right"])] if WEBXR["right"].exists() else []
    args = _parser().parse_args(["calibrate", str(tmp_path / "scan.ply"), "--landmarks", str(tmp_path / "lm.json"),
                                 "--out", str(tmp_path / "subject.npz"), "--report", str(tmp_path / "report.json"),
                                 "--gltf", str(tmp_path / "subject.glb"), "--quiet", *template])
    assert args.handler(args) == 0
    out = capsys.readouterr().out
    assert "landmark RMS" in out and "subject.npz" in out
    model = HandModel.load(tmp_path / "subject.npz")
    assert load_gltf_hand(tmp_path / "subject.glb").landmarks == model.landmarks
    assert json.loads((tmp_path / "report.json").read_text())["scan_to_model_mm"]["median"] < 2.0


def test_calibrate_command_bad_input_is_one_clear_error(tmp_path):
    (tmp_path / "lm.json").write_text(json.dumps({"units": "mm", "landmarks": {"wrist": [0, 0, 0]}}))
    (tmp_path / "scan.ply").write_text("not a ply")
    args = _parser().parse_args(["calibrate", str(tmp_path / "scan.ply"), "--landmarks", str(tmp_path / "lm.json"),
                                 "--out", str(tmp_path / "subject.npz")])
    with pytest.raises(HandMocapError) as error:
        args.handler(args)
    assert "\n" not in str(error.value)
    assert not (tmp_path / "subject.npz").exists()
