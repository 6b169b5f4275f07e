"""Two hands and other programs' names on the command line: ``solve`` (no ``--layout``: recognised; one result
per hand), ``fill --method model`` and ``export`` (BVH per hand, one glTF with both) of takes labelled by
``label --hands both``, by a lab template and by vendors; a left hand solved as left; a take whose names match
no layout refused in one line."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from two_hand_takes import STYLES, named_take, write_lab_template

from handmocap.app.cli.main import main
from handmocap.core.gaps import fill_codes
from handmocap.core.io import save_take
from handmocap.core.io.labelled_c3d import read_labelled_c3d
from handmocap.core.model import add_layout_folder, remove_layout_folder
from handmocap.core.model.bvh import read_bvh


@pytest.fixture(scope="module")
def takes(tmp_path_factory) -> dict[str, Path]:
    """Each style's two-hand take (C3D) and the lab template, in a folder of their own."""
    folder = tmp_path_factory.mktemp("two-hands")
    paths = {}
    for style in STYLES:
        paths[style] = folder / f"{style}.c3d"
        save_take(named_take(style), paths[style])
    paths["lab"] = write_lab_template(folder / "..")
    return paths


def _run(*arguments: str) -> int:
    return main([*arguments, "--quiet"])


def _error(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("handmocap: error:"), lines
    return lines[0]


def _layout_options(style: str, takes: dict[str, Path]) -> list[str]:
    return ["--layout", str(takes["lab"])] if style == "template" else []


@pytest.mark.parametrize("style", STYLES)
def test_solve_writes_one_result_per_hand(style, takes, tmp_path, capsys):
    out = tmp_path / "result.npz"
    assert _run("solve", str(takes[style]), *_layout_options(style, takes), "--out", str(out),
                "--csv", str(tmp_path / "angles.csv")) == 0
    printed = capsys.readouterr().out
    assert "right hand (13 markers" in printed and "left hand (13 markers" in printed
    for side in ("right", "left"):
        with np.load(tmp_path / f"result_{side}.npz") as result:
            assert str(result["hand_side"]) == side
            assert np.nanmean(result["residuals_mm"]) < 1.0
            assert np.isfinite(result["joint_angles"]).all()
        assert (tmp_path / f"angles_{side}.csv").is_file()
    assert not out.exists()


def test_a_template_in_a_layout_folder_is_recognised_without_layout(takes, tmp_path):
    add_layout_folder(takes["lab"].parent)    # as the session's layouts folder is in the application
    try:
        assert _run("solve", str(takes["template"]), "--out", str(tmp_path / "r.npz")) == 0
    finally:
        remove_layout_folder(takes["lab"].parent)
    assert (tmp_path / "r_right.npz").is_file() and (tmp_path / "r_left.npz").is_file()


def test_solve_side_picks_one_hand(takes, tmp_path, capsys):
    assert _run("solve", str(takes["vicon"]), "--side", "left", "--out", str(tmp_path / "left.npz")) == 0
    with np.load(tmp_path / "left.npz") as result:
        assert str(result["hand_side"]) == "left"
        assert [str(name) for name in result["marker_names"]][:1] == ["LeftHand:hand_top"]


def test_a_left_hand_take_is_solved_as_left(tmp_path):
    path = tmp_path / "left.trc"
    save_take(named_take("dash", hands="left"), path)
    assert _run("solve", str(path), "--out", str(tmp_path / "left.npz")) == 0
    with np.load(tmp_path / "left.npz") as result:
        assert str(result["hand_side"]) == "left" and np.nanmean(result["residuals_mm"]) < 1.0


@pytest.mark.parametrize("style", STYLES)
def test_model_fill_fills_the_gaps_of_both_hands(style, takes, tmp_path, capsys):
    if style == "template":
        add_layout_folder(takes["lab"].parent)
    try:
        assert main(["fill", str(takes[style]), "--max-gap", "30", "--method", "model", "--out",
                     str(tmp_path / "filled.c3d"), "--quiet", "--json"]) == 0
    finally:
        remove_layout_folder(takes["lab"].parent)
    filled = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["filled"]
    assert filled.get("model", 0) >= 2 and set(filled) == {"model"}
    data = read_labelled_c3d(tmp_path / "filled.c3d")
    model = data.provenance == fill_codes()["model"]
    right = [index for index, name in enumerate(data.label_names) if name.startswith(("R", "Right"))]
    left = [index for index, name in enumerate(data.label_names) if name.startswith(("L", "Left"))]
    assert model[:, right].any() and model[:, left].any()


def _glb_json(path: Path) -> dict:
    data = path.read_bytes()
    length = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + length])


@pytest.mark.parametrize("style", STYLES)
def test_export_writes_a_bvh_per_hand_and_one_gltf_with_both(style, takes, tmp_path, capsys):
    if style == "template":
        add_layout_folder(takes["lab"].parent)
    try:
        assert _run("export", str(takes[style]), "--format", "bvh", "--out", str(tmp_path / "angles.bvh")) == 0
        assert _run("export", str(takes[style]), "--format", "gltf", "--out", str(tmp_path / "hands.glb")) == 0
    finally:
        remove_layout_folder(takes["lab"].parent)
    printed = capsys.readouterr().out
    assert "angles_right.bvh, " in printed and "angles_left.bvh" in printed
    for side, prefix in (("right", "R_"), ("left", "L_")):
        motion = read_bvh(tmp_path / f"angles_{side}.bvh")
        assert motion.joint_names[0] == f"{prefix}wrist" and np.isfinite(motion.motion).all()
    document = _glb_json(tmp_path / "hands.glb")
    assert len(document["skins"]) == 2 and len(document["meshes"]) == 2
    assert document["extras"]["handmocap"]["hands"] == ["right", "left"]
    assert len(document["animations"][0]["channels"]) == 2 * 17
    names = [node["name"] for node in document["nodes"]]
    assert "R_wrist" in names and "L_wrist" in names
    assert not (tmp_path / "angles.bvh").exists()


def test_export_hand_writes_that_hand_only(takes, tmp_path):
    assert _run("export", str(takes["label"]), "--format", "bvh", "--hand", "left", "--out",
                str(tmp_path / "left.bvh")) == 0
    assert read_bvh(tmp_path / "left.bvh").joint_names[0] == "L_wrist"
    assert _run("export", str(takes["label"]), "--format", "gltf", "--hand", "right", "--out",
                str(tmp_path / "right.glb")) == 0
    assert len(_glb_json(tmp_path / "right.glb")["skins"]) == 1


def test_per_hand_files_that_exist_are_refused_before_any_work(takes, tmp_path, capsys):
    (tmp_path / "result_left.npz").write_bytes(b"keep")
    assert _run("solve", str(takes["label"]), "--out", str(tmp_path / "result.npz")) == 2
    assert "result_left.npz exists" in _error(capsys)
    assert (tmp_path / "result_left.npz").read_bytes() == b"keep" and not (tmp_path / "result_right.npz").exists()


def test_the_art_hands_take_matches_no_layout_in_one_line(shared_data, tmp_path, capsys):
    path = shared_data / "c3d" / "sample_37__ART-Human_hands_real_no6dof.c3d"
    if not path.is_file():
        pytest.skip(f"{path.name} is absent")
    assert _run("solve", str(path), "--out", str(tmp_path / "r.npz")) == 2
    assert _error(capsys) == ("handmocap: error: no layout matches these names: learn one with "
                              "`handmocap layout learn`")
    assert _run("export", str(path), "--format", "bvh", "--out", str(tmp_path / "r.bvh")) == 2
    assert "this take has no hand: its marker names match no layout" in _error(capsys)
