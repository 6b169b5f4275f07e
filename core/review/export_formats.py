"""The export formats: one registry that ``handmocap export``, the GUI's Export dialog and batch read.

A format is an :class:`ExportFormat` made known with :func:`register_export_format` (the built-in ones at the
end of :mod:`core.review.export`); :func:`core.review.export.export_review` checks the options against it and
calls its writer. "csv" is the labelled marker positions everywhere; the joint angles are "angles-csv".
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from handmocap.core.io.labelled_c3d import SubjectCalibration
from handmocap.core.model import HandModel
from handmocap.core.registry import Registry
from handmocap.core.review.take import ReviewTake


@dataclass(frozen=True)
class ExportOptions:
    """What a writer is given besides the review and the file: ``units`` ("mm", "cm", "m") and ``up`` ("z", "y")
    of the file, ``hand`` (a side, or None: every hand), ``fills`` (accepted fills written, marker formats),
    ``models`` (hand model per side, joint-angle formats) and ``subjects`` (calibrations for a labelled C3D)."""

    units: str
    up: str
    hand: str | None
    fills: bool
    models: Mapping[str, HandModel]
    subjects: list[SubjectCalibration] | None


#: a writer: ``(review, file, options)`` -> the files written (several for a per-hand format with two hands)
ExportWriter = Callable[[ReviewTake, Path, ExportOptions], list[Path]]


@dataclass(frozen=True)
class ExportFormat:
    """One export format.

    ``name``: on the command line and in pipeline files; ``label``: in menus; ``suffixes``: the file endings it
    accepts (the first is proposed); ``name_tag``: what the GUI adds to the take's name (``walk_labelled.c3d``);
    ``batch_ending``: the end of the file a batch writes (``<take><batch_ending>``, per hand
    ``<take>.<side><batch_ending>``; unique among the formats); ``axes``: it takes units and an up axis, else
    it is always in ``units`` and ``up``; ``joint_angles``: it writes the solved hands' joint angles (it needs a
    solved hand and hand models, ``hand`` applies, ``fills`` does not), else the labelled marker positions;
    ``per_hand``: a take with several hands gives one file per hand; ``writer``: the :data:`ExportWriter`."""

    name: str
    label: str
    suffixes: tuple[str, ...]
    name_tag: str
    batch_ending: str
    writer: ExportWriter
    axes: bool = False
    units: str = "mm"
    up: str = "z"
    joint_angles: bool = False
    per_hand: bool = False

    @property
    def file_filter(self) -> str:
        """A file dialog's filter: ``"CSV markers (*.csv)"``."""
        return f"{self.label} ({' '.join('*' + suffix for suffix in self.suffixes)})"


_FORMATS: Registry[ExportFormat] = Registry("export format", lambda export_format: export_format.name,
                                           lambda export_format: {"batch ending": export_format.batch_ending})


def register_export_format(export_format: ExportFormat) -> ExportFormat:
    """Make ``export_format`` known to every list of export formats; ValueError when its name or batch ending
    is taken."""
    return _FORMATS.add(export_format)


def unregister_export_format(name: str) -> None:
    """Forget the export format ``name`` (tests, plug-ins)."""
    _FORMATS.remove(name)


def export_format(name: str) -> ExportFormat:
    """The registered format ``name``; InputError naming the known ones otherwise."""
    return _FORMATS.get(name)


def export_formats() -> tuple[ExportFormat, ...]:
    """Every registered format, in registration order (the order of menus and choices)."""
    return _FORMATS.entries()


def export_format_names() -> tuple[str, ...]:
    """The names of :func:`export_formats`."""
    return _FORMATS.names()
