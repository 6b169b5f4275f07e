"""A session keeps the frame rate the user gave for a take whose file states none, and reads it again at it."""

import json
import shutil
from pathlib import Path

import pytest

from handmocap.core.io import FrameRateMissingError
from handmocap.core.session import Session

NOKOV = Path(__file__).resolve().parents[1] / "io" / "fixtures" / "nokov.csv"


def test_the_given_rate_is_kept_in_the_manifest_and_used_when_reopening(tmp_path):
    source = tmp_path / "arpeggio.csv"
    shutil.copy(NOKOV, source)
    session = Session.create(tmp_path / "session")
    with pytest.raises(FrameRateMissingError):
        session.add_take(source)
    entry = session.add_take(source, frame_rate=120.0)
    assert entry.frame_rate == 120.0 and entry.frame_rate_given and entry.given_frame_rate == 120.0
    manifest = json.loads((tmp_path / "session" / "session.json").read_text())
    assert manifest["takes"][0]["frame_rate"] == 120.0 and manifest["takes"][0]["frame_rate_given"] is True
    session.close()

    reopened = Session.open(tmp_path / "session")
    opened = reopened.open_take(entry.id)                  # no rate asked: the manifest has it
    assert opened.review.take.frame_rate == 120.0 and opened.review.take.n_frames == 4
    opened.close()
    moved = tmp_path / "moved.csv"
    source.rename(moved)
    assert reopened.relink_take(entry.id, moved).source == str(moved)
    reopened.close()


def test_a_file_with_its_own_rate_records_none_given_and_old_manifests_still_open(tmp_path):
    vicon = Path(__file__).resolve().parents[1] / "io" / "fixtures" / "vicon_nexus.csv"
    session = Session.create(tmp_path / "session")
    entry = session.add_take(vicon)
    assert entry.frame_rate == 100.0 and not entry.frame_rate_given and entry.given_frame_rate is None
    session.close()
    manifest_path = tmp_path / "session" / "session.json"
    manifest = json.loads(manifest_path.read_text())
    del manifest["takes"][0]["frame_rate_given"]            # a manifest written before the field existed
    manifest_path.write_text(json.dumps(manifest))
    reopened = Session.open(tmp_path / "session")
    assert reopened.takes[0].frame_rate_given is False
    reopened.close()
