"""Scrubbing and playback of the 3D view with a review open: the real 3000-frame recording is opened in
the main window, auto-labelled (glove-13) and its hand solved, a label is selected (trail, label text),
then

* scrub: ~100 random frame steps through the timeline, each timed from the step until the new frame is
  on screen (rendered by VTK and composed by Qt: the view's ``frameSwapped``); median and 95th percentile;
* playback: 1× for a few seconds; drawn frames/s = frames composed on screen per second, and the data
  rate the playback kept (100 Hz data: 100 frames/s means real time, frames between draws are dropped).

The process's CPU time per step is printed too: on a machine shared with other work the wall clock
waits for the CPU (the load average is printed with the figures).

Run under a virtual screen with software OpenGL (targets: ≤ 40 ms per step, ≥ 25 drawn frames/s):
    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python tests/bench/bench_scrub.py [steps] [play_s]
"""

import json
import os
import statistics
import sys
import time

import numpy as np
from PySide6.QtCore import QEventLoop, QTimer
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.main_window import MainWindow
from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.core.evaluation.data import REAL_RECORDING

REAL = REAL_RECORDING
WAIT_S = 300.0


class ScreenCounter:
    """Counts VTK renders of the view and the frames Qt composed on screen after one (``frameSwapped``)."""

    def __init__(self, window: MainWindow) -> None:
        self.window = window
        self.renders = 0
        self.shown = 0
        self.shown_frames: list[int] = []
        self._rendered_since_swap = False
        plotter = window.viewport.plotter
        plotter.GetRenderWindow().AddObserver("EndEvent", self._rendered)
        plotter.frameSwapped.connect(self._swapped)

    def _rendered(self, *_args) -> None:
        self.renders += 1
        self._rendered_since_swap = True

    def _swapped(self) -> None:
        if self._rendered_since_swap:
            self._rendered_since_swap = False
            self.shown += 1
            self.shown_frames.append(self.window.app.frame)


def wait_until(app: QApplication, condition, timeout_s: float = WAIT_S) -> None:
    end = time.perf_counter() + timeout_s
    while not condition():
        if time.perf_counter() > end:
            raise TimeoutError("the window did not get there in time")
        app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 20)
        time.sleep(0.002)


def run_for(app: QApplication, seconds: float) -> None:
    loop = QEventLoop()
    QTimer.singleShot(int(seconds * 1000), loop.quit)
    loop.exec()


def prepare(app: QApplication, window: MainWindow) -> None:
    """Open, auto-label and solve the real take; select a fingertip label."""
    window.open_files([REAL])
    wait_until(app, lambda: window.document is not None and not window.loader.is_busy())
    window.review.start_auto_label(AutoLabelSettings(layout="glove-13"))
    wait_until(app, lambda: not window.is_busy())
    if not window.document.has_solved_hands():
        window.solver.solve()
        wait_until(app, lambda: not window.is_busy())
    review = window.document.review
    window.review.select_label(review.label_index("index_tip"))
    run_for(app, 1.0)


def scrub(app: QApplication, window: MainWindow, counter: ScreenCounter, steps: int) -> tuple[list[float], list[float]]:
    """Milliseconds from a timeline step to the new frame on screen, per random step: wall clock, and the
    process's CPU time (all threads, software OpenGL's included: what the step costs on an idle machine
    with one core)."""
    rng = np.random.default_rng(13)
    n_frames = window.document.take.n_frames
    frames = rng.integers(0, n_frames, steps + 5)
    times, cpu = [], []
    for number, drawn in enumerate(frames):
        frame = (drawn + 1) % n_frames if drawn == window.app.frame else drawn
        shown = counter.shown
        start, start_cpu = time.perf_counter(), time.process_time()
        window.timeline.set_frame(int(frame))
        wait_until(app, lambda shown=shown: counter.shown > shown, 5.0)
        if number >= 5:                                  # the first steps warm caches up
            times.append(1000.0 * (time.perf_counter() - start))
            cpu.append(1000.0 * (time.process_time() - start_cpu))
    return times, cpu


def play(app: QApplication, window: MainWindow, counter: ScreenCounter, seconds: float) -> dict:
    """Play at 1× for ``seconds``: frames drawn on screen per second and data frames per second."""
    window.timeline.set_speed(1.0)
    window.timeline.set_frame(0)
    run_for(app, 0.5)
    shown, renders, first = counter.shown, counter.renders, window.app.frame
    start, start_cpu = time.perf_counter(), time.process_time()
    window.timeline.play()
    run_for(app, seconds)
    window.timeline.pause()
    elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    drawn = counter.shown_frames[shown:]
    return {"drawn_fps": round((counter.shown - shown) / elapsed, 1),
            "cpu_ms_per_drawn_frame": round(1000.0 * cpu / max(counter.shown - shown, 1), 1),
            "cpu_share": round(cpu / elapsed, 2),
            "renders_per_s": round((counter.renders - renders) / elapsed, 1),
            "distinct_frames_drawn": len(set(drawn)),
            "data_frames_per_s": round((window.app.frame - first) / elapsed, 1),
            "frame_rate_hz": window.document.take.frame_rate}


def main() -> None:
    if not REAL.exists():
        print(f"skipped: {REAL} is not there")
        return
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    play_s = float(sys.argv[2]) if len(sys.argv) > 2 else 6.0
    app = QApplication.instance() or QApplication(sys.argv[:1])
    window = MainWindow()
    window.show()
    prepare(app, window)
    counter = ScreenCounter(window)
    run_for(app, 0.5)
    renders = counter.renders
    times, cpu = scrub(app, window, counter, steps)
    renders_per_step = (counter.renders - renders) / (steps + 5)
    playback = play(app, window, counter, play_s)
    size = window.viewport.plotter.size()
    result = {"steps": len(times), "scrub_median_ms": round(statistics.median(times), 1),
              "scrub_p95_ms": round(float(np.percentile(times, 95)), 1),
              "scrub_max_ms": round(max(times), 1), "scrub_cpu_median_ms": round(statistics.median(cpu), 1),
              "renders_per_step": round(renders_per_step, 2), "view_px": [size.width(), size.height()],
              "load_average": [round(value, 1) for value in os.getloadavg()], **playback}
    print(f"scrub: {result['scrub_median_ms']} ms median, {result['scrub_p95_ms']} ms p95 per step "
          f"(CPU {result['scrub_cpu_median_ms']} ms median) "
          f"({result['renders_per_step']} renders per step, view {size.width()}×{size.height()} px); "
          f"playback 1×: {result['drawn_fps']} drawn frames/s, {result['data_frames_per_s']} data frames/s")
    print(json.dumps(result))
    window.close()
    window.deleteLater()
    app.processEvents()


if __name__ == "__main__":
    main()
