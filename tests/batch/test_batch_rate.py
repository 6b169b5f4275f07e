"""The pipeline's ``rate``: the frame rate of the takes of a folder whose file states none (NOKOV CSV)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from handmocap.core.batch.pipeline import Pipeline, load_pipeline, pipeline_from_dict, save_pipeline
from handmocap.core.batch.runner import open_study
from handmocap.core.errors import InputError

NOKOV = Path(__file__).resolve().parents[1] / "io" / "fixtures" / "nokov.csv"


def test_rate_setting_reads_round_trips_and_leaves_the_key(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("rate = 120\n")
    pipeline = load_pipeline(path)
    assert pipeline.rate == 120.0 and isinstance(pipeline.rate, float)
    for name in ("p2.toml", "p2.json"):
        save_pipeline(pipeline, tmp_path / name)
        assert load_pipeline(tmp_path / name) == pipeline
    assert pipeline_from_dict({"rate": 120}).key() == pipeline_from_dict({}).key()
    assert Pipeline().rate == 0.0


@pytest.mark.parametrize("text", ["rate = -1", "rate = nan", 'rate = "fast"'])
def test_a_bad_rate_is_a_one_line_error(tmp_path, text):
    path = tmp_path / "p.toml"
    path.write_text(text + "\n")
    with pytest.raises(InputError, match="'rate' must be") as caught:
        load_pipeline(path)
    assert "\n" not in str(caught.value)


def test_a_folder_of_nokov_takes_needs_the_rate_and_keeps_it(tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    shutil.copy(NOKOV, folder / "arpeggio.csv")
    (folder / "notes.txt").write_text("subject 3, guitar, 120 Hz\n")     # not a take: left alone
    with pytest.raises(InputError, match="arpeggio.csv: the file has no frame rate; give it with rate = HZ"):
        open_study(folder, Pipeline(layout="glove-13"))
    session = open_study(folder, Pipeline(layout="glove-13", rate=120.0))
    assert [entry.name for entry in session.takes] == ["arpeggio"]
    entry = session.takes[0]
    assert entry.frame_rate == 120.0 and entry.frame_rate_given
    opened = session.open_take(entry.id)
    assert opened.review.take.frame_rate == 120.0
    opened.close()
    session.close()
