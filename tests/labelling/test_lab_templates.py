"""Lab templates: learning one from labelled takes, labelling with it (the lab's names, both hands, a prop),
whole-take identity, and the evaluation on a lab's own labelled take."""

from __future__ import annotations

import json
from dataclasses import replace
from functools import lru_cache

import numpy as np
import pytest

from handmocap.app.cli.main import main
from handmocap.core.errors import InputError
from handmocap.core.evaluation.take_labelling import evaluate_take_labelling, stripped_take
from handmocap.core.io import Take
from handmocap.core.labelling.hypotheses import _apply, _full, check_whole_take, hand_hypotheses
from handmocap.core.labelling.scene import label_scene
from handmocap.core.labelling.templates import learn_template, name_digit, name_side
from handmocap.core.model.lab_template import load_lab_template, save_lab_template
from handmocap.core.simulate.scene import simulate_scene

GUITAR = "guitar/nokov_guitarist_arpeggio.csv"


@lru_cache(maxsize=1)
def _lab_take() -> Take:
    """A labelled two-hand take with a box, as a lab would bring it: noise, occlusion gaps, labels kept."""
    scene = simulate_scene("dense", n_frames=1000, seed=5, hands="both", n_objects=1, noise_mm=0.3, ghost_rate=0.0,
                           occlusion=True)
    truth = scene.truth
    positions = np.where(truth["visible"][:, :, None], truth["marker_positions"], np.nan)
    return Take([str(name) for name in truth["marker_names"]], positions, scene.take.frame_rate)


def test_name_side_and_digit():
    assert name_side("R_index_tip") == ("right", "index_tip")
    assert name_side("L-A1") == ("left", "A1")
    assert name_side("LeftHand:IF3") == ("left", "IF3")
    assert name_side("index_tip_l") == ("left", "index_tip")
    assert name_side("Marker1") == (None, "Marker1")
    assert name_digit("R_index_middle") == "index"
    assert name_digit("L-Wan-1") is None


def test_learn_places_every_marker_and_finds_the_prop(tmp_path):
    take = _lab_take()
    learned = learn_template([replace(take, marker_positions=take.marker_positions[:500])], name="lab")
    template = learned.template
    assert template.sides == ["right", "left"]
    right = dict(zip(template.hands["right"].names, zip(template.hands["right"].digits,
                                                         template.hands["right"].segments, strict=True), strict=True))
    assert right["R_index_distal"] == ("index", 3)
    assert right["R_little_proximal"] == ("little", 1)
    assert right["R_back_centre"][0] == "palm"
    assert [spec.marker_names for spec in template.objects] == [("box1", "box2", "box3", "box4")]
    assert learned.report["hands"]["left"]["residual_mm"] < 3.0
    path = tmp_path / "lab.json"
    save_lab_template(template, path)
    again = load_lab_template(path)
    assert again is not None and again.marker_names == template.marker_names
    assert np.allclose(again.hands["left"].statistics.mean_mm, template.hands["left"].statistics.mean_mm, atol=1e-3,
                       equal_nan=True)


def test_relabelled_held_out_frames_with_the_lab_names():
    figures = evaluate_take_labelling(_lab_take(), learn_on=500)
    assert figures["labels_not_in_take"] == []
    for name in ("right", "left"):
        assert figures["groups"][name]["correct_pct"] >= 99.0, figures["groups"][name]
        assert figures["groups"][name]["wrong_pct"] <= 0.2
    assert figures["groups"]["box"]["correct_pct"] >= 95.0
    assert figures["groups"]["box"]["taken_as_hand_pct"] <= 0.1


def test_whole_take_cycle_of_the_fingers_is_undone():
    take = _lab_take()
    template = learn_template([replace(take, marker_positions=take.marker_positions[:500])]).template
    held_out = replace(take, marker_positions=take.marker_positions[500:700])
    raw, _ = stripped_take(held_out, np.arange(take.n_markers), seed=1)
    result = label_scene(raw, "auto", template)
    before = result.assignment.copy()
    index_of = {name: index for index, name in enumerate(result.marker_names)}
    hand = template.hands["left"]
    columns = np.array([index_of[name] for name in hand.names])
    cycled = next(h for h in hand_hypotheses(hand, columns) if h.name == "fingers cycled by 1")
    _apply(result, _full(cycled.permutation, result.marker_names, index_of, template, "left"))
    assert not np.array_equal(result.assignment, before)
    warnings = check_whole_take(result, template, 0.3)
    assert any(w.kind == "whole_take_identity" and "cycled by 3" in w.message for w in warnings)
    assert np.array_equal(result.assignment, before)


