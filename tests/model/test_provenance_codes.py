"""One provenance code per fill method (its registration, core.gaps.methods): the gap filler, the review and
the marker lanes use the same codes and names."""

from handmocap.core import gaps, review
from handmocap.core.model.provenance import MEASURED, MISSING


def test_the_code_table_names_every_code_once():
    assert MEASURED == 0 and MISSING == -1
    codes = gaps.fill_codes()
    assert codes == {"linear": 1, "spline": 2, "pattern": 3, "rigid": 4, "model": 5, "pca": 6}   # stored in files
    assert tuple(codes) == gaps.fill_method_names()                                        # every method has a code
    assert gaps.provenance_names() == {MISSING: "missing", MEASURED: "measured",
                                       **{code: name for name, code in codes.items()}}


def test_gaps_and_review_use_the_one_table():
    assert gaps.MISSING == MISSING
    assert (review.MEASURED, review.MISSING) == (MEASURED, MISSING)
