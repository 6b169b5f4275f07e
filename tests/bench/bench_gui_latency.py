"""GUI responsiveness while a worker solves: how late the GUI thread serves a 10 ms timer and how long
one repaint of the main window takes, with the interpreter's default switch interval (5 ms) and with
the interval the task runner sets (``app.gui.workers.GUI_SWITCH_INTERVAL_S``).

Run (needs a display or QT_QPA_PLATFORM=offscreen): python tests/bench/bench_gui_latency.py [frames]
"""

import json
import os
import sys
import time

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen" if not os.environ.get("DISPLAY") else "xcb")

import numpy as np
from PySide6.QtCore import QElapsedTimer, QTimer
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.main_window import MainWindow
from handmocap.app.gui.workers import GUI_SWITCH_INTERVAL_S
from handmocap.core.simulate import simulate_take

TICK_MS = 10
MEASURE_S = 2.0


def measure(app: QApplication, window: MainWindow, take, interval_s: float, solve: bool = True) -> dict:
    """Start a solve of ``take`` (unless not ``solve``: the idle baseline) with ``interval_s`` and
    measure timer lateness and repaint time (ms)."""
    document = TakeDocument(take, f"switch {interval_s * 1000:g} ms")
    window.add_document(document)
    for _ in range(20):
        app.processEvents()
    sys.setswitchinterval(interval_s)
    if solve:
        window.solver.solve(document)
    clock, lateness, repaints = QElapsedTimer(), [], []
    clock.start()
    last = [clock.elapsed()]

    def tick() -> None:
        now = clock.elapsed()
        lateness.append(now - last[0] - TICK_MS)
        last[0] = now
        start = time.perf_counter()
        window.repaint()
        repaints.append(1000.0 * (time.perf_counter() - start))

    timer = QTimer()
    timer.timeout.connect(tick)
    timer.start(TICK_MS)
    while clock.elapsed() < 1000 * MEASURE_S and (window.solver.runner.is_busy() or not solve):
        app.processEvents()
    timer.stop()
    window.solver.runner.stop()
    return {"switch_interval_ms": interval_s * 1000, "solving": solve, "ticks": len(lateness),
            "timer_late_mean_ms": round(float(np.mean(lateness)), 1),
            "timer_late_max_ms": round(float(np.max(lateness)), 1),
            "repaint_mean_ms": round(float(np.mean(repaints)), 1),
            "repaint_max_ms": round(float(np.max(repaints)), 1)}


def main() -> None:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 20_000
    app = QApplication.instance() or QApplication(sys.argv[:1])
    window = MainWindow()
    window.resize(1600, 1000)
    window.show()
    take = simulate_take(layout="dense", n_frames=frames, seed=5).take
    rows = [measure(app, window, take, 0.005, solve=False)]
    rows += [measure(app, window, take, interval) for interval in (0.005, GUI_SWITCH_INTERVAL_S)]
    for row in rows:
        state = "solving" if row["solving"] else "idle"
        print(f"{state}, switch interval {row['switch_interval_ms']:g} ms: timer late {row['timer_late_mean_ms']} ms "
              f"mean / {row['timer_late_max_ms']} ms max; repaint {row['repaint_mean_ms']} ms mean / "
              f"{row['repaint_max_ms']} ms max ({row['ticks']} ticks)")
    window.close()
    window.deleteLater()
    app.processEvents()
    print(json.dumps({"frames": frames, "runs": rows}))


if __name__ == "__main__":
    main()
