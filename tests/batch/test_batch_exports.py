"""The batch's exports are the registered export formats (issue 26 item 3), written as ``handmocap export``
writes them: "csv" is the labelled markers, "angles-csv" the joint angles, one BVH per hand."""

from __future__ import annotations

import numpy as np
import pytest
from simulated_files import solved_review

from handmocap.core.batch.pipeline import pipeline_from_dict
from handmocap.core.batch.steps import StepsResult, export_take, output_paths
from handmocap.core.batch.task import exports_complete
from handmocap.core.errors import InputError
from handmocap.core.io import load_take
from handmocap.core.review import ReviewTake
from handmocap.core.review.export_formats import (
    ExportFormat,
    export_format_names,
    register_export_format,
    unregister_export_format,
)

FRAMES = 30


@pytest.fixture
def review() -> ReviewTake:
    return solved_review(FRAMES, seed=3)[0]


def test_a_pipeline_takes_every_registered_format_and_only_those():
    pipeline = pipeline_from_dict({"exports": list(export_format_names())})
    assert pipeline.exports == export_format_names()
    with pytest.raises(InputError, match="'exports' has 'names'; use c3d, trc, csv, angles-csv, bvh, gltf"):
        pipeline_from_dict({"exports": ["names"]})
    register_export_format(ExportFormat(name="names", label="Label names", suffixes=(".txt",), name_tag="_names",
                                        batch_ending=".names.txt", writer=lambda review, path, options: [path]))
    try:
        assert pipeline_from_dict({"exports": ["names"]}).exports == ("names",)
    finally:
        unregister_export_format("names")


def test_csv_is_markers_and_angles_csv_joint_angles(tmp_path, review):
    pipeline = pipeline_from_dict({"exports": ["csv", "angles-csv", "bvh"]})
    paths = output_paths(pipeline, tmp_path, "t1_walk")
    assert paths["csv"] == tmp_path / "t1_walk.csv" and paths["angles-csv"] == tmp_path / "t1_walk.angles.csv"
    assert paths["bvh-right"] == tmp_path / "t1_walk.right.bvh"
    written = export_take(review, pipeline, StepsResult(), paths)
    side = review.hands[0].side
    assert set(written) == {"csv", "angles-csv", f"bvh-{side}"} and exports_complete(pipeline, written)
    markers = load_take(written["csv"])
    assert markers.marker_names == review.label_names
    np.testing.assert_allclose(markers.marker_positions, review.labelled_positions(), atol=1e-3, equal_nan=True)
    header = written["angles-csv"].read_text().splitlines()[0].split(",")
    assert header[:3] == ["frame", "time_s", "wrist_tx_mm"] and "wrist_rx_deg" in header
    assert not exports_complete(pipeline, {"csv": written["csv"], "angles-csv": written["angles-csv"]})
