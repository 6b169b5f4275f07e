"""A session take another process is editing opens read-only in the window: the title and the status bar
say so (and who holds it), and an edit is refused with a message instead of being lost."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from handmocap.core.io import save_take
from handmocap.core.review import Unlabel
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session

pytestmark = pytest.mark.gui
ROOT = Path(__file__).resolve().parents[2]
HOLD_TAKE = textwrap.dedent("""
    import sys, time
    from handmocap.core.session import Session
    opened = Session.open(sys.argv[1]).open_take("t0001")
    print("held", flush=True)
    time.sleep(120)
""")


def test_a_take_held_elsewhere_is_read_only_and_refuses_edits(window, qtbot, tmp_path):
    take, _, _ = synthetic_labelling(frames=30, shuffle=False, ghosts=0)
    take.marker_names = ["thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"]
    save_take(take, tmp_path / "labelled.c3d")
    folder = tmp_path / "session"
    Session.create(folder).add_take(tmp_path / "labelled.c3d")
    holder = subprocess.Popen([sys.executable, "-c", HOLD_TAKE, str(folder)], cwd=ROOT,
                              env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert window.sessions.open_session(folder)
        window.sessions.open_take("t0001")
        qtbot.waitUntil(lambda: window.document is not None, timeout=30_000)
        document = window.document
        assert document.open_take.read_only
        assert "(read-only)" in window.windowTitle()
        assert f"(process {holder.pid})" in window.statusBar().currentMessage()
        before = document.review.assignment.copy()
        assert window.review.run_edit(lambda: Unlabel(label="thumb_tip", scope="take")) is None
        assert window.messages and "read-only" in window.messages[-1] and "not applied" in window.messages[-1]
        assert (document.review.assignment == before).all()
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
