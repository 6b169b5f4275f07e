"""A hand's gaps are filled per hand, but the fills that reconstruct a marker from others (PCA, pattern) and
their fill check use every labelled marker of the take as donors: an object held in the fingers, the arm."""

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.review import ReviewTake
from handmocap.core.simulate import simulate_take
from handmocap.core.workflows import check_review_gap, fill_review_gaps, find_review_gaps, gap_groups, preview_fill

#: an object held in the fingers: each of its markers follows one fingertip at a fixed offset
HELD = {"pillow_top": "index_tip", "pillow_left": "thumb_tip", "pillow_right": "middle_tip"}
GAPS = ((100, 40), (300, 40), (450, 40))


@pytest.fixture(scope="module")
def takes():
    """A glove-13 take with the object's markers (labelled, not the hand's), the same take without them,
    both with gaps of index_tip; and the truth."""
    simulated = simulate_take(layout="glove-13", n_frames=600, seed=4, noise_mm=0.3).take
    names, truth = list(simulated.marker_names), simulated.marker_positions
    rng = np.random.default_rng(0)
    held = np.stack([truth[:, names.index(tip)] + rng.normal(0.0, 15.0, 3) for tip in HELD.values()], axis=1)
    positions = np.concatenate([truth, held + rng.normal(0.0, 0.3, held.shape)], axis=1)
    for start, length in GAPS:
        positions[start:start + length, names.index("index_tip")] = np.nan
    with_object = Take(names + list(HELD), positions, simulated.frame_rate)
    hand_only = Take(names, positions[:, :len(names)].copy(), simulated.frame_rate)
    return with_object, hand_only, truth


def _pca_fill(take: Take, truth: np.ndarray) -> tuple[np.ndarray, list[float]]:
    """Errors (mm) of ``handmocap fill --method pca`` on the gaps, and the fill check's PCA error per gap."""
    review = ReviewTake.from_labelled_take(take)
    groups = gap_groups(review)
    gaps = find_review_gaps(review, groups)
    assert [(gap.name, gap.start, gap.length) for gap in gaps] == [("index_tip", *gap) for gap in GAPS]
    checks = [check_review_gap(groups[gap.group], gap).errors_mm["pca"] for gap in gaps]
    fill_review_gaps(review, groups, 60, "pca").do(review)
    tip, filled = gaps[0].label, review.labelled_positions()
    return np.concatenate([np.linalg.norm(filled[start:start + length, tip] - truth[start:start + length, tip],
                                          axis=1) for start, length in GAPS]), checks


def test_a_hand_groups_pca_fill_uses_the_takes_other_labelled_markers(takes):
    with_object, hand_only, truth = takes
    review = ReviewTake.from_labelled_take(with_object)
    hand, rest = gap_groups(review)
    assert hand.labels.tolist() == list(range(13)) and hand.context is not None   # the gaps stay per hand
    assert hand.donors.tolist() == [13, 14, 15] and rest.labels.tolist() == [13, 14, 15]
    assert hand.take.marker_names[13:] == list(HELD) and rest.donors.tolist() == list(range(13))
    with_donors, checks_with = _pca_fill(with_object, truth)
    without, checks_without = _pca_fill(hand_only, truth)
    assert np.isfinite(with_donors).all() and with_donors.mean() < 0.5 * without.mean()
    assert all(mine < 0.5 * other for mine, other in zip(checks_with, checks_without, strict=True))


def test_a_pattern_fill_may_follow_a_marker_outside_the_hand(takes):
    with_object, _, truth = takes
    review = ReviewTake.from_labelled_take(with_object)
    groups = gap_groups(review)
    gap = find_review_gaps(review, groups)[0]
    values = preview_fill(groups[gap.group], gap, "pattern", donor=with_object.marker_names.index("pillow_top"))
    assert np.linalg.norm(values - truth[gap.start:gap.start + gap.length, gap.label], axis=1).mean() < 2.0
    with pytest.raises(InputError, match="another labelled marker"):
        preview_fill(groups[gap.group], gap, "pattern", donor=gap.label)


def test_a_donor_named_as_one_of_the_groups_layout_markers_is_told_apart():
    """Two hands, the right one labelled with the layout's bare names: the left hand's group (named by its layout
    markers) takes the right hand's labels as donors under other names, and both hands' gaps are filled."""
    right = simulate_take(layout="dense", n_frames=400, seed=2, noise_mm=0.3).take
    left = simulate_take(layout="dense", n_frames=400, seed=3, noise_mm=0.3).take
    positions = np.concatenate([right.marker_positions, left.marker_positions + [400.0, 0.0, 0.0]], axis=1)
    positions[100:120, 3] = np.nan
    positions[200:220, len(right.marker_names) + 3] = np.nan
    take = Take(list(right.marker_names) + [f"L_{name}" for name in left.marker_names], positions, right.frame_rate)
    review = ReviewTake.from_labelled_take(take)
    groups = gap_groups(review)
    assert len(groups) == 2
    command = fill_review_gaps(review, groups, 40)
    assert command is not None and len(command.fills) == 2
