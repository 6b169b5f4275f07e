"""Filling gaps of a take: fill check (hide known stretches, measure each method), "auto" (the check's ranking
over the registered methods, :mod:`core.gaps.methods`), fill-all.

Provenance codes per (frame, marker): 0 measured, each method's code (:attr:`FillMethod.code`), -1 still
missing. Measured samples are never changed; donors are always measured samples.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.gaps.context import ModelContext
from handmocap.core.gaps.detect import Gap, find_gaps
from handmocap.core.gaps.fills import SPLINE_CONTEXT
from handmocap.core.gaps.methods import AUTO, check_fill_choice, fill_method, fill_method_names, fill_methods
from handmocap.core.ik import IKResult, solve_take
from handmocap.core.io import Take
from handmocap.core.model import HandModel, MarkerLayout, load_template
from handmocap.core.model.provenance import MEASURED, MISSING

#: order tried by ``fill_all(method="auto")`` when no stretch near a gap can be hidden to check the fills
FALLBACK_ORDER = ("pca", "model", "spline", "linear")
#: known stretches the fill check hides on each side of a gap, when there is room
STRETCHES_PER_SIDE = 2
#: gaps longer than this (s) are filled by PCA when it applies: over a longer gap the hand's motion is no longer
#: the one the nearby check stretches sample, and their errors stop predicting the local fills' errors
LOCAL_HORIZON_S = 0.5
#: another method displaces PCA only when it beats it by this factor on every hidden stretch, on the mean and on
#: the worst-frame error (the check's few stretches are a noisy sample; PCA is the better fill in general)
DISPLACE_FACTOR = 2.0
#: the fill check first looks for its hidden stretches within this many stretch sizes on each side of the gap
SEARCH_REACH = 4


def fill_gap(positions: np.ndarray, marker: int, start: int, length: int, method: str,
             context: ModelContext | None = None, joint_angles: np.ndarray | None = None) -> np.ndarray:
    """Fill frames ``start .. start + length - 1`` of take column ``marker`` with the registered ``method``
    (:func:`core.gaps.methods.fill_method`), (length, 3) mm.

    ``positions (F, M, 3)`` mm are the take's measured positions (the gap samples are ignored); ``context``
    (a hand model matched to the take) and ``joint_angles (F, 26)`` (IK solved with the gap missing) are
    for the methods that need a model. Raises InputError when the method is unknown or cannot apply.
    """
    return fill_method(method).fill(positions, marker, start, length, context, joint_angles)


@dataclass
class FillCheck:
    """Fill check of one gap: each applicable method fills hidden known stretches of the same length
    starting at frames ``test_starts`` (the nearest first, ``test_start``); ``errors_mm`` is its mean
    3D error over the stretches' frames, ``worst_mm`` its largest error in any frame, ``stretch_errors_mm``
    the (mean, worst) of each stretch (mm); ``reasons`` says why the other methods did not apply;
    ``frame_rate`` (Hz) of the take gives the gap's duration."""

    gap: Gap
    test_starts: tuple[int, ...]
    frame_rate: float = 100.0
    errors_mm: dict[str, float] = field(default_factory=dict)
    worst_mm: dict[str, float] = field(default_factory=dict)
    stretch_errors_mm: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    reasons: dict[str, str] = field(default_factory=dict)

    @property
    def test_start(self) -> int:
        """First frame of the hidden stretch nearest to the gap."""
        return self.test_starts[0]

    def score_mm(self, method: str) -> float:
        """Score of ``method`` (mm): the mean of its mean and its worst-frame error."""
        return 0.5 * (self.errors_mm[method] + self.worst_mm[method])

    def displaces_pca(self, method: str) -> bool:
        """Whether ``method`` beats PCA by :data:`DISPLACE_FACTOR` on every stretch, mean and worst frame."""
        return all(DISPLACE_FACTOR * mean < pca_mean and DISPLACE_FACTOR * worst < pca_worst
                   for (mean, worst), (pca_mean, pca_worst)
                   in zip(self.stretch_errors_mm[method], self.stretch_errors_mm["pca"], strict=True))

    def ranking(self) -> list[str]:
        """Applicable methods, the one to use first: PCA when it applies, unless the gap lasts at most
        :data:`LOCAL_HORIZON_S` and a method displaces it (:meth:`displaces_pca`, the best score first);
        the others by score (:meth:`score_mm`)."""
        order = sorted(self.errors_mm, key=self.score_mm)
        if "pca" not in self.errors_mm:
            return order
        short = self.gap.length <= LOCAL_HORIZON_S * self.frame_rate
        first = next((method for method in order if method != "pca" and short and self.displaces_pca(method)), "pca")
        return [first] + [method for method in order if method != first]


