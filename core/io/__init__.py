"""Takes and their files: C3D, Qualisys TSV, TRC and CSV (millimetres, seconds, NaN for missing)."""

from core.io.errors import TakeFormatError
from core.io.loader import load_take, save_take
from core.io.take import Take

__all__ = ["Take", "TakeFormatError", "load_take", "save_take"]
