"""Units and up axis of exported files.

Our data are in mm in the lab frame of the capture, Z up (as C3D). Files for other tools may want
"cm" or "m" and a Y-up frame. Y up is reached by a proper rotation of -90° about X (right-handed
frames stay right-handed): ``(x, y, z) -> (x, z, -y)``, so the lab's horizontal X stays X and the
lab's Y axis points along -Z (towards the viewer in Y-up tools whose forward is -Z).
"""

from __future__ import annotations

import numpy as np

from handmocap.core.errors import InputError

#: length units per mm
UNITS: dict[str, float] = {"mm": 1.0, "cm": 0.1, "m": 0.001}
UP_AXES = ("z", "y")
#: rotation taking Z-up lab coordinates to Y-up coordinates (row-vector form: ``v @ Y_UP.T``)
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def check_units(units: str) -> float:
    """Length units per mm of ``units`` ("mm", "cm", "m"); InputError otherwise."""
    if units not in UNITS:
        raise InputError(f"units must be mm, cm or m, not '{units}'")
    return UNITS[units]


def axes_rotation(up: str) -> np.ndarray:
    """The rotation ``(3, 3)`` from our Z-up lab frame to a frame with ``up`` ("z": identity, "y")."""
    if up not in UP_AXES:
        raise InputError(f"up axis must be y or z, not '{up}'")
    return Y_UP.copy() if up == "y" else np.eye(3)


def convert_points(points: np.ndarray, units: str = "mm", up: str = "z") -> np.ndarray:
    """``points (..., 3)`` mm, Z up, in ``units`` with ``up`` (NaN stays NaN); a new float64 array."""
    return np.asarray(points, dtype=np.float64) @ axes_rotation(up).T * check_units(units)