def test_learning_refuses_what_it_cannot_learn():
    take = _lab_take()
    raw, _ = stripped_take(take, np.arange(take.n_markers), seed=0)
    with pytest.raises(InputError, match="no labelled markers"):
        learn_template([raw])
    few = Take(["R_a", "R_b", "R_c"], take.marker_positions[:50, :3], take.frame_rate)
    with pytest.raises(InputError, match="at least 5 are needed"):
        learn_template([few])
    clash = Take(["R_index_tip", "r_INDEX_tip"], take.marker_positions[:50, :2], take.frame_rate)
    with pytest.raises(InputError, match="upper and lower case"):
        learn_template([clash])


def _write_nokov(take: Take, path) -> None:
    header = ",".join(f"{name}-{axis}" for name in take.marker_names for axis in "XYZ")
    rows = np.where(np.isnan(take.marker_positions), np.nan, take.marker_positions).reshape(take.n_frames, -1)
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.4f")


def test_cli_learn_label_and_evaluate_a_real_lab_take(shared_data, tmp_path, capsys):
    """The guitarist's take (NOKOV CSV, no rate in the file): learn on its first frames, label a later stretch
    stripped and shuffled with the lab's names, and measure with evaluate label --take."""
    source = shared_data / GUITAR
    if not source.is_file():
        pytest.skip("the guitar take is absent")
    rows = np.genfromtxt(source, delimiter=",", skip_header=1, max_rows=900)
    names = [column[:-2] for column in source.open().readline().strip().split(",")[0::3]]
    take = Take(names, rows.reshape(len(rows), -1, 3), 120.0)
    learning, later = tmp_path / "learn.csv", tmp_path / "later.csv"
    _write_nokov(replace(take, marker_positions=take.marker_positions[:600]), learning)
    _write_nokov(replace(take, marker_positions=take.marker_positions[600:]), later)
    template = tmp_path / "lab.json"
    assert main(["layout", "learn", str(learning), "--rate", "120", "--out", str(template), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "index   L-B1 (3), L-B2 (2), L-B3 (1)" in out and "object 'Marker': Marker1" in out
    assert main(["evaluate", "label", "--take", str(later), "--rate", "120", "--layout", str(template),
                 "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for group in ("right", "left"):
        assert figures["groups"][group]["correct_pct"] >= 99.5
        assert figures["groups"][group]["longest_wrong_frames"] <= 10
    assert figures["groups"]["Marker"]["correct_pct"] >= 95.0
    assert figures["groups"]["Marker"]["taken_as_hand_pct"] <= 0.1
    assert main(["layout", "learn", str(later), "--out", str(tmp_path / "x.json")]) == 2
    assert "rate" in capsys.readouterr().err


def test_vendor_body_and_hands_take_learned_from_its_own_labels(shared_data):
    """ART's hand C3D (a body model with fingers, ``Human4:LIFT`` …): learned on its first half, its second
    half relabelled stripped and shuffled."""
    from handmocap.core.io import load_take

    path = shared_data / "c3d" / "sample_37__ART-Human_hands_real_no6dof.c3d"
    if not path.is_file():
        pytest.skip("the ART hand C3D is absent")
    figures = evaluate_take_labelling(load_take(path))
    digits = figures["template"]["hands"]["right"]["digits"]
    assert digits["Human4:RIFT"] == "index 3" and digits["Human4:RTTI"] == "thumb 3"
    assert digits["Human4:RPMI"] == "little 1" and digits["Human4:RHAN"] == "palm 0"
    assert "Human4:RFOO" in figures["template"]["ignored_markers"]
    for side in ("right", "left"):
        assert figures["groups"][side]["correct_pct"] >= 99.0
        assert figures["groups"][side]["wrong_pct"] == 0.0
