"""``handmocap label`` and ``handmocap fill`` on real files: labels found, C3D readable by ezc3d and c3d,
measured coordinates unchanged, bad input one line and exit code 2."""

import json

import ezc3d
import numpy as np
import pytest
from simulated_files import save_raw_take

from handmocap.app.cli.main import main
from handmocap.core.io import load_take, save_take


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "raw.c3d"
    return path, save_raw_take(path, n_frames=250, seed=6)


def test_label_then_fill(raw, tmp_path, capsys):
    path, simulated = raw
    labelled, report, filled = tmp_path / "labelled.c3d", tmp_path / "report.json", tmp_path / "filled.c3d"
    assert main(["label", str(path), "--layout", "dense", "--out", str(labelled), "--report", str(report),
                 "--quiet"]) == 0
    figures = json.loads(report.read_text())
    assert figures["labelled_share"] > 0.9 and figures["models"][0]["kind"] == "right"
    names = ezc3d.c3d(str(labelled))["parameters"]["POINT"]["LABELS"]["value"]
    assert names[:24] == list(simulated.truth["marker_names"])
    # the labelled points are the raw points, unchanged (float32 in the file)
    take = load_take(labelled)
    raw_points = load_take(path).marker_positions
    frame = 100
    for column in range(24):
        point = take.marker_positions[frame, column]
        if np.isfinite(point).all():
            assert np.nanmin(np.linalg.norm(raw_points[frame] - point, axis=1)) < 1e-3
    capsys.readouterr()
    assert main(["fill", str(labelled), "--max-gap", "40", "--out", str(filled), "--quiet", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert sum(result["filled"].values()) >= 1
    before = load_take(labelled).marker_positions[:, :24]
    after = load_take(filled).marker_positions[:, :24]
    measured = np.isfinite(before).all(axis=2)
    np.testing.assert_array_equal(after[measured], before[measured])
    assert np.isfinite(after).all(axis=2).sum() > measured.sum()


def test_label_bad_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"\x00" * 100)
    assert main(["label", str(bad), "--layout", "dense", "--out", str(tmp_path / "x.c3d"), "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("handmocap: error:") and len(error.splitlines()) == 1
    assert not (tmp_path / "x.c3d").exists()
    assert main(["fill", str(tmp_path / "missing.c3d"), "--max-gap", "10", "--out", str(tmp_path / "y.c3d")]) == 2


def test_label_take_with_no_points(tmp_path, capsys):
    from handmocap.core.io import Take

    empty = Take(marker_names=["p1", "p2"], marker_positions=np.full((50, 2, 3), np.nan), frame_rate=100.0)
    path = tmp_path / "empty.trc"
    save_take(empty, path)
    assert main(["label", str(path), "--layout", "dense", "--out", str(tmp_path / "o.c3d"), "--quiet"]) == 2
    assert "handmocap: error:" in capsys.readouterr().err


def test_evaluate_label_online_prints_figures(capsys):
    assert main(["evaluate", "label", "--frames", "300", "--seeds", "1", "--online", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["online"] is True
    for case in ("dense_one_hand", "dense_scene", "glove13_one_hand", "glove13_scene"):
        assert figures[f"{case}_correct_share"] >= 0.99, figures
        assert figures[f"{case}_longest_swap_frames"] <= 10, figures
