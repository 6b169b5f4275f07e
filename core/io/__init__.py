"""Takes and their files: C3D, Qualisys TSV, TRC and CSV (millimetres, seconds, NaN for missing)."""

from core.io.errors import TakeFormatError
from core.io.loader import READ_SUFFIXES, TAKE_FILE_FILTER, load_take, save_take
from core.io.take import Take, is_marker_label, looks_unlabelled

__all__ = ["READ_SUFFIXES", "TAKE_FILE_FILTER", "Take", "TakeFormatError", "is_marker_label", "load_take",
           "looks_unlabelled", "save_take"]
