"""Takes and their files: C3D, Qualisys TSV, TRC, the CSV exports of Vicon Nexus, OptiTrack Motive and NOKOV,
and CSV of axis columns (millimetres, seconds, NaN for missing)."""

from handmocap.core.io.errors import FrameRateMissingError, TakeFormatError
from handmocap.core.io.loader import (
    READ_SUFFIXES,
    TAKE_FILE_FILTER,
    TAKE_FORMATS,
    TakeFormat,
    load_take,
    recognised_format,
    save_take,
    take_format,
)
from handmocap.core.io.take import Take, is_marker_label, looks_unlabelled

__all__ = ["READ_SUFFIXES", "TAKE_FILE_FILTER", "TAKE_FORMATS", "FrameRateMissingError", "Take", "TakeFormat",
           "TakeFormatError", "is_marker_label", "load_take", "looks_unlabelled", "recognised_format", "save_take",
           "take_format"]
