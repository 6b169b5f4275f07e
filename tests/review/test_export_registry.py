"""One registry of export formats (issue 26 item 3): ``export_review`` writes every registered format through
its writer; "csv" is the labelled markers, "angles-csv" the joint angles; a registered format is exported and
gone again once unregistered."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from simulated_files import solved_review

from handmocap.core.errors import InputError
from handmocap.core.io import load_take
from handmocap.core.review import ReviewTake
from handmocap.core.review.export import export_review
from handmocap.core.review.export_formats import (
    ExportFormat,
    ExportOptions,
    export_format,
    export_format_names,
    register_export_format,
    unregister_export_format,
)

FRAMES = 30


@pytest.fixture
def review() -> ReviewTake:
    return solved_review(FRAMES, seed=3)[0]


def _write_names(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    """The label names, one a line (units in the first line)."""
    path.write_text("\n".join([options.units, *review.label_names]))
    return [path]


@pytest.fixture
def names_format():
    """A label-name list registered for one test."""
    registered = register_export_format(ExportFormat(
        name="names", label="Label names", suffixes=(".txt",), name_tag="_names", batch_ending=".names.txt",
        writer=_write_names))
    yield registered
    unregister_export_format("names")


def test_the_built_in_formats():
    assert export_format_names() == ("c3d", "trc", "csv", "angles-csv", "bvh", "gltf")
    assert not export_format("csv").joint_angles and export_format("angles-csv").joint_angles
    assert export_format("bvh").per_hand and export_format("bvh").axes and not export_format("gltf").per_hand
    with pytest.raises(InputError, match="unknown export format 'fbx'.*c3d, trc, csv, angles-csv"):
        export_format("fbx")


def test_csv_is_the_labelled_markers(tmp_path, review):
    path = tmp_path / "take.csv"
    assert export_review(review, path, "csv") == [path]
    read = load_take(path)
    assert read.marker_names == review.label_names and read.n_frames == FRAMES
    np.testing.assert_allclose(read.marker_positions, review.labelled_positions(), atol=1e-3, equal_nan=True)


def test_angles_csv_is_the_joint_angles(tmp_path, review):
    path = tmp_path / "take.csv"
    assert export_review(review, path, "angles-csv", hand=review.hands[0].side) == [path]
    header = path.read_text().splitlines()[0].split(",")
    assert header[:3] == ["frame", "time_s", "wrist_tx_mm"] and "wrist_rx_deg" in header and len(header) == 28
    with pytest.raises(InputError, match="--no-fills applies to the marker formats \\(c3d, trc, csv\\)"):
        export_review(review, path, "angles-csv", fills=False)


def test_a_registered_format_is_written_by_its_writer(tmp_path, review, names_format):
    assert export_format_names()[-1] == "names"
    path = tmp_path / "take.txt"
    assert export_review(review, path, "names") == [path]
    assert path.read_text().splitlines() == ["mm", *review.label_names]
    with pytest.raises(InputError, match="always in mm and Z up; --units and --up apply to trc, bvh"):
        export_review(review, path, "names", units="m")
    with pytest.raises(ValueError, match="batch ending '.names.txt' is taken"):
        register_export_format(ExportFormat(name="other", label="", suffixes=(".txt",), name_tag="",
                                            batch_ending=".names.txt", writer=_write_names))
    unregister_export_format("names")
    try:
        with pytest.raises(InputError, match="unknown export format 'names'"):
            export_review(review, path, "names")
    finally:
        register_export_format(names_format)
