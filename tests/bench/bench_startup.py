"""Start-up time as an operator sees it: from launching the program to the first drawn main window, to the
demo session showing its first take, and to every demo take opened, labelled and solved.

Each figure is measured in a fresh process (interpreter start and imports included), on a new demo
session folder ("first start") and then on the same folder again ("next start"). "window" is the main window
drawn; its 3D view is built 0.1 s after that (``widgets/deferred_viewport.py``), before "demo".

Run (needs a display or runs offscreen): python tests/bench/bench_startup.py [runs]

With ``--command PATH`` the program started is an installed ``handmocap`` executable (the frozen bundle's
``dist/handmocap/handmocap`` or a venv's ``.venv/bin/handmocap``) run as ``PATH gui --screenshot``: "window"
is when its main window is first mapped on the X display (polled with xwininfo; needs an X display, e.g.
under xvfb-run) and "ready" when it has opened and solved the demo session, saved the screenshot and exited.
Each first start also gets a new user cache folder (XDG_CACHE_HOME), as on an operator's new account.
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHILD = """
import sys
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from handmocap.app.gui.main_window import MainWindow
from handmocap.app.gui.palette import apply_dark_palette

app = QApplication(sys.argv[:1])
app.setStyle("Fusion")
apply_dark_palette(app)
window = MainWindow()
window.show()
app.processEvents()
window.repaint()
print("window", flush=True)
window.open_demo()
stage = {"shown": False}

def poll():
    if not stage["shown"] and window.document is not None:
        stage["shown"] = True
        app.processEvents()
        print("demo", flush=True)
    if stage["shown"] and not window.is_busy():
        print("ready", flush=True)
        timer.stop()
        window.close()
        app.quit()

timer = QTimer()
timer.timeout.connect(poll)
timer.start(20)
app.exec()
"""


def one_start(demo_folder: Path) -> dict[str, float]:
    """Seconds from spawning the process to each stage line it prints."""
    environment = dict(os.environ, HANDMOCAP_DEMO_SESSION=str(demo_folder))
    environment.setdefault("QT_QPA_PLATFORM", "offscreen" if not os.environ.get("DISPLAY") else "xcb")
    start = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-c", CHILD], cwd=ROOT, env=environment, stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True)
    stages: dict[str, float] = {}
    assert child.stdout is not None
    for line in child.stdout:
        stages[line.strip()] = round(time.perf_counter() - start, 2)
    child.wait(timeout=600)
    return stages


def _main_window_mapped() -> bool:
    """Whether a top-level window titled Hand Mocap Studio is viewable on ``$DISPLAY``."""
    tree = subprocess.run(["xwininfo", "-root", "-tree"], capture_output=True, text=True).stdout
    for window in re.findall(r"^\s*(0x[0-9a-f]+) \"[^\"]*Hand Mocap Studio\"", tree, flags=re.MULTILINE):
        state = subprocess.run(["xwininfo", "-id", window], capture_output=True, text=True).stdout
        if "IsViewable" in state:
            return True
    return False


def one_command_start(command: str, folder: Path, screenshot: str) -> dict[str, float]:
    """Seconds from spawning ``command gui --screenshot`` to its mapped main window and to its exit."""
    environment = dict(os.environ, HANDMOCAP_DEMO_SESSION=str(folder / "demo-session"),
                       HANDMOCAP_DATA=str(folder / "data"), XDG_CACHE_HOME=str(folder / "cache"))
    errors = folder / f"{screenshot}.stderr"
    start = time.perf_counter()
    with errors.open("w") as stderr:
        child = subprocess.Popen([command, "gui", "--screenshot", str(folder / screenshot)], env=environment,
                                 stdout=subprocess.DEVNULL, stderr=stderr)
    stages: dict[str, float] = {}
    while child.poll() is None:
        if "window" not in stages and _main_window_mapped():
            stages["window"] = round(time.perf_counter() - start, 2)
        time.sleep(0.02)
    if child.returncode == 0 and (folder / screenshot).exists():
        stages["ready"] = round(time.perf_counter() - start, 2)
    else:
        print(f"start failed (exit code {child.returncode}): {errors.read_text()[-2000:]}", file=sys.stderr)
    return stages


def main(runs: int = 2, command: str | None = None) -> None:
    if command is not None and not (os.environ.get("DISPLAY") and shutil.which("xwininfo")):
        sys.exit("--command needs an X display and xwininfo (run under xvfb-run -a)")
    figures: dict[str, list[dict[str, float]]] = {"first_start": [], "next_start": []}
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as folder:
            if command is None:
                demo = Path(folder) / "demo-session"
                figures["first_start"].append(one_start(demo))
                figures["next_start"].append(one_start(demo))
            else:
                figures["first_start"].append(one_command_start(command, Path(folder), "first.png"))
                figures["next_start"].append(one_command_start(command, Path(folder), "next.png"))
    for name, starts in figures.items():
        for stage in ("window", "demo", "ready"):
            values = [start[stage] for start in starts if stage in start]
            if values:
                print(f"{name:11s} {stage:7s} {min(values):6.2f} s (best of {len(values)}), "
                      f"{max(values):6.2f} s worst")
    print(json.dumps(figures))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="?", type=int, default=2)
    parser.add_argument("--command", metavar="PATH", help="time this handmocap executable instead")
    arguments = parser.parse_args()
    main(arguments.runs, arguments.command)
