"""Batch faults of issue 22: what counts as done includes the exports (path and sha256), so --redo into
another output folder, a new output folder or a deleted export redo what is missing; a failing take (a 0-byte
file, a link to /proc/self/mem) fails alone with its reason while the others finish; a '../../' take id and
a bad scheduler address are refused before anything is created.
"""

from __future__ import annotations

import json
import os

import pytest
from batch_study import make_study

from handmocap.app.cli.main import main
from handmocap.core.batch.pipeline import pipeline_from_dict
from handmocap.core.batch.runner import plan_batch, run_batch
from handmocap.core.batch.scheduler import check_scheduler_address
from handmocap.core.batch.state import read_state
from handmocap.core.errors import InputError
from handmocap.core.session.session import Session

LABEL_ONLY = {"steps": ["label", "export"], "layout": "glove-13", "hands": "right", "exports": ["c3d"]}

distributed = pytest.importorskip("distributed")


def run(session, output, scheduler, redo=False):
    pipeline = pipeline_from_dict(LABEL_ONLY | {"output": str(output)})
    plan = plan_batch(Session.open(session.folder), pipeline, redo=redo)
    return plan, run_batch(plan, scheduler=scheduler)


def test_outputs_are_part_of_done_redo_new_folder_and_deleted_export(tmp_path, cluster):
    session = make_study(tmp_path, 2)
    first_out, second_out = tmp_path / "out", tmp_path / "elsewhere"
    plan, progress = run(session, first_out, cluster[0])
    assert progress.count("done") == 2
    state = read_state(session.folder, [entry.id for entry in session.takes])
    for entry in session.takes:
        summary = state[entry.id]["summary"]
        assert set(summary["output_sha256"]) == set(summary["outputs"]) == {"c3d"}
    written = {job.take_id: first_out / f"{job.stem}.c3d" for job in plan.jobs}
    assert all(path.is_file() for path in written.values())

    plan, _ = run(session, first_out, cluster[0])       # nothing missing: nothing to do
    assert not plan.jobs and len(plan.up_to_date) == 2

    plan, progress = run(session, second_out, cluster[0], redo=True)   # --redo into another folder
    assert len(plan.jobs) == 2 and progress.count("done") == 2
    assert sorted(path.name for path in second_out.iterdir()) == sorted(path.name for path in written.values())
    for entry in session.takes:   # still one batch step, done afresh
        opened = Session.open(session.folder, read_only=True).open_take(entry.id)
        assert opened.stack.index == 1 and opened.stack.undo_text().startswith("batch ")
        opened.close(save=False)

    plan, _ = run(session, second_out, cluster[0])       # the new folder is what counts as done now
    assert not plan.jobs
    victim = session.takes[0].id
    exported = second_out / written[victim].name
    exported.unlink()                                     # a deleted export is written again
    plan, progress = run(session, second_out, cluster[0])
    assert [job.take_id for job in plan.jobs] == [victim] and progress.count("done") == 1
    assert exported.is_file()
    exported.write_bytes(exported.read_bytes()[:-10])     # a changed export too
    plan, _ = run(session, second_out, cluster[0])
    assert [job.take_id for job in plan.jobs] == [victim]
    plan, _ = run(session, first_out, cluster[0])         # the first folder's files are no longer recorded
    assert len(plan.jobs) == 2


def test_a_failing_take_fails_alone_with_its_reason(tmp_path, cluster, capsys):
    make_study(tmp_path, 2)
    raw = tmp_path / "raw"
    (raw / "empty.c3d").write_bytes(b"")
    (raw / "memory.c3d").symlink_to("/proc/self/mem")
    pipeline = tmp_path / "p.toml"
    pipeline.write_text('steps = ["label", "export"]\nlayout = "glove-13"\nhands = "right"\nexports = ["c3d"]\n')
    code = main(["batch", str(raw), "--pipeline", str(pipeline), "--scheduler", cluster[0], "--json"])
    out = capsys.readouterr().out
    assert code == 1, out
    report = json.loads(out.strip().splitlines()[-1])
    assert report["done"] == 2 and report["failed"] == 2
    reasons = {row["name"]: row.get("reason", "") for row in report["takes"] if row["status"] == "failed"}
    assert set(reasons) == {"empty.c3d", "memory.c3d"} and all(reasons.values())
    assert all("\n" not in reason for reason in reasons.values())
    html = (raw / "handmocap-session" / "batch-report.html").read_text()
    assert "empty.c3d" in html and "memory.c3d" in html


