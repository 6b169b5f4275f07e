"""Session lock stress benchmark: two windows on one session, many times over.

* Simultaneous opens: in each trial ``processes`` processes wait at a barrier, open the same take at the
  same moment, wait until all of them have opened it, then each tries ``edits`` edits (unlabelling its own
  cells, so every edit leaves a mark), saving now and then. Half the trials end in a "crash" (the take
  released without saving). Then the take is opened afresh and every acknowledged edit (``push``
  returned) is looked for. Figures: trials where not exactly one process got the take for editing,
  acknowledged edits lost, edits a read-only opening accepted (all must be 0).
* Manifest updates: in each round two processes, each with its own take, record ``updates`` exports at
  the same time; afterwards the manifest must hold all of them. Figure: updates lost (must be 0).

The worker processes are started once (spawn) and run every trial.

Run: python tests/bench/bench_session_lock.py [trials] [processes] [edits]
"""

from __future__ import annotations

import multiprocessing
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from handmocap.core.errors import InputError
from handmocap.core.io import save_take
from handmocap.core.review import Unlabel
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session

NAMES = ["thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"]
WAIT_S = 120.0  # a barrier not reached in this time means a worker hung: the run fails instead of hanging
_SPAWN = multiprocessing.get_context("spawn")


def make_session(folder: Path, takes: int = 1, frames: int = 400) -> Path:
    """A session in ``folder`` with ``takes`` takes of one labelled raw file (every label in every frame)."""
    take, _, _ = synthetic_labelling(frames=frames, shuffle=False, ghosts=0, gap_labels=0)
    take.marker_names = list(NAMES)
    raw = folder.parent / f"{folder.name}.c3d"
    save_take(take, raw)
    session = Session.create(folder)
    for _ in range(takes):
        session.add_take(raw)
    return folder


def _cell(worker: int, edit: int, edits: int) -> tuple[int, int]:
    """The (frame, label) an edit of a worker unlabels; distinct for every worker and edit."""
    return worker * edits + edit, edit % len(NAMES)


def _editor(worker: int, tasks, results, ready, opened_all) -> None:
    """Worker loop: for each (folder, edits, crash) task, open the take with the others, edit, release."""
    while (task := tasks.get()) is not None:
        folder, edits, crash = task
        ready.wait(WAIT_S)
        opened = Session.open(folder).open_take("t0001")
        writer = not opened.read_only
        opened_all.wait(WAIT_S)  # every process has tried before any lets go of the take
        acknowledged, accepted_read_only = [], 0
        for edit in range(edits):
            frame, label = _cell(worker, edit, edits)
            try:
                opened.push(Unlabel(label=NAMES[label], scope="range", start=frame, stop=frame + 1))
            except InputError:
                continue
            acknowledged.append((frame, label))
            accepted_read_only += opened.read_only
            if writer and edit % 7 == 6:
                opened.save()
        opened.close(save=not crash)
        results.put((worker, writer, opened.held_by, acknowledged, accepted_read_only))


def _recorder(worker: int, tasks, results, ready) -> None:
    """Worker loop: for each (folder, updates) task, record exports of take ``t000<worker+1>``."""
    while (task := tasks.get()) is not None:
        folder, updates = task
        session = Session.open(folder)
        ready.wait(WAIT_S)
        for number in range(updates):
            session.record_export(f"t{worker + 1:04d}", f"kind{number}", folder / f"out{worker}-{number}.c3d")
        results.put(worker)


@contextmanager
def _workers(target: Callable, processes: int, *shared: object) -> Iterator[tuple[list, object]]:
    """Start ``processes`` spawned ``target(index, tasks, results, *shared)`` workers; yields (their task
    queues, the results queue). At the end each is sent None and joined (killed after 30 s)."""
    tasks = [_SPAWN.Queue() for _ in range(processes)]
    results = _SPAWN.Queue()
    workers = [_SPAWN.Process(target=target, args=(index, tasks[index], results, *shared))
               for index in range(processes)]
    for worker in workers:
        worker.start()
    try:
        yield tasks, results
    finally:
        for queue in tasks:
            queue.put(None)
        for worker in workers:
            worker.join(timeout=30)
            if worker.is_alive():
                worker.kill()


def lock_trials(trials: int, processes: int, edits: int, folder: Path) -> dict[str, float]:
    """Run the simultaneous-open trials in ``folder``; returns the figures (module docstring)."""
    barriers = (_SPAWN.Barrier(processes), _SPAWN.Barrier(processes))
    figures = {"trials": trials, "processes": processes, "not_one_writer": 0, "acknowledged": 0, "lost": 0,
               "accepted_read_only": 0, "readers_told_holder": 0, "readers": 0}
    started = time.perf_counter()
    with _workers(_editor, processes, *barriers) as (tasks, results):
        for trial in range(trials):
            session_folder = make_session(folder / f"trial{trial}", frames=processes * edits)
            for queue in tasks:
                queue.put((session_folder, edits, trial % 2 == 1))
            answers = [results.get(timeout=WAIT_S) for _ in range(processes)]
            writers = [answer for answer in answers if answer[1]]
            figures["not_one_writer"] += len(writers) != 1
            readers = [answer for answer in answers if not answer[1]]
            figures["readers"] += len(readers)
            figures["readers_told_holder"] += sum(bool(answer[2]) and "process" in answer[2] for answer in readers)
            review = Session.open(session_folder, read_only=True).open_take("t0001").review
            for _, _, _, acknowledged, accepted_read_only in answers:
                figures["acknowledged"] += len(acknowledged)
                figures["accepted_read_only"] += accepted_read_only
                figures["lost"] += sum(int(review.assignment[frame, label]) != -1 for frame, label in acknowledged)
    figures["seconds"] = round(time.perf_counter() - started, 1)
    return figures


def manifest_rounds(rounds: int, updates: int, folder: Path) -> dict[str, float]:
    """Two processes record exports of their own take at once, ``rounds`` times; returns the figures."""
    figures = {"rounds": rounds, "updates": 2 * rounds * updates, "lost": 0, "rounds_losing": 0}
    with _workers(_recorder, 2, _SPAWN.Barrier(2)) as (tasks, results):
        for number in range(rounds):
            session_folder = make_session(folder / f"round{number}", takes=2, frames=30)
            for queue in tasks:
                queue.put((session_folder, updates))
            for _ in range(2):
                results.get(timeout=WAIT_S)
            session = Session.open(session_folder, read_only=True)
            lost = sum(f"kind{n}" not in session.take(f"t{w + 1:04d}").exports
                       for w in range(2) for n in range(updates))
            figures["lost"] += lost
            figures["rounds_losing"] += lost > 0
    return figures


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    processes = int(sys.argv[2]) if len(sys.argv) > 2 else 4
    edits = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    with tempfile.TemporaryDirectory() as folder:
        opens = lock_trials(trials, processes, edits, Path(folder))
        print(f"simultaneous opens: {opens['trials']} trials x {opens['processes']} processes: "
              f"{opens['not_one_writer']} trials without exactly one writer; {opens['acknowledged']} acknowledged "
              f"edits, {opens['lost']} lost; {opens['accepted_read_only']} edits accepted by a read-only opening; "
              f"{opens['readers_told_holder']} of {opens['readers']} read-only openings told who holds the take "
              f"({opens['seconds']} s)")
        manifest = manifest_rounds(20, 10, Path(folder))
        print(f"manifest: {manifest['rounds']} rounds of two processes on different takes, {manifest['updates']} "
              f"updates: {manifest['lost']} lost ({manifest['rounds_losing']} rounds losing one)")


if __name__ == "__main__":
    main()
