"""One registry of fill methods (issue 26 item 3): a method registered once is filled by ``fill_all``, checked by
the fill check, accepted by a pipeline file and a review fill, and gone again once unregistered."""

from __future__ import annotations

import numpy as np
import pytest

from handmocap.core.batch.pipeline import pipeline_from_dict
from handmocap.core.errors import InputError
from handmocap.core.gaps import (
    FillMethod,
    check_gap,
    fill_all,
    fill_choices,
    fill_method,
    fill_method_names,
    find_gaps,
    provenance_names,
    register_fill_method,
    unregister_fill_method,
)
from handmocap.core.io import Take


def _hold(positions: np.ndarray, marker: int, start: int, length: int, _context, _angles) -> np.ndarray:
    """The sample before the gap held through it, (length, 3) mm."""
    return np.repeat(positions[start - 1:start, marker], length, axis=0)


@pytest.fixture
def hold_method():
    """A sample-and-hold fill registered for one test."""
    method = register_fill_method(FillMethod(
        name="hold", label="Hold", description="The sample before the gap held through it",
        needs="1 measured frame before the gap", code=42, colour=(10, 20, 30), fill=_hold, reach=1, menu_rank=9))
    yield method
    unregister_fill_method("hold")


def _take() -> Take:
    """Five markers moving smoothly in 3D, one with a 5-frame gap."""
    time = np.arange(120)[:, None] / 100.0
    rng = np.random.default_rng(0)
    offsets, phases = rng.normal(0.0, 40.0, (5, 3)), rng.uniform(0.0, 6.0, (5, 3))
    positions = np.stack([offset + 20.0 * np.sin(3.0 * time + phase)
                          for offset, phase in zip(offsets, phases, strict=True)], axis=1)
    positions[50:55, 1] = np.nan
    return Take(["a", "b", "c", "d", "e"], positions, 100.0)


def test_the_built_in_methods_in_the_fill_checks_order():
    assert fill_method_names() == ("linear", "spline", "pattern", "rigid", "model", "pca")
    assert fill_choices() == ("auto", *fill_method_names())
    assert fill_method("model").needs_model and not fill_method("pca").needs_model
    with pytest.raises(InputError, match="unknown fill method 'cubic'.*linear, spline"):
        fill_method("cubic")


def test_a_registered_method_reaches_fill_all_the_check_and_pipelines(hold_method):
    assert fill_method_names()[-1] == "hold" and "hold" in fill_choices()
    take = _take()
    filled, provenance = fill_all(take, max_gap=10, method="hold")
    assert (provenance[50:55, 1] == 42).all() and provenance_names()[42] == "hold"
    np.testing.assert_array_equal(filled[50:55, 1], np.repeat(take.marker_positions[49:50, 1], 5, axis=0))
    check = check_gap(take, find_gaps(take)[0])
    assert "hold" in check.errors_mm
    assert pipeline_from_dict({"fill_method": "hold"}).fill_method == "hold"


def test_unregistered_is_gone_everywhere(hold_method):
    unregister_fill_method("hold")
    try:
        assert "hold" not in fill_choices()
        with pytest.raises(InputError, match="fill_method"):
            pipeline_from_dict({"fill_method": "hold"})
        with pytest.raises(InputError, match="unknown fill method 'hold'"):
            fill_all(_take(), max_gap=10, method="hold")
    finally:
        register_fill_method(hold_method)


def test_names_and_codes_are_never_shared(hold_method):
    with pytest.raises(ValueError, match="name 'hold' is taken"):
        register_fill_method(hold_method)
    with pytest.raises(ValueError, match="code 6 is taken"):
        register_fill_method(FillMethod(name="other", label="Other", description="", needs="", code=6,
                                        colour=(0, 0, 0), fill=_hold, reach=1, menu_rank=9))
    with pytest.raises(ValueError, match="'auto' is taken"):
        register_fill_method(FillMethod(name="auto", label="Auto", description="", needs="", code=43,
                                        colour=(0, 0, 0), fill=_hold, reach=1, menu_rank=9))
