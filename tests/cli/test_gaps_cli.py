"""``handmocap fill --method pca``, the refusal of an unlabelled take, and ``handmocap evaluate gaps``."""

import json

import numpy as np
import pytest

from handmocap.app.cli.main import main
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.io import Take, load_take, save_take
from handmocap.core.simulate import simulate_take


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """A labelled glove-13 take (TRC) with two gaps of a fingertip, and the truth."""
    simulated = simulate_take(layout="glove-13", n_frames=400, seed=5, noise_mm=0.2)
    truth = simulated.take.marker_positions
    positions = truth.copy()
    tip = simulated.take.marker_names.index("middle_tip")
    positions[100:130, tip] = np.nan
    positions[250:290, tip] = np.nan
    take = Take(list(simulated.take.marker_names), positions, simulated.take.frame_rate)
    path = tmp_path_factory.mktemp("fill") / "labelled.trc"
    save_take(take, path)
    return path, truth, tip


def test_fill_with_pca_through_the_command_line(labelled, tmp_path, capsys):
    path, truth, tip = labelled
    out = tmp_path / "filled.c3d"
    assert main(["fill", str(path), "--max-gap", "60", "--method", "pca", "--out", str(out), "--quiet",
                 "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    result = json.loads(lines[-1])
    assert result["filled"] == {"pca": 2} and result["codes"]["6"] == "pca"
    assert "filled 2 (2 pca)" in lines[0]
    filled = load_take(out).marker_positions[:, tip]
    for start, stop in ((100, 130), (250, 290)):
        error = np.linalg.norm(filled[start:stop] - truth[start:stop, tip], axis=1)
        assert np.isfinite(error).all() and error.mean() < 5.0


def test_fill_refuses_an_unlabelled_take(tmp_path, capsys):
    raw = simulate_take(layout="glove-13", n_frames=120, seed=1, unlabelled=True).take
    path = tmp_path / "raw.csv"
    save_take(raw, path)
    out = tmp_path / "filled.c3d"
    assert main(["fill", str(path), "--max-gap", "20", "--out", str(out), "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "not labelled" in error and "point_000" in error
    assert not out.exists()


@pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")
def test_evaluate_gaps_prints_every_method_and_auto_against_pca(capsys):
    assert main(["evaluate", "gaps", "--lengths", "10", "80", "--trials", "2", "--gaps", "2", "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    rows = {line.split()[0] for line in lines if line and line.split()[0] in
            ("linear", "spline", "pattern", "rigid", "model", "pca", "auto")}
    assert rows == {"linear", "spline", "pattern", "rigid", "model", "pca", "auto"}
    figures = json.loads(lines[-1])
    assert {"pca_80_mean_mm", "pca_80_worst_mm", "hidden_auto_80_mean_mm", "hidden_pca_10_worst_mm"} <= set(figures)


def test_fill_of_an_auto_labelled_take_uses_the_subjects_calibrated_hand(tmp_path):
    """`handmocap label` stores the subject calibration in the labelled C3D; `fill` gives it to the model fill."""
    from handmocap.app.cli.review import _load_review, _subject_hands
    from handmocap.core.model import load_layout, load_template, resolve_layout
    from handmocap.core.workflows import gap_groups

    raw = tmp_path / "raw.c3d"
    simulated = simulate_take(layout="glove-13", n_frames=300, seed=5, noise_mm=0.3, occlusion=True, unlabelled=True)
    save_take(simulated.take, raw)
    out = tmp_path / "labelled.c3d"
    assert main(["label", str(raw), "--layout", "glove-13", "--out", str(out), "--quiet"]) == 0
    review = _load_review(str(out))
    models, marker_sets = _subject_hands(review.take.parameters, str(out))
    assert list(marker_sets) == ["right"]
    context = gap_groups(review, models, marker_sets)[0].context
    assert context is not None and context.markers is marker_sets["right"]
    template = resolve_layout(load_template("right"), load_layout("glove-13"))
    assert not np.allclose(context.markers.rest_positions, template.rest_positions)