def _pick_stretches(candidates: np.ndarray, length: int, per_side: int) -> list[int]:
    """Up to ``per_side`` of ``candidates`` (stretch starts, the nearest to the gap first), each at least
    ``length`` frames from those already taken."""
    taken: list[int] = []
    for start in candidates.tolist():
        if all(abs(start - other) >= length for other in taken):
            taken.append(start)
            if len(taken) == per_side:
                break
    return taken


def _test_stretches(trajectory: np.ndarray, gap: Gap, margin: int, per_side: int = STRETCHES_PER_SIDE) -> list[int]:
    """Starts of up to ``per_side`` observed stretches of ``gap.length`` frames before the gap and as many
    after it, each with ``margin`` observed frames on each side, the nearest first and not overlapping;
    InputError when there is none. ``trajectory (F, 3)`` mm, NaN where missing.

    Only a window around the gap is read: it starts at :data:`SEARCH_REACH` stretch sizes on each side and
    doubles until each side has its stretches or reaches the end of the take. The candidates in a window
    are the nearest ones of the whole take, so the choice is the same as over the whole take."""
    size = gap.length + 2 * margin
    reach = SEARCH_REACH * size
    while True:
        first, last = max(0, gap.start - reach), min(len(trajectory), gap.end + reach)
        observed = (~np.isnan(trajectory[first:last]).any(axis=1)).astype(np.int64)
        counts = np.convolve(observed, np.ones(size, dtype=np.int64), mode="valid") if len(observed) >= size \
            else np.zeros(0, dtype=np.int64)
        starts = np.flatnonzero(counts == size) + margin + first
        before = _pick_stretches(starts[starts < gap.start][::-1], gap.length, per_side)
        after = _pick_stretches(starts[starts >= gap.end], gap.length, per_side)
        if (len(before) == per_side or first == 0) and (len(after) == per_side or last == len(trajectory)):
            break
        reach *= 2
    if not before and not after:
        raise InputError(f"fill check of '{gap.name}' needs {size} consecutive observed frames near the gap; "
                         "there are none")
    return sorted(before + after, key=lambda start: abs(start - gap.start))


class HiddenStretches:
    """The fill check's hidden stretches of one gap (:func:`_test_stretches`) and each method's errors on
    them, each fill computed once and only when asked for. Only the frames the fills of the stretches read
    are kept, so the cost does not grow with the take."""

    def __init__(self, take: Take, gap: Gap, context: ModelContext | None = None,
                 margin: int = SPLINE_CONTEXT) -> None:
        self.gap, self.context = gap, context
        self.starts = _test_stretches(take.marker_positions[:, gap.marker], gap, margin)
        pad = max(max((method.reach for method in fill_methods()), default=0), margin) + 1
        self.first = max(0, min(self.starts) - pad)
        self.positions = take.marker_positions[self.first:max(self.starts) + gap.length + pad]
        self._hidden: dict[int, np.ndarray] = {}
        self._errors: dict[tuple[str, int], np.ndarray | InputError] = {}

    def errors(self, method: str, index: int) -> np.ndarray:
        """3D errors (length,) mm of ``method`` on stretch ``index``; its InputError when it does not apply."""
        key = (method, index)
        if key not in self._errors:
            gap, start = self.gap, self.starts[index] - self.first
            if index not in self._hidden:
                self._hidden[index] = self.positions.copy()
                self._hidden[index][start:start + gap.length, gap.marker] = np.nan
            truth = self.positions[start:start + gap.length, gap.marker]
            try:
                values = fill_gap(self._hidden[index], gap.marker, start, gap.length, method, self.context)
                self._errors[key] = np.linalg.norm(values - truth, axis=1)
            except InputError as error:
                self._errors[key] = error
        result = self._errors[key]
        if isinstance(result, InputError):
            raise result
        return result


