"""Gap fills work on a window around each gap: the frames a fill reads do not grow with the take, and the
windowed fill equals the fill over the whole take (the stretch search, the fill order, the fills)."""

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from handmocap.core.errors import InputError
from handmocap.core.gaps import ModelContext, check_gap, fill_gap, find_gaps
from handmocap.core.gaps.builtin_methods import IK_PAD
from handmocap.core.gaps.check import FALLBACK_ORDER, _test_stretches, fill_order
from handmocap.core.gaps.fills import MODEL_FIT, SPLINE_CONTEXT, fill_linear, fill_model, fill_pattern, fill_spline
from handmocap.core.io import Take
from handmocap.core.model import load_layout, load_template
from handmocap.core.review import ReviewTake
from handmocap.core.simulate import simulate_take
from handmocap.core.workflows import fill_gaps, gap_groups, short_open_gaps

BASE_FRAMES = 2000


class FrameTracker(np.ndarray):
    """A ``(F, ...)`` array that records which of its frames (axis 0) are read: by indexing that selects
    frames, or by a numpy function or ufunc given a view that spans frames. A view of every frame
    (``positions[:, marker]``) is tracked too and counts only once something reads it."""

    def __new__(cls, values: np.ndarray, frames: np.ndarray | None = None, touched: set | None = None):
        tracked = np.asarray(values).view(cls)
        tracked.frames = np.arange(len(values)) if frames is None else frames
        tracked.touched = set() if touched is None else touched
        return tracked

    def __array_finalize__(self, source):
        self.frames = getattr(source, "frames", None)
        self.touched = getattr(source, "touched", None)

    def _plain(self) -> np.ndarray:
        self.touched.update(np.atleast_1d(self.frames).tolist())
        return self.view(np.ndarray)

    def __getitem__(self, key):
        first = key[0] if isinstance(key, tuple) else key
        result = np.ndarray.__getitem__(self.view(np.ndarray), key)
        if first is Ellipsis or (isinstance(first, slice) and first == slice(None)):   # every frame, not read yet
            return FrameTracker(result, self.frames, self.touched) if np.ndim(result) else result
        self.touched.update(np.atleast_1d(self.frames[first]).tolist())
        return result

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        plain = [value._plain() if isinstance(value, FrameTracker) else value for value in inputs]
        return getattr(ufunc, method)(*plain, **kwargs)

    def __array_function__(self, function, types, args, kwargs):
        def plain(value):
            if isinstance(value, FrameTracker):
                return value._plain()
            if isinstance(value, (list, tuple)):
                return type(value)(plain(item) for item in value)
            return value
        return function(*plain(args), **plain(kwargs))

    def copy(self, order="C"):
        return self._plain().copy(order)


