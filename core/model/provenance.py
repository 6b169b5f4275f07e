"""Provenance codes: where a labelled marker's position in a frame comes from.

One int8 code per sample (``provenance (F, M)`` of a review, the ``PROVENANCE`` parameter of a
labelled C3D): :data:`MEASURED` 0 (a measured point), :data:`MISSING` -1 (no position), and an accepted
fill by the fill method whose provenance code it is (1..127, :attr:`core.gaps.methods.FillMethod.code`).
"""

from __future__ import annotations

MEASURED = 0
MISSING = -1

__all__ = ["MEASURED", "MISSING"]
