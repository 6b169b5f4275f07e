"""One provenance code table (core.model.provenance): the gap filler, the review and the marker lanes use
the same codes and names."""

from handmocap.core import gaps, review
from handmocap.core.model.provenance import FILL_CODES, MEASURED, MISSING, PROVENANCE_NAMES


def test_the_code_table_names_every_code_once():
    assert MEASURED == 0 and MISSING == -1
    assert sorted(FILL_CODES.values()) == list(range(1, len(FILL_CODES) + 1))     # 1..6, none shared
    expected = {MISSING: "missing", MEASURED: "measured", **{code: name for name, code in FILL_CODES.items()}}
    assert expected == PROVENANCE_NAMES
    assert tuple(FILL_CODES) == gaps.FILL_METHODS                               # every fill method has a code


def test_gaps_and_review_use_the_one_table():
    assert gaps.METHOD_CODES is FILL_CODES and gaps.MISSING == MISSING
    assert review.FILL_CODES is FILL_CODES and review.PROVENANCE_NAMES is PROVENANCE_NAMES
    assert (review.MEASURED, review.MISSING) == (MEASURED, MISSING)
