"""Batches on Dask: the same labels as ``handmocap label``, one undoable review step per take, resume,
a corrupt take failing alone and a worker killed with SIGKILL mid-run losing nothing.

Small takes (200 frames, one hand, glove-13 with ghosts and occlusion) on a two-worker LocalCluster
shared by the tests (its scheduler address is passed like ``--scheduler``); the CLI test starts its own.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from batch_study import make_study

from handmocap.app.cli.main import main
from handmocap.core.batch.pipeline import pipeline_from_dict
from handmocap.core.batch.runner import open_study, plan_batch, run_batch
from handmocap.core.batch.state import read_state
from handmocap.core.batch.task import process_take
from handmocap.core.io import load_take
from handmocap.core.session.session import Session

LABEL_ONLY = {"steps": ["label", "export"], "layout": "glove-13", "hands": "right", "exports": ["c3d"]}
FULL = {"steps": ["label", "calibrate", "fill", "solve", "export"], "layout": "glove-13", "hands": "right",
        "max_gap": 20, "exports": ["c3d", "csv", "angles-csv", "bvh"]}

distributed = pytest.importorskip("distributed")


def run(session, settings, scheduler, **options):
    pipeline = pipeline_from_dict(settings | {"output": str(session.folder.parent / "out")})
    plan = plan_batch(Session.open(session.folder), pipeline)
    return plan, run_batch(plan, scheduler=scheduler, **options)


def test_batch_labels_are_the_cli_labels_and_one_undoable_step(tmp_path, cluster):
    session = make_study(tmp_path, 2)
    _, progress = run(session, LABEL_ONLY, cluster[0])
    assert progress.count("done") == 2 and not progress.interrupted
    for entry in session.takes:
        cli_out = tmp_path / f"cli-{entry.id}.c3d"
        assert main(["label", entry.source, "--layout", "glove-13", "--hands", "right", "--out", str(cli_out),
                     "--quiet"]) == 0
        batch_out = tmp_path / "out" / f"{entry.id}_{entry.name}.c3d"
        cli_take, batch_take = load_take(cli_out), load_take(batch_out)
        assert batch_take.marker_names == cli_take.marker_names
        assert np.array_equal(batch_take.marker_positions, cli_take.marker_positions, equal_nan=True)
        opened = Session.open(session.folder).open_take(entry.id)
        assert opened.stack.index == 1 and opened.stack.undo_text().startswith("batch ")
        assert np.array_equal(opened.review.labelled_take().marker_positions[:, :13],
                              cli_take.marker_positions[:, :13], equal_nan=True)
        opened.undo()
        assert not (opened.review.assignment >= 0).any()  # undone: the take as it was before the batch
        opened.close(save=False)


def test_full_pipeline_resume_and_corrupt_take(tmp_path, cluster):
    session = make_study(tmp_path, 4)
    corrupt = session.takes[1]
    with open(corrupt.source, "r+b") as handle:  # a damaged file (same size): fails alone, with its reason
        handle.seek(512)
        handle.write(b"\xff" * 4096)
    seen = {}

    def stop() -> bool:  # as Ctrl+C once one take has finished
        return "progress" in seen and seen["progress"].count("done") + seen["progress"].count("failed") >= 1

    plan, first = run(session, FULL, cluster[0], stop=stop, on_progress=lambda progress: seen.update(progress=progress))
    assert first.interrupted
    finished = {take for take, state in first.states.items() if state in ("done", "failed")}
    assert finished and len(finished) < 4
    state = read_state(session.folder, [entry.id for entry in session.takes])
    assert all(state[take]["state"] in ("done", "failed") for take in finished)
    plan, second = run(session, FULL, cluster[0])
    resumed = {job.take_id for job in plan.jobs}
    done_before = {take for take in finished if state[take]["state"] == "done"}
    assert not resumed & done_before, "a finished take was run again"
    assert plan.up_to_date == sorted(done_before)
    assert all(second.states[take] in ("done", "failed") for take in resumed)
    final = read_state(session.folder, [entry.id for entry in session.takes])
    assert final[corrupt.id]["state"] == "failed" and final[corrupt.id]["reason"]
    good = [entry for entry in session.takes if entry.id != corrupt.id]
    for entry in good:
        assert final[entry.id]["state"] == "done", final[entry.id]
        summary = final[entry.id]["summary"]
        assert summary["labelled_share"] > 0.8 and summary["mean_residual_mm"] < 2.0 and summary["hands"]
        assert {"c3d", "csv", "angles-csv", "bvh-right"} <= set(summary["outputs"])
        assert summary["compilations"] == 0, "a worker compiled numba kernels instead of loading them"
    assert Session.open(session.folder).take(good[0].id).state == "exported"
    plan, _ = run(session, FULL, cluster[0])
    assert [job.take_id for job in plan.jobs] == [corrupt.id]  # only the failed one is tried again


def test_worker_killed_mid_run_loses_nothing(tmp_path, cluster):
    address, client = cluster
    session = make_study(tmp_path, 6, first_seed=10)
    pids = client.run(os.getpid)
    killed: dict[str, object] = {}

    def kill_once(progress) -> None:
        # both workers running a take (one thread each): whichever is killed dies mid-task. The test's own client
        # is not called while the batch's client runs (two clients of one process once raised "bound to a
        # different event loop" under load)
        if killed or progress.count("done") < 1 or progress.count("running") < 2:
            return
        killed["done"] = {take for take, state in progress.states.items() if state == "done"}
        os.kill(next(iter(pids.values())), signal.SIGKILL)

    _, progress = run(session, FULL, address, on_progress=kill_once)
    assert killed, "no worker was killed"
    assert progress.count("done") == 6, progress.summaries
    state = read_state(session.folder, [entry.id for entry in session.takes])
    for entry in session.takes:
        assert state[entry.id]["state"] == "done"
        opened = Session.open(session.folder, read_only=True).open_take(entry.id)
        assert opened.stack.index == 1, f"take {entry.id} has {opened.stack.index} batch steps"
        opened.close(save=False)


def test_take_open_elsewhere_is_skipped(tmp_path):
    session = make_study(tmp_path, 1)
    entry = session.takes[0]
    holder = Session.open(session.folder).open_take(entry.id)
    settings = pipeline_from_dict(LABEL_ONLY).to_dict()
    summary = process_take(str(session.folder), entry.id, settings, "k" * 64, str(tmp_path / "out"), "x")
    holder.close()
    assert summary["status"] == "skipped" and "is editing it" in summary["reason"]


def test_cli_on_a_folder_of_takes(tmp_path, capsys):
    make_study(tmp_path, 2)
    pipeline = tmp_path / "p.toml"
    pipeline.write_text('steps = ["label", "export"]\nlayout = "glove-13"\nhands = "right"\nexports = ["c3d"]\n')
    assert main(["batch", str(tmp_path / "raw"), "--pipeline", str(pipeline), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "2 takes processed" in out and "batch-report.html" in out
    session = open_study(tmp_path / "raw", pipeline_from_dict(LABEL_ONLY))
    assert len(session.takes) == 2 and (session.folder / "batch-report.html").exists()
    assert main(["batch", str(tmp_path / "raw"), "--pipeline", str(pipeline)]) == 0
    assert "0 takes to process, 2 up to date" in capsys.readouterr().out


def test_a_take_costs_one_manifest_update(tmp_path, monkeypatch):
    """With many workers the manifest updates (each rewrites the whole manifest under the session lock)
    are what waits: a task makes one."""
    session = make_study(tmp_path, 1)
    entry = session.takes[0]
    calls, original = [], Session.update
    monkeypatch.setattr(Session, "update", lambda self, change: calls.append(1) or original(self, change))
    (tmp_path / "out").mkdir()
    settings = pipeline_from_dict(LABEL_ONLY).to_dict()
    summary = process_take(str(session.folder), entry.id, settings, "k" * 64, str(tmp_path / "out"), "x")
    assert summary["status"] == "done" and len(calls) == 1
    saved = Session.open(session.folder).take(entry.id)
    assert saved.state == "exported" and (session.folder / saved.results["review"]).is_file()
    assert saved.exports["c3d"] == str(tmp_path / "out" / "x.c3d")
