"""Provenance codes: where a labelled marker's position in a frame comes from.

One int8 code per sample (``provenance (F, M)`` of a review, the ``PROVENANCE`` parameter of a
labelled C3D): :data:`MEASURED` 0 (a measured point), 1..6 an accepted fill by the method of
:data:`FILL_CODES`, :data:`MISSING` -1 (no position).
"""

from __future__ import annotations

MEASURED = 0
MISSING = -1
#: fill method -> provenance code
FILL_CODES: dict[str, int] = {"linear": 1, "spline": 2, "pattern": 3, "rigid": 4, "model": 5, "pca": 6}
#: provenance code -> name (the fill methods plus "measured" and "missing")
PROVENANCE_NAMES: dict[int, str] = {MISSING: "missing", MEASURED: "measured",
                                    **{code: name for name, code in FILL_CODES.items()}}

__all__ = ["FILL_CODES", "MEASURED", "MISSING", "PROVENANCE_NAMES"]
