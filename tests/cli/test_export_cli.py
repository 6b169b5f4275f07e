"""``handmocap export`` of a labelled take and of a session's take in every format, read back; ``handmocap
fill`` keeps the input's provenance (codes of measured and earlier filled samples, edits, residuals, source,
hands, unlabelled point names) and adds its own fills."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from simulated_files import save_raw_take

from handmocap.app.cli.main import main
from handmocap.core.io import load_take
from handmocap.core.io.axes import Y_UP
from handmocap.core.io.labelled_c3d import read_labelled_c3d
from handmocap.core.model.bvh import read_bvh
from handmocap.core.model.gltf import load_gltf_hand
from handmocap.core.review import AcceptFills, GapFill, export_labelled_c3d, review_from_labelled_c3d
from handmocap.core.session import Session

FRAMES = 150


@pytest.fixture(scope="module")
def labelled(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("export")
    save_raw_take(folder / "raw.c3d", n_frames=FRAMES, seed=6)
    assert main(["label", str(folder / "raw.c3d"), "--layout", "dense", "--out", str(folder / "labelled.c3d"),
                 "--quiet"]) == 0
    return folder / "labelled.c3d"


def _error(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("handmocap: error:"), lines
    return lines[0]


def test_fill_keeps_all_provenance(labelled: Path, tmp_path: Path, capsys) -> None:
    review = review_from_labelled_c3d(labelled)
    missing = np.argwhere(review.provenance == -1)
    assert len(missing), "the simulated take must have gaps"
    frame, label = (int(value) for value in missing[0])
    AcceptFills([GapFill(review.label_names[label], frame, "linear", np.full((1, 3), 5.0))]).do(review)  # part of a gap
    review.edited[10:20, 3] = True
    before = tmp_path / "before.c3d"
    export_labelled_c3d(review, before)
    filled = tmp_path / "filled.c3d"
    assert main(["fill", str(before), "--max-gap", "40", "--out", str(filled), "--quiet", "--json"]) == 0
    assert sum(json.loads(capsys.readouterr().out.strip().splitlines()[-1])["filled"].values()) >= 1
    old, new = read_labelled_c3d(before), read_labelled_c3d(filled)
    kept = old.provenance != -1
    np.testing.assert_array_equal(new.provenance[kept], old.provenance[kept])   # measured and earlier fills
    assert new.provenance[frame, label] == 1                                    # the earlier linear fill stays
    assert (new.provenance[~kept] > 0).any()                                    # plus the new fills
    np.testing.assert_array_equal(new.edited, old.edited)
    np.testing.assert_array_equal(new.ghost, old.ghost)
    np.testing.assert_allclose(new.residuals_mm, old.residuals_mm, equal_nan=True)
    assert np.isfinite(old.residuals_mm[old.provenance == 0]).mean() > 0.9      # the labelling residuals
    assert new.source == old.source == str(labelled.parent / "raw.c3d")
    assert new.hands == old.hands == ["right:right:dense"]
    assert new.take.marker_names == old.take.marker_names                       # '*n' names too
    assert set(new.take.parameters) == set(old.take.parameters)                 # HAND_SUBJECT and the rest


@pytest.mark.parametrize("format_name, suffix, options", [
    ("c3d", ".c3d", []), ("trc", ".trc", ["--units", "m", "--up", "y"]), ("csv", ".csv", []),
    ("bvh", ".bvh", ["--units", "m", "--up", "y"]), ("gltf", ".glb", [])])
def test_export_each_format_reads_back(labelled: Path, tmp_path: Path, format_name: str, suffix: str,
                                       options: list[str], capsys) -> None:
    out = tmp_path / f"take{suffix}"
    assert main(["export", str(labelled), "--format", format_name, "--out", str(out), "--quiet", *options]) == 0
    assert f"as {format_name} -> {out}" in capsys.readouterr().out
    source = read_labelled_c3d(labelled)
    points = source.labelled_positions
    if format_name == "c3d":
        back = read_labelled_c3d(out)
        np.testing.assert_array_equal(back.provenance, source.provenance)
        np.testing.assert_allclose(back.labelled_positions, points, equal_nan=True)
        assert back.take.marker_names == source.take.marker_names and back.hands == source.hands
    elif format_name in ("trc", "csv"):
        back = load_take(out)
        assert back.marker_names == source.label_names and back.first_frame == source.take.first_frame
        positions = back.marker_positions @ Y_UP if format_name == "trc" else back.marker_positions
        np.testing.assert_allclose(positions, points, atol=2e-3, equal_nan=True)
    elif format_name == "bvh":
        motion = read_bvh(out)
        assert motion.n_frames == FRAMES and motion.joint_names[0] == "wrist"
        # metres, Y up: the wrist moves where the labelled markers are (hand-sized distances, in metres)
        wrist = motion.world_positions()[:, 0] * 1000.0 @ Y_UP
        centre = np.nanmean(points, axis=1)
        assert np.nanmax(np.linalg.norm(wrist - centre, axis=1)) < 150.0
    else:
        model = load_gltf_hand(out)
        assert model.side == "right"
        document = out.read_bytes()
        assert b'"animations"' in document


def test_export_a_session_take_read_only(labelled: Path, tmp_path: Path, capsys) -> None:
    folder = tmp_path / "session"
    session = Session.create(folder, "lab")
    entry = session.add_take(labelled, layout="dense", labelled=True, name="grasp")
    session.close()
    listing = {path: path.stat().st_mtime_ns for path in folder.rglob("*")}
    first, second = tmp_path / "a.trc", tmp_path / "b.c3d"
    assert main(["export", f"{folder}:{entry.id}", "--format", "trc", "--out", str(first), "--quiet"]) == 0
    assert main(["export", str(folder), "--take", "grasp", "--format", "c3d", "--out", str(second), "--quiet"]) == 0
    assert "take 'grasp' of session" in capsys.readouterr().out
    assert {path: path.stat().st_mtime_ns for path in folder.rglob("*")} == listing   # nothing in it changed
    source = read_labelled_c3d(labelled)
    exported = load_take(first)
    assert exported.marker_names[:source.n_labels] == source.label_names
    np.testing.assert_allclose(exported.marker_positions[:, :source.n_labels], source.labelled_positions,
                               atol=2e-3, equal_nan=True)
    assert main(["export", str(folder), "--format", "trc", "--out", str(tmp_path / "c.trc")]) == 2
    assert "name a take of the session" in _error(capsys)
    assert main(["export", f"{folder}:nothing", "--format", "trc", "--out", str(tmp_path / "c.trc")]) == 2
    assert "no take 'nothing'" in _error(capsys)


def test_export_refuses_bad_options_in_one_line(labelled: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "take.c3d"
    out.write_bytes(b"old")
    assert main(["export", str(labelled), "--format", "c3d", "--out", str(out)]) == 2
    assert "exists; use --overwrite" in _error(capsys)
    assert out.read_bytes() == b"old"
    cases = [(["--format", "c3d", "--units", "m", "--out", str(tmp_path / "x.c3d")], "always in mm"),
             (["--format", "gltf", "--up", "z", "--out", str(tmp_path / "x.glb")], "metres and Y up"),
             (["--format", "bvh", "--no-fills", "--out", str(tmp_path / "x.bvh")], "--no-fills"),
             (["--format", "trc", "--out", str(tmp_path / "x.csv")], "must end in .trc"),
             (["--format", "bvh", "--hand", "left", "--out", str(tmp_path / "x.bvh")], "no left hand")]
    for options, message in cases:
        assert main(["export", str(labelled), "--quiet", *options]) == 2
        assert message in _error(capsys)
    assert main(["export", str(tmp_path / "none.c3d"), "--format", "trc", "--out", str(tmp_path / "x.trc")]) == 2
    assert "no such take file" in _error(capsys)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["take.c3d"]