def check_gap(take: Take, gap: Gap, context: ModelContext | None = None,
              methods: tuple[str, ...] | None = None, margin: int = SPLINE_CONTEXT,
              stretches: HiddenStretches | None = None) -> FillCheck:
    """Hide measured stretches of ``gap.length`` frames near the gap (up to :data:`STRETCHES_PER_SIDE` on
    each side, ``margin`` observed frames around each), fill each with every method and report the mean
    and worst-frame 3D error in mm (ranked by :meth:`FillCheck.ranking`). The model fill solves its IK
    with the stretch hidden; a method that fails on any stretch is not applicable. ``stretches``: the
    stretches of this gap with fills already computed (:func:`fill_order`). ``methods``: default every
    registered one."""
    methods = fill_method_names() if methods is None else methods
    stretches = stretches or HiddenStretches(take, gap, context, margin)
    check = FillCheck(gap, tuple(stretches.starts), take.frame_rate)
    errors: dict[str, list[np.ndarray]] = {method: [] for method in methods}
    for index in range(len(stretches.starts)):
        for method in methods:
            if method in check.reasons:
                continue
            try:
                errors[method].append(stretches.errors(method, index))
            except InputError as error:
                check.reasons[method] = str(error)
    for method, per_stretch in errors.items():
        if method not in check.reasons:
            frames = np.concatenate(per_stretch)
            check.errors_mm[method] = float(frames.mean())
            check.worst_mm[method] = float(frames.max())
            check.stretch_errors_mm[method] = [(float(error.mean()), float(error.max())) for error in per_stretch]
    return check


def _first_choice(stretches: HiddenStretches, frame_rate: float) -> str | None:
    """The first method of the ranking of the full fill check (:meth:`FillCheck.ranking`), found with as few
    fills as that takes; None when PCA does not apply (the whole ranking is then by score).

    PCA comes first unless the gap is short and a method beats it by :data:`DISPLACE_FACTOR` on every
    stretch: a method stops being filled at the first stretch where it does not (it can no longer
    displace PCA, and where it ranks after the first only matters when the first fails on the gap)."""
    pca = []
    for index in range(len(stretches.starts)):
        try:
            pca.append(stretches.errors("pca", index))
        except InputError:
            return None
    if stretches.gap.length > LOCAL_HORIZON_S * frame_rate:
        return "pca"
    best, best_score = "pca", np.inf
    for method in fill_method_names():
        if method == "pca":
            continue
        per_stretch = []
        for index, pca_errors in enumerate(pca):
            try:
                errors = stretches.errors(method, index)
            except InputError:
                break
            if not (DISPLACE_FACTOR * float(errors.mean()) < float(pca_errors.mean())
                    and DISPLACE_FACTOR * float(errors.max()) < float(pca_errors.max())):
                break
            per_stretch.append(errors)
        else:
            frames = np.concatenate(per_stretch)
            score = 0.5 * (float(frames.mean()) + float(frames.max()))
            if score < best_score:
                best, best_score = method, score
    return best


def fill_order(take: Take, gap: Gap, context: ModelContext | None = None,
               none_applies: tuple[str, ...] = FALLBACK_ORDER) -> Iterator[str]:
    """The methods to try on ``gap``, in the order of its fill check's ranking (:func:`check_gap`); the
    first is found with as few fills of the hidden stretches as that takes (:func:`_first_choice`), the
    full check runs only when more are asked for. :data:`FALLBACK_ORDER` when no stretch can be hidden,
    ``none_applies`` when no method applies to the stretches."""
    try:
        stretches = HiddenStretches(take, gap, context)
    except InputError:
        yield from FALLBACK_ORDER
        return
    first = _first_choice(stretches, take.frame_rate)
    if first is not None:
        yield first
    ranking = check_gap(take, gap, context, stretches=stretches).ranking()
    yield from [method for method in ranking if method != first] if ranking else none_applies


