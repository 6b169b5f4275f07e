"""Fixtures shared by every test folder (one folder per package under test: tests/io, tests/labelling, ...).

The real data lives outside the project (:mod:`core.evaluation.data`); tests that need it ask for these
fixtures and are skipped when it is absent.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import replace
from functools import lru_cache

import pytest

from handmocap.core.evaluation.data import REAL_RECORDING, SHARED_DATA
from handmocap.core.io import Take, load_take
from handmocap.core.model import HandModel, load_template


@lru_cache(maxsize=1)
def _real_recording() -> Take:
    return load_take(REAL_RECORDING)


@pytest.fixture
def real_recording() -> Take:
    """The real DFKI glove recording (3000 frames at 100 Hz, 21 labelled markers, mm): a fresh copy for each
    test (read from disk once per run), so a test may change it."""
    if not REAL_RECORDING.is_file():
        pytest.skip(f"the real recording is not in {REAL_RECORDING.parent}")
    take = _real_recording()
    return replace(take, marker_names=list(take.marker_names), marker_positions=take.marker_positions.copy(),
                   parameters=dict(take.parameters))


@pytest.fixture
def shared_data():
    """The shared data folder (``../shared/data``); the test is skipped when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} is absent")
    return SHARED_DATA


@pytest.fixture(scope="session")
def template() -> HandModel:
    """The shipped right template hand."""
    return load_template()


@pytest.fixture
def cancel_after():
    """A factory of ``cancelled`` callbacks: ``cancel_after(n)`` answers False n times, then True."""
    def make(calls: int) -> Callable[[], bool]:
        counter = itertools.count(1)
        return lambda: next(counter) > calls
    return make
