"""Health warnings say something (issue 23 item 3): figures are compared with the take's own spread, under a
floor nothing is said, neighbouring flagged windows are one warning, re-initialisations close together one."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np

from handmocap.core.labelling.health import assess_labelling

RATE = 100.0
FRAMES = 6000
MARKERS = 10


def _result(residuals: np.ndarray, reinitialised: list[int] | None = None, noise: float | None = 0.3):
    assignment = np.tile(np.arange(MARKERS), (FRAMES, 1))
    hand = SimpleNamespace(kind="right", name="right", init_frame=0, reinitialised=reinitialised or [],
                           markers=slice(0, MARKERS))
    return SimpleNamespace(assignment=assignment, residuals_mm=residuals, models=[hand], noise_mm=noise,
                           side_decision=None, points=np.zeros((FRAMES, MARKERS, 3)),
                           ghost_points=np.zeros((FRAMES, MARKERS), dtype=bool))


def _figures(message: str) -> list[str]:
    return re.findall(r"(\d+(?:\.\d+)?) mm", message)


def test_a_clean_take_raises_nothing_even_when_its_residuals_vary_below_the_floor():
    rng = np.random.default_rng(0)
    residuals = np.abs(rng.normal(0.02, 0.01, (FRAMES, MARKERS)))      # a noise-free take: hundredths of a mm
    residuals[1300:1600] *= 4                                           # four times "worse": still 0.08 mm
    assert assess_labelling(_result(residuals, noise=0.0), RATE) == []
    residuals = np.abs(rng.normal(0.4, 0.1, (FRAMES, MARKERS)))         # 0.3 mm noise, no trouble
    assert assess_labelling(_result(residuals), RATE) == []


def test_a_bad_stretch_is_one_warning_with_two_different_figures():
    rng = np.random.default_rng(1)
    residuals = np.abs(rng.normal(0.4, 0.1, (FRAMES, MARKERS)))
    residuals[2000:2200] = 4.0                      # two bad seconds,
    residuals[2400:2500] = 5.0                      # one good second and one more bad second: one stretch
    warnings = assess_labelling(_result(residuals), RATE)
    assert [warning.kind for warning in warnings] == ["high_residual"]
    warning = warnings[0]
    assert (warning.first_frame, warning.last_frame) == (2000, 2499)
    here, typical = _figures(warning.message)
    assert here != typical and float(here) == 5.0, warning.message


def test_reinitialisations_close_together_are_one_warning():
    residuals = np.full((FRAMES, MARKERS), 0.4)
    warnings = assess_labelling(_result(residuals, reinitialised=[1000, 1100, 1350, 4000]), RATE)
    assert [(w.kind, w.first_frame, w.last_frame) for w in warnings] == [
        ("reinitialised", 1000, 1350), ("reinitialised", 4000, 4000)]
    assert "3 times" in warnings[0].message