#: a method that has not displaced PCA (:meth:`FillCheck.displaces_pca`) on this many checks in a row (of one
#: marker and gap-length class) is then checked only on every 2nd, 4th, 8th ... gap of that class
WARM_CHECKS = 3
#: ... but at least on every this many gaps of the class (the motion changes along a take)
MAX_INTERVAL = 32
#: methods whose check costs several PCA fills (the model fill's IK over the stretch): learned per group over all
#: its gaps, checked on its first gap and then on every :data:`MAX_INTERVAL`-th while they do not displace PCA
GROUP_LEARNED = ("model",)


class FillChooser:
    """The methods to try on each gap of one fill (``--method auto``), learning along the take when PCA wins.

    Per gap :func:`fill_order` fills the hidden stretches beside it with PCA and with every other method until
    none can displace PCA (:meth:`FillCheck.ranking`): a few PCA fills and an IK solve per gap. Here each method
    keeps, per marker and gap-length class (a power of two of frames; :data:`GROUP_LEARNED` per group), the
    number of checks in a row on which it did not displace PCA. From :data:`WARM_CHECKS` such losses on it is
    checked on every 2nd, 4th ... gap of its class only (at least every :data:`MAX_INTERVAL`-th); one that
    displaces PCA is checked on every gap again. A gap with no
    method due is filled by PCA without a check; a gap longer than :data:`LOCAL_HORIZON_S` needs none (nothing
    displaces PCA there). The first choice on a checked gap is :func:`_first_choice`'s for the methods checked;
    when PCA fails on the gap or on the nearest stretch, the gap gets the full check's ranking."""

    def __init__(self) -> None:
        self._cells: dict[tuple, list[int]] = {}    # key: [losses in a row, gaps since the last check]

    def _due(self, key: tuple) -> bool:
        losses, since = self._cells.setdefault(key, [0, 0])
        if key[1] in GROUP_LEARNED:
            interval = 1 if losses == 0 else MAX_INTERVAL
        else:
            interval = 1 if losses < WARM_CHECKS else min(2 ** (losses - WARM_CHECKS + 1), MAX_INTERVAL)
        self._cells[key][1] = since + 1
        return since + 1 >= interval

    def _checked(self, key: tuple, lost: bool) -> None:
        self._cells[key] = [self._cells[key][0] + 1 if lost else 0, 0]

    def order(self, take: Take, gap: Gap, context: ModelContext | None = None, group: object = 0,
              none_applies: tuple[str, ...] = FALLBACK_ORDER) -> Iterator[str]:
        """The methods to try on ``gap`` of ``take`` (the first as learned, then the full check's ranking when
        more are asked for); ``group``: the key of the take's group (its markers' cells are its own)."""
        if gap.length > LOCAL_HORIZON_S * take.frame_rate:
            yield "pca"
            yield from (method for method in fill_order(take, gap, context, none_applies) if method != "pca")
            return
        size = int(np.log2(gap.length))
        keys = {method: (group, method) if method in GROUP_LEARNED else (group, gap.marker, method, size)
                for method in fill_method_names() if method != "pca"}
        due = [method for method, key in keys.items() if self._due(key)]
        first = None
        if due:
            try:
                stretches = HiddenStretches(take, gap, context)
                pca = stretches.errors("pca", 0)
            except InputError:
                stretches = None
            if stretches is not None:
                first = self._first_checked(stretches, pca, due, keys)
        else:
            first = "pca"
        if first is not None:
            yield first
        yield from (method for method in fill_order(take, gap, context, none_applies) if method != first)

    def _first_checked(self, stretches: HiddenStretches, pca: np.ndarray, due: list[str],
                       keys: dict[str, tuple]) -> str | None:
        """:func:`_first_choice` over PCA and the ``due`` methods, given PCA's errors on the nearest stretch
        (``pca``); each due method's loss or near-win recorded. None when PCA fails on a further stretch."""
        best, best_score = "pca", np.inf
        for method in due:
            per_stretch: list[np.ndarray] = []
            for index in range(len(stretches.starts)):
                try:
                    errors = stretches.errors(method, index)
                    pca_errors = pca if index == 0 else stretches.errors("pca", index)
                except InputError:
                    if index and len(per_stretch) == index:
                        try:
                            stretches.errors("pca", index)
                        except InputError:
                            return None     # PCA does not apply on every stretch: the full check decides
                    break
                if not (DISPLACE_FACTOR * float(errors.mean()) < float(pca_errors.mean())
                        and DISPLACE_FACTOR * float(errors.max()) < float(pca_errors.max())):
                    break
                per_stretch.append(errors)
            displaces = len(per_stretch) == len(stretches.starts)
            self._checked(keys[method], lost=not displaces)
            if displaces:
                frames = np.concatenate(per_stretch)
                score = 0.5 * (float(frames.mean()) + float(frames.max()))
                if score < best_score:
                    best, best_score = method, score
        return best


