"""The batch pipeline file: defaults, checks with one-line errors, TOML and JSON round trips, its key."""

from __future__ import annotations

import json

import pytest

from handmocap.core.batch.pipeline import (
    STEPS,
    Pipeline,
    load_pipeline,
    pipeline_from_dict,
    pipeline_toml,
    save_pipeline,
)
from handmocap.core.batch.report import study_report_html
from handmocap.core.errors import InputError


def test_defaults_and_relative_paths(tmp_path):
    (tmp_path / "objects.json").write_text("[]")
    path = tmp_path / "p.toml"
    path.write_text('steps = ["fill", "label"]\nobjects = "objects.json"\noutput = "out"\nmax_gap = 12\n')
    pipeline = load_pipeline(path)
    assert pipeline.steps == ("label", "fill")  # always run in pipeline order
    assert pipeline.objects == str(tmp_path / "objects.json")
    assert pipeline.output == str(tmp_path / "out")
    assert pipeline.max_gap == 12 and pipeline.hands == "auto" and pipeline.layout == "dense"


@pytest.mark.parametrize(("text", "message"), [
    ("colour = 1", "unknown setting 'colour'"),
    ("max_gap = 0", "'max_gap' must be at least 1"),
    ("max_gap = true", "'max_gap' must be a whole number"),
    ('hands = "three"', "'hands' has 'three'"),
    ('steps = ["label", "dance"]', "'steps' has 'dance'"),
    ('fill_method = "magic"', "'fill_method' has 'magic'"),
    ('exports = []', "needs at least one"),
    ('objects = "missing.json"', "does not exist"),
    ("layout = ", "not a valid TOML"),
])
def test_bad_settings_are_one_line_errors(tmp_path, text, message):
    path = tmp_path / "p.toml"
    path.write_text(text + "\n")
    with pytest.raises(InputError, match=message) as caught:
        load_pipeline(path)
    assert "\n" not in str(caught.value) and str(path) in str(caught.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="cannot read the pipeline"):
        load_pipeline(tmp_path / "none.toml")


def test_toml_and_json_round_trip(tmp_path):
    pipeline = Pipeline(steps=STEPS, layout="glove-13", hands="right", max_gap=33, exports=("c3d", "bvh"),
                        output=str(tmp_path / 'o "quoted" é\x7f'))
    for name in ("p.toml", "p.json"):
        save_pipeline(pipeline, tmp_path / name)
        assert load_pipeline(tmp_path / name) == pipeline
    assert json.loads((tmp_path / "p.json").read_text())["max_gap"] == 33
    assert pipeline_toml(pipeline).count("\n") == 13


def test_key_follows_what_decides_the_results(tmp_path):
    base = pipeline_from_dict({"layout": "glove-13"})
    assert base.key() == pipeline_from_dict({"layout": "glove-13", "output": str(tmp_path)}).key()
    assert base.key() != pipeline_from_dict({"layout": "glove-13", "max_gap": 21}).key()
    spec = tmp_path / "objects.json"
    spec.write_text("[]")
    first = pipeline_from_dict({"objects": str(spec)}).key()
    spec.write_text("[ ]")
    assert pipeline_from_dict({"objects": str(spec)}).key() != first


def test_report_lists_failed_and_least_labelled_first():
    rows = [{"take": "t1", "name": "good", "status": "done", "labelled_share": 0.95, "mean_residual_mm": 0.4,
             "longest_gap": 3, "health_count": 0, "seconds": 1.0},
            {"take": "t2", "name": "poor", "status": "done", "labelled_share": 0.40, "mean_residual_mm": 2.0,
             "longest_gap": 80, "health_count": 2, "health": ["swap: a", "gap: b"], "seconds": 1.0},
            {"take": "t3", "name": "broken", "status": "failed", "reason": "not a C3D <file>"}]
    page = study_report_html("study", rows)
    assert page.index("broken") < page.index("poor") < page.index("good")
    assert "not a C3D &lt;file&gt;" in page and "data:image/png;base64," in page
    assert "2 of 3 takes done, 1 failed" in page