def dense_take(n_frames: int) -> Take:
    """A labelled, occluded dense take of :data:`BASE_FRAMES` frames tiled to ``n_frames`` (every other
    copy backwards, so the trajectories are continuous): frames ``k * 2 * BASE_FRAMES + f`` hold frame f."""
    base = simulate_take("dense", n_frames=BASE_FRAMES, seed=1, noise_mm=0.3, occlusion=True).take
    copies = [base.marker_positions if index % 2 == 0 else base.marker_positions[::-1]
              for index in range(-(-n_frames // BASE_FRAMES))]
    return Take(list(base.marker_names), np.concatenate(copies)[:n_frames].copy(), base.frame_rate)


@pytest.fixture(scope="module")
def short_take():
    return dense_take(BASE_FRAMES)


@pytest.fixture(scope="module")
def long_take():
    return dense_take(40_000)


def test_the_tracker_sees_a_read_of_every_frame():
    tracked = FrameTracker(np.zeros((50, 4, 3)))
    trajectory = tracked[:, 2]
    assert not tracked.touched
    np.isnan(trajectory[10:20]).any()
    assert tracked.touched == set(range(10, 20))
    np.isfinite(trajectory).all()
    assert tracked.touched == set(range(50))


def _fill_tracked(take: Take, start: int) -> tuple[int, list]:
    """Frames read by ``fill_gaps`` (auto) of the first gap starting at frame ``start``, and the fills."""
    review = ReviewTake.from_labelled_take(take)
    groups = gap_groups(review)
    gaps = [gap for gap in short_open_gaps(review, groups, 80) if gap.start == start]
    assert gaps
    group = groups[gaps[0].group]
    group.take.marker_positions = FrameTracker(group.take.marker_positions)
    command = fill_gaps(groups, gaps[:1])
    return len(group.take.marker_positions.touched), command.fills


def test_one_gap_reads_as_many_frames_in_a_long_take_as_in_a_short_one(short_take, long_take):
    review = ReviewTake.from_labelled_take(short_take)
    gaps = short_open_gaps(review, gap_groups(review), 80)
    start = min((gap for gap in gaps if gap.start >= 900), key=lambda gap: gap.start).start
    short_frames, short_fills = _fill_tracked(short_take, start)
    long_frames, long_fills = _fill_tracked(long_take, 10 * BASE_FRAMES + start)   # a forward copy mid-take
    assert 0 < short_frames < BASE_FRAMES
    assert long_frames == short_frames
    assert [fill.method for fill in long_fills] == [fill.method for fill in short_fills]
    np.testing.assert_array_equal(long_fills[0].positions, short_fills[0].positions)


def _whole_take_stretches(observed: np.ndarray, gap, margin: int, per_side: int = 2) -> list[int]:
    """The fill check's stretch search over every frame of the marker (before it worked on a window)."""
    size = gap.length + 2 * margin
    counts = np.convolve(observed.astype(np.int64), np.ones(size, dtype=np.int64), mode="valid")
    starts = np.flatnonzero(counts == size) + margin
    if not starts.size:
        raise InputError("none")
    chosen: list[int] = []
    for side in (starts[starts < gap.start][::-1], starts[starts >= gap.end]):
        taken: list[int] = []
        for candidate in side.tolist():
            if all(abs(candidate - other) >= gap.length for other in taken):
                taken.append(candidate)
                if len(taken) == per_side:
                    break
        chosen += taken
    return sorted(chosen, key=lambda candidate: abs(candidate - gap.start))


def test_windowed_stretch_search_equals_the_whole_take_search(short_take):
    positions = short_take.marker_positions.copy()
    positions[100:1700, 3] = np.nan                     # a marker missing for long: the window must grow
    take = Take(list(short_take.marker_names), positions, short_take.frame_rate)
    gaps = [gap for gap in find_gaps(take) if not gap.open]
    assert any(gap.marker == 3 for gap in gaps)
    for gap in gaps:
        for margin in (2, 10, 40):
            observed = ~take.missing_mask[:, gap.marker]
            try:
                expected = _whole_take_stretches(observed, gap, margin)
            except InputError:
                with pytest.raises(InputError):
                    _test_stretches(take.marker_positions[:, gap.marker], gap, margin)
                continue
            assert _test_stretches(take.marker_positions[:, gap.marker], gap, margin) == expected


def test_fill_order_equals_the_full_check_ranking(short_take):
    context = ModelContext.for_take(short_take.marker_names, load_template(), load_layout("dense"))
    gaps = [gap for gap in find_gaps(short_take) if not gap.open and gap.length <= 80][::4]
    assert len(gaps) >= 10
    for gap in gaps:
        try:
            expected = check_gap(short_take, gap, context).ranking() or list(FALLBACK_ORDER)
        except InputError:
            expected = list(FALLBACK_ORDER)
        assert list(fill_order(short_take, gap, context)) == expected


def _observed_starts(positions: np.ndarray, marker: int, length: int, pad: int) -> np.ndarray:
    """Frames where ``marker`` is measured from ``pad`` frames before to ``pad`` frames after a stretch of
    ``length`` frames starting there."""
    observed = np.isfinite(positions[:, marker]).all(axis=1).astype(int)
    counts = np.convolve(observed, np.ones(length + 2 * pad, dtype=int), mode="valid")
    return np.flatnonzero(counts == length + 2 * pad) + pad


def test_model_fill_with_ik_stopped_after_the_gap_equals_ik_over_the_whole_window(short_take):
    context = ModelContext.for_take(short_take.marker_names, load_template(), load_layout("dense"))
    positions = short_take.marker_positions
    marker, length = short_take.marker_names.index("index_distal"), 12
    index = context.layout_index(marker)
    starts = _observed_starts(positions, marker, length, IK_PAD)
    assert len(starts) > 100 and MODEL_FIT < IK_PAD
    for start in starts[[0, len(starts) // 2, -1]]:
        window = context.layout_positions(positions[start - IK_PAD:start + length + IK_PAD])
        window[IK_PAD:IK_PAD + length, index] = np.nan
        expected = fill_model(window, IK_PAD, length, index, context.solve(window), context.model, context.markers)
        np.testing.assert_array_equal(fill_gap(positions, marker, int(start), length, "model", context), expected)


def test_pattern_and_spline_fills_equal_their_whole_take_forms(short_take):
    positions = short_take.marker_positions
    marker, donor = short_take.marker_names.index("index_distal"), short_take.marker_names.index("index_middle")
    length = 15
    starts = _observed_starts(positions, marker, length, SPLINE_CONTEXT)
    starts = starts[np.isfinite(positions[starts - 1, donor]).all(axis=1)
                    & np.isfinite(positions[starts + length, donor]).all(axis=1)]
    for start in starts[[0, len(starts) // 2, -1]]:
        donor_span = positions[start - 1:start + length + 1, donor]
        if not np.isfinite(donor_span).all():
            continue
        hidden = positions[:, marker].copy()
        hidden[start:start + length] = np.nan
        expected = positions[start:start + length, donor] + fill_linear(hidden - positions[:, donor], start, length)
        np.testing.assert_array_equal(fill_pattern(hidden, int(start), length, positions[:, donor]), expected)
        frames = np.r_[start - SPLINE_CONTEXT:start, start + length:start + length + SPLINE_CONTEXT]
        spline = CubicSpline(frames, hidden[frames], axis=0)(np.arange(start, start + length))
        np.testing.assert_array_equal(fill_spline(hidden, int(start), length), spline)


def test_auto_learns_when_pca_wins_and_checks_as_the_full_check_does_until_then(short_take):
    """``fill --method auto`` (:class:`FillChooser`): a gap on which the local methods are due gets the first
    method of its full check (the model fill, checked on fewer gaps, never displaced PCA here); a method that has
    not displaced PCA on WARM_CHECKS checks in a row is checked on fewer gaps; a gap longer than the local horizon
    goes to PCA without a check."""
    from handmocap.core.gaps import check as check_module

    context = ModelContext.for_take(short_take.marker_names, load_template(), load_layout("dense"))
    gaps = [gap for gap in find_gaps(short_take) if not gap.open and gap.length <= 80]
    chooser = check_module.FillChooser()
    due: list[bool] = []
    original_due = chooser._due

    def recording(key):
        answer = original_due(key)
        if key[1] not in check_module.GROUP_LEARNED:
            due.append(answer)
        return answer

    chooser._due = recording
    compared = skipped = 0
    for gap in gaps:
        due.clear()
        first = next(chooser.order(short_take, gap, context))
        if gap.length > check_module.LOCAL_HORIZON_S * short_take.frame_rate:
            assert first == "pca" and not due
        elif all(due):
            assert first == next(fill_order(short_take, gap, context))
            compared += 1
        elif not any(due):
            assert first == "pca"
            skipped += 1
    assert compared >= 5 and skipped >= 1
    learned = [cell for key, cell in chooser._cells.items() if len(key) == 4 and cell[0] >= check_module.WARM_CHECKS]
    assert learned, "no method was found to lose to PCA often enough to be checked less"


def test_pca_pose_kernel_equals_kabsch_by_svd():
    from handmocap.core.gaps.pca_kernel import poses_kernel

    rng = np.random.default_rng(3)
    for trial in range(60):
        count = int(rng.integers(3, 8))
        reference = rng.normal(size=(count, 3)) * 30
        if trial % 3 == 0:
            reference[:, 2] *= 1e-5                     # donors nearly coplanar: Horn's quaternion
        donors = rng.normal(size=(40, count, 3)) * 30
        if trial % 4 == 0:
            donors[:, :, 2] *= -1.0                     # reflections
        share = rng.random(count)
        share /= share.sum()
        origins, rotations = poses_kernel(donors, reference, share)
        np.testing.assert_allclose(origins, np.einsum("k,nki->ni", share, donors))
        covariance = np.einsum("k,ki,nkj->nij", share, reference - share @ reference, donors - origins[:, None])
        u, _, vt = np.linalg.svd(covariance)
        flip = np.ones((len(donors), 3))
        flip[:, 2] = np.sign(np.linalg.det(u @ vt))
        expected = np.einsum("nji,nj,nkj->nik", vt, flip, u)
        np.testing.assert_allclose(np.einsum("nij,nji->n", rotations, covariance),
                                   np.einsum("nij,nji->n", expected, covariance), rtol=1e-9, atol=1e-9)
        identity = np.broadcast_to(np.eye(3), rotations.shape)
        np.testing.assert_allclose(rotations @ rotations.transpose(0, 2, 1), identity, atol=1e-9)
        if trial % 3:
            np.testing.assert_allclose(rotations, expected, atol=1e-7)