def _study_with_a_damaged_take_id(folder, count):
    """A study of ``count`` takes whose last take's id in the manifest is '../../evil'."""
    session = make_study(folder, count)
    manifest = session.folder / "session.json"
    data = json.loads(manifest.read_text())
    data["takes"][-1]["id"] = "../../evil"
    manifest.write_text(json.dumps(data))
    return session


def test_a_damaged_take_id_fails_alone_and_nothing_is_written_for_it(tmp_path, cluster):
    session = _study_with_a_damaged_take_id(tmp_path, 2)
    before = set(os.listdir(tmp_path))
    plan, progress = run(session, tmp_path / "out", cluster[0])
    assert list(plan.failed) == ["../../evil"] and "not a valid take id" in plan.failed["../../evil"]
    assert progress.count("done") == 1 and progress.count("failed") == 1
    assert set(os.listdir(tmp_path)) == before | {"out"}
    assert not (tmp_path.parent / "evil").exists()
    assert all(".." not in path.name and "evil" not in path.name for path in (tmp_path / "out").iterdir())


def test_only_damaged_take_ids_create_nothing(tmp_path, cluster):
    session = _study_with_a_damaged_take_id(tmp_path, 1)
    before = sorted(path.relative_to(tmp_path) for path in tmp_path.rglob("*"))
    plan, progress = run(session, tmp_path / "out", cluster[0])
    assert progress.count("failed") == 1 and not plan.jobs
    assert sorted(path.relative_to(tmp_path) for path in tmp_path.rglob("*")) == before


@pytest.mark.parametrize(("address", "message"), [
    ("tls://127.0.0.1:8786", "TLS certificates"),
    ("ucx://127.0.0.1:8786", "distributed-ucxx"),
    ("inproc://x", "inside this same process"),
    ("tcp://host", "HOST:PORT"),
    ("tcp://host:0", "1..65535"),
    ("gopher://host:70", "unknown scheme"),
    ("tcp://a b:1", "not a host name"),
])
def test_bad_scheduler_addresses_are_one_line_before_anything_starts(tmp_path, capsys, address, message):
    with pytest.raises(InputError, match=message) as caught:
        check_scheduler_address(address)
    assert "\n" not in str(caught.value)
    make_study(tmp_path, 1)
    pipeline = tmp_path / "p.toml"
    pipeline.write_text('steps = ["label", "export"]\nlayout = "glove-13"\nhands = "right"\nexports = ["c3d"]\n')
    before = sorted(path.relative_to(tmp_path) for path in tmp_path.rglob("*"))
    assert main(["batch", str(tmp_path / "raw"), "--pipeline", str(pipeline), "--scheduler", address]) == 2
    assert message in capsys.readouterr().err
    assert sorted(path.relative_to(tmp_path) for path in tmp_path.rglob("*")) == before


def test_valid_scheduler_addresses_keep_their_form():
    assert check_scheduler_address("127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    assert check_scheduler_address("tcp://[::1]:8786") == "tcp://[::1]:8786"
    assert check_scheduler_address("ws://scheduler.lab:8786") == "ws://scheduler.lab:8786"
    assert check_scheduler_address(f"inproc://10.0.0.1/{os.getpid()}/1").startswith("inproc://")


def test_a_bad_layout_is_refused_before_the_session_is_made(tmp_path, capsys):
    make_study(tmp_path, 1)
    (tmp_path / "deep.json").write_text("[" * 100_000)
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(f'steps = ["label", "export"]\nlayout = "{tmp_path / "deep.json"}"\nexports = ["c3d"]\n')
    assert main(["batch", str(tmp_path / "raw"), "--pipeline", str(pipeline)]) == 2
    assert "nested" in capsys.readouterr().err
    assert not (tmp_path / "raw" / "handmocap-session").exists()
