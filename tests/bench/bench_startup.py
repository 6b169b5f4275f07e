"""Start-up time as an operator sees it: from launching the program to the first drawn main window, to the
demo session showing its first take, and to every demo take opened, labelled and solved.

Each figure is measured in a fresh process (interpreter start and imports included), on a new demo
session folder ("first start") and then on the same folder again ("next start").

Run (needs a display or runs offscreen): python tests/bench/bench_startup.py [runs]
"""

import json
import os
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
from app.gui.main_window import MainWindow
from app.gui.palette import apply_dark_palette

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


def main(runs: int = 2) -> None:
    figures: dict[str, list[dict[str, float]]] = {"first_start": [], "next_start": []}
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as folder:
            demo = Path(folder) / "demo-session"
            figures["first_start"].append(one_start(demo))
            figures["next_start"].append(one_start(demo))
    for name, starts in figures.items():
        for stage in ("window", "demo", "ready"):
            values = [start[stage] for start in starts if stage in start]
            if values:
                print(f"{name:11s} {stage:7s} {min(values):6.2f} s (best of {len(values)}), "
                      f"{max(values):6.2f} s worst")
    print(json.dumps(figures))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