def recommend(take: Take, gap: Gap, context: ModelContext | None = None) -> str:
    """The first method of the fill check ranking of ``gap``; InputError when none applies."""
    ranking = check_gap(take, gap, context).ranking()
    if not ranking:
        raise InputError(f"no fill method applies to the gap of '{gap.name}' at frame {gap.start}")
    return ranking[0]


def fill_all(take: Take, max_gap: int, method: str = "auto", ik_result: IKResult | None = None,
             model: HandModel | None = None, layout: MarkerLayout | None = None,
             progress: Callable[[float], None] | None = None,
             cancelled: Callable[[], bool] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Fill every closed gap of at most ``max_gap`` frames; returns positions (F, M, 3) mm and provenance
    (F, M) int (codes in the module docstring). Measured samples are copied unchanged.

    ``method`` is a registered method's name or "auto": per gap, the methods in the order of its fill
    check (or :data:`FALLBACK_ORDER` when the check cannot run), the first that applies. The model fill (and
    any method that needs a model) needs ``layout`` (``model`` defaults to the template) and uses
    ``ik_result`` (solved on this take, gaps missing, in layout order) or solves it. Gaps no method fills
    stay missing (-1).
    """
    check_fill_choice(method)
    if max_gap < 1:
        raise InputError(f"the maximum gap length must be at least 1 frame, got {max_gap}")
    if method != AUTO and fill_method(method).needs_model and layout is None:
        raise InputError(f"{method} fill needs a marker layout")
    context = None
    joint_angles = None
    if layout is not None and (method == AUTO or fill_method(method).needs_model):
        context = ModelContext.for_take(take.marker_names, model or load_template(), layout)
        if ik_result is None:
            ik_result = solve_take(take, context.model, layout, cancelled=cancelled)
        if ik_result.marker_names != context.markers.names or len(ik_result.joint_angles) != take.n_frames:
            raise InputError(f"the IK result does not belong to this take and layout '{layout.name}'")
        joint_angles = ik_result.joint_angles
    positions = take.marker_positions
    filled = positions.copy()
    provenance = np.where(take.missing_mask, MISSING, MEASURED)
    gaps = [gap for gap in find_gaps(take) if not gap.open and gap.length <= max_gap]
    chooser = FillChooser()
    for number, gap in enumerate(gaps):
        if cancelled is not None and cancelled():
            raise CancelledError("gap filling cancelled; the take is unchanged")
        order = chooser.order(take, gap, context, none_applies=()) if method == AUTO else (method,)
        for name in order:
            try:
                values = fill_gap(positions, gap.marker, gap.start, gap.length, name, context, joint_angles)
            except InputError:
                continue
            filled[gap.start:gap.end, gap.marker] = values
            provenance[gap.start:gap.end, gap.marker] = fill_method(name).code
            break
        if progress is not None:
            progress((number + 1) / len(gaps))
    return filled, provenance
