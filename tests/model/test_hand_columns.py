"""The hands of a labelled take found from its marker names (:func:`core.model.detect_hands`): ``label --hands
both``'s ``R_``/``L_``, a lab template's names, a vendor's side tokens and subjects; a left hand found as left;
a take no layout matches refused in one line; a review's hands and the layout of their labels."""

from __future__ import annotations

import numpy as np
import pytest
from two_hand_takes import LAYOUT, STYLES, marker_name, named_take, write_lab_template

from handmocap.core.errors import InputError
from handmocap.core.model import (
    add_layout_folder,
    detect_hands,
    load_layout,
    name_side,
    remove_layout_folder,
    track_layout,
)
from handmocap.core.review import ReviewTake
from handmocap.core.review.export import labelled_hands

GLOVE = load_layout(LAYOUT).names


@pytest.fixture
def lab_folder(tmp_path):
    """A folder of layouts (as a session's ``layouts``) holding a lab template, searched while the test runs."""
    write_lab_template(tmp_path)
    add_layout_folder(tmp_path)
    yield tmp_path
    remove_layout_folder(tmp_path)


@pytest.mark.parametrize("style", STYLES)
def test_both_hands_are_found_with_their_columns_in_layout_order(style, lab_folder):
    names = [marker_name(style, side, marker) for side in ("left", "right") for marker in GLOVE] + ["guitar1"]
    hands = detect_hands(names)
    assert [hand.side for hand in hands] == ["right", "left"]
    assert all(hand.side_from_names and hand.present.all() for hand in hands)
    assert hands[0].columns.tolist() == list(range(13, 26)) and hands[1].columns.tolist() == list(range(13))
    expected = "guitar-lab" if style == "template" else LAYOUT
    assert {hand.layout_name for hand in hands} == {expected}
    if style == "template":   # the layout of each side holds the lab's own names
        assert hands[1].layout.names[0] == "L-Wan-nei" and hands[0].layout.names[0] == "R-Wan-nei"
    else:
        assert hands[0].layout.names == GLOVE


def test_a_template_given_as_a_file_is_used_without_being_in_a_layout_folder(tmp_path):
    path = write_lab_template(tmp_path)
    names = [marker_name("template", "left", marker) for marker in GLOVE]
    assert detect_hands(names) == []     # not known without the file
    hands = detect_hands(names, str(path))
    assert [hand.side for hand in hands] == ["left"] and hands[0].layout_name == str(path)


@pytest.mark.parametrize("names, side", [
    ([f"L_{name}" for name in GLOVE], "left"),
    ([f"LeftHand:{name}" for name in GLOVE], "left"),
    ([f"{name}_l" for name in GLOVE], "left"),
    ([f"Right:{name}" for name in GLOVE], "right"),
])
def test_one_hand_whose_names_say_the_side_is_that_side(names, side):
    hands = detect_hands(names)
    assert [(hand.side, hand.side_from_names) for hand in hands] == [(side, True)]
    assert hands[0].present.all()


def test_a_hand_whose_names_say_no_side_takes_the_side_given_else_right():
    names = [f"Subject:{name}" for name in GLOVE[:-2]]      # a Vicon subject that says no side, two markers short
    hands = detect_hands(names)
    assert [(hand.side, hand.side_from_names) for hand in hands] == [("right", False)]
    assert hands[0].columns.tolist() == list(range(11)) + [-1, -1]
    assert detect_hands(names, side="left")[0].side == "left"
    assert hands[0].present_layout.names == GLOVE[:-2]


def test_names_matching_no_layout_are_refused_in_one_line():
    names = [f"Human4:{name}" for name in ("LHAN", "LIFI", "LIFM", "RHAN", "RIFI", "RIFM", "PELV")]
    assert detect_hands(names) == []
    with pytest.raises(InputError, match="no layout matches these names: learn one with `handmocap layout learn`"):
        detect_hands(names, required=True)
    with pytest.raises(InputError, match="only 0 of the 13 markers of layout 'glove-13'"):
        detect_hands(names, LAYOUT, required=True)


def test_name_side_reads_the_vendors_side_tokens():
    assert name_side("R_index_tip") == ("right", "index_tip")
    assert name_side("L-A1") == ("left", "A1")
    assert name_side("LeftHand:IF3") == ("left", "IF3")
    assert name_side("Subject:index_tip") == (None, "index_tip")
    from handmocap.core.labelling.templates import name_side as labelling_name_side  # still found where it was
    assert labelling_name_side is name_side


def test_track_layout_gives_the_markers_of_a_hands_labels_in_their_order(lab_folder):
    layout = track_layout(LAYOUT, "left", ["L_thumb_tip", "L_hand_top"])
    assert layout.names == ["thumb_tip", "hand_top"]
    assert track_layout("guitar-lab", "right", ["R-A1"]).names == ["R-A1"]
    with pytest.raises(InputError, match="not markers of layout"):
        track_layout(LAYOUT, "left", ["L_thumb_tip", "guitar1"])


def test_a_labelled_takes_review_holds_its_hands():
    take = named_take("vicon", frames=20)
    review = ReviewTake.from_labelled_take(take)
    assert [(hand.side, hand.layout, len(hand.labels)) for hand in review.hands] == [("right", LAYOUT, 13),
                                                                                    ("left", LAYOUT, 13)]
    assert [review.label_names[label] for label in review.hands[1].labels][:2] == ["LeftHand:hand_top",
                                                                                  "LeftHand:hand_left"]
    assert np.isnan(review.hands[0].joint_angles).all()


def test_a_labelled_c3d_says_the_side_of_a_hand_its_names_do_not():
    tracks = labelled_hands(list(GLOVE), ["left:left:glove-13"], 10)
    assert [(track.name, track.side) for track in tracks] == [("left", "left")]
    tracks = labelled_hands(list(GLOVE), [], 10)      # another program's C3D: recognised, right by default
    assert [(track.side, track.layout) for track in tracks] == [("right", LAYOUT)]
