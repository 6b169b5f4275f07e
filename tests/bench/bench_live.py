"""Live capture figures (README "Live capture"): the stand-in server replays a take on 127.0.0.1 in a process of
its own (pinned to the second core), ``handmocap live record`` records it in another (pinned to the first:
the recording runs on one core), and the figures are read from its ``--json`` last line. Then the recorded
take is labelled offline in online mode and compared with the live labels (agreement: samples both give the
same point, over the samples either labels), and, where the replayed take's truth is known, the live labels are
checked against it.

    python tests/bench/bench_live.py [--seconds 30] [--only one_hand_100|scene_200|real_100] [--protocol qtm]

The ``window`` case (run it under a display: ``xvfb-run -a -s "-screen 0 1600x1000x24" python
tests/bench/bench_live.py --only window``) measures the live window instead: the stand-in streams one hand at
100 Hz from its own process (the second core) while this process (pinned to the first core unless
``--no-pin``) captures, labels and shows it in :class:`app.gui.live_window.LiveWindow`; it reports the drawn
frames per second, the time a draw takes, and whether the stream was held up (frames dropped, latency).
It runs only with ``--only window`` (it needs a display).

Bounded: each case streams ``--seconds`` seconds (30 by default) and everything stops by itself.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handmocap.core.evaluation.data import REAL_RECORDING

ROOT = Path(__file__).resolve().parents[2]
REAL = REAL_RECORDING
CLI = [sys.executable, "-m", "handmocap.app.cli.main"]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def pinned(core: int) -> list[str]:
    return ["taskset", "-c", str(core)] if os.cpu_count() and os.cpu_count() > 1 else []


def run_case(name: str, take_path: Path, rate: float, layout: str, hands: str, objects: Path | None,
             protocol: str, seconds: float, folder: Path) -> dict:
    port = free_port()
    serve = subprocess.Popen(pinned(1) + CLI + ["live", "serve", str(take_path), "--protocol", protocol, "--port",
                                                 str(port), "--rate", str(rate), "--unlabelled", "--once",
                                                 "--seconds", str(seconds + 30)],
                             stderr=subprocess.PIPE, text=True, cwd=ROOT)
    serve.stderr.readline()
    out = folder / f"{name}_{protocol}.c3d"
    address = f"127.0.0.1:{port}"
    command = pinned(0) + CLI + ["live", "record", f"--{protocol}", address, "--layout", layout, "--hands", hands,
                                 "--seconds", str(seconds), "--out", str(out), "--session", str(folder / "session"),
                                 "--json", "--quiet"] + (["--objects", str(objects)] if objects else [])
    started = time.monotonic()
    record = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, timeout=seconds + 120)
    serve.terminate()
    serve.wait(10)
    if record.returncode != 0:
        raise SystemExit(f"{name}: record failed: {record.stderr.strip()}")
    figures = json.loads(record.stdout.strip().splitlines()[-1])
    figures["wall_s"] = round(time.monotonic() - started, 1)
    return figures


def agreement(out: Path, session: Path, take_id: str, layout: str, hands: str, objects: Path | None) -> dict:
    """Live labels (the session take's first review step) against the same take labelled offline, online mode."""
    from handmocap.core.io import load_take
    from handmocap.core.labelling.scene import label_scene
    from handmocap.core.session.session import Session

    take = load_take(out)
    offline = label_scene(take, hands=hands, layout=layout, objects=str(objects) if objects else None, online=True)
    opened_session = Session.open(session)
    opened = opened_session.open_take(take_id)
    live = opened.review.assignment
    names = list(opened.review.label_names)
    opened.close(save=False)
    opened_session.close()
    columns = [names.index(name) for name in offline.marker_names]
    live = live[:, columns]
    other = offline.assignment
    either = (live >= 0) | (other >= 0)
    return {"agreement": round(float(((live == other) & either).sum() / max(either.sum(), 1)), 4),
            "offline_online_labelled_share": round(float((other >= 0).mean()), 4),
            "live_labelled_share": round(float((live >= 0).mean()), 4)}


def real_truth(out: Path, session: Path, take_id: str) -> dict:
    """On the replayed real recording: the hand labels the live labeller gave, against the recording's own labels
    (a point is matched to the file's marker at the same coordinates)."""
    from handmocap.core.io import load_take
    from handmocap.core.session.session import Session

    truth = load_take(REAL)
    recorded = load_take(out)
    opened_session = Session.open(session)
    opened = opened_session.open_take(take_id)
    review = opened.review
    names, assignment = list(review.label_names), review.assignment.copy()
    opened.close(save=False)
    opened_session.close()
    frames = min(len(recorded.marker_positions), len(truth.marker_positions))
    hand = [name for name in names if name in truth.marker_names]
    correct = wrong = missed = 0
    for frame in range(frames):
        for name in hand:
            expected = truth.marker_positions[frame, truth.marker_names.index(name)]
            column = assignment[frame, names.index(name)]
            if not np.isfinite(expected).all():
                continue
            if column < 0:
                missed += 1
            elif np.abs(recorded.marker_positions[frame, column] - expected).max() < 0.01:
                correct += 1
            else:
                wrong += 1
    total = max(correct + wrong + missed, 1)
    return {"hand_samples": total, "hand_correct_share": round(correct / total, 4),
            "hand_wrong_share": round(wrong / total, 4), "hand_missed_share": round(missed / total, 4)}


def load() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def window_case(seconds: float, protocol: str, pin: bool) -> dict:
    """The live window's drawn frames per second while the stand-in streams one hand at 100 Hz (module
    docstring); the figures and the load average before and after."""
    from PySide6.QtWidgets import QApplication

    from handmocap.app.gui.live_window import DRAW_HZ, LiveWindow
    from handmocap.core.io import save_take
    from handmocap.core.live.capture import LiveCapture
    from handmocap.core.live.systems import make_source
    from handmocap.core.simulate.take import simulate_take

    if pin and hasattr(os, "sched_setaffinity") and (os.cpu_count() or 1) > 1:
        os.sched_setaffinity(0, {0})
    app = QApplication.instance() or QApplication(sys.argv)
    figures: dict = {"load_before": load(), "pinned": pin, "draw_hz_timer": DRAW_HZ}
    with tempfile.TemporaryDirectory(prefix="bench-live-window-") as tmp:
        folder = Path(tmp)
        take = simulate_take("glove-13", n_frames=int((seconds + 40) * 100), seed=11, noise_mm=0.3, ghost_rate=0.05,
                             occlusion=True, unlabelled=True, frame_rate=100.0).take
        save_take(take, folder / "one_hand.c3d")
        port = free_port()
        serve = subprocess.Popen(pinned(1) + CLI + ["live", "serve", str(folder / "one_hand.c3d"), "--protocol",
                                                     protocol, "--port", str(port), "--rate", "100", "--unlabelled",
                                                     "--seconds", str(seconds + 60)],
                                 stderr=subprocess.PIPE, text=True, cwd=ROOT)
        serve.stderr.readline()
        capture = LiveCapture(make_source(protocol, f"127.0.0.1:{port}"), "glove-13", "auto",
                              session=folder / "session", name="window")
        window = None
        try:
            capture.start()
            window = LiveWindow(capture, folder / "session", "window")
            draw_times: list[float] = []       # the window's handling of a new frame (the 3D scene and the panel)
            render_times: list[float] = []     # the VTK renders (in the view's paint)
            draw = window.draw_latest

            def timed() -> None:
                started = time.perf_counter()
                before = window._last_snapshot
                draw()
                if window._last_snapshot is not before:
                    draw_times.append(time.perf_counter() - started)

            render_started = [0.0]
            render_window = window.view.GetRenderWindow()
            render_window.AddObserver("StartEvent", lambda *_: render_started.__setitem__(0, time.perf_counter()))
            render_window.AddObserver("EndEvent", lambda *_: render_times.append(time.perf_counter()
                                                                                 - render_started[0]))
            window.timer.timeout.disconnect()
            window.timer.timeout.connect(timed)
            window.show()
            end = time.monotonic() + 30.0
            while not capture.labeller.started and time.monotonic() < end:      # the start-up window first
                app.processEvents()
                time.sleep(0.005)
            drawn, received, draws, renders = window.drawn, capture.frames_received, len(draw_times), len(render_times)
            started = time.monotonic()
            cpu = time.process_time()
            while time.monotonic() - started < seconds:
                app.processEvents()
                time.sleep(0.002)
            elapsed = time.monotonic() - started
            times = np.array(draw_times[draws:]) * 1000.0
            rendering = np.array(render_times[renders:]) * 1000.0
            live = capture.figures()
            figures |= {
                "seconds": round(elapsed, 1),
                "drawn_per_s": round((window.drawn - drawn) / elapsed, 1),
                "received_per_s": round((capture.frames_received - received) / elapsed, 1),
                "draw_ms_p50": round(float(np.percentile(times, 50)), 1) if len(times) else None,
                "draw_ms_p99": round(float(np.percentile(times, 99)), 1) if len(times) else None,
                "render_ms_p50": round(float(np.percentile(rendering, 50)), 1) if len(rendering) else None,
                "render_ms_p99": round(float(np.percentile(rendering, 99)), 1) if len(rendering) else None,
                "cpu_share_of_a_core": round((time.process_time() - cpu) / elapsed, 2),
                "frames_dropped": live["frames_dropped"], "latency_ms_p50": live["latency_ms_p50"],
                "latency_ms_p99": live["latency_ms_p99"], "latency_ms_max": live["latency_ms_max"],
                "load_after": load(),
            }
        finally:
            if window is not None:
                window.stop()                        # the take written and entered as the operator's Stop does
                end = time.monotonic() + 120.0
                while window.result is None and time.monotonic() < end:
                    app.processEvents()
                    time.sleep(0.01)
                window.close()
            else:
                capture.stop()
            serve.terminate()
            serve.wait(10)
        if window is not None and window.result is not None:
            figures["frames_received"] = window.result.figures["frames_received"]
            figures["frames_dropped_total"] = window.result.figures["frames_dropped"]
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--only", choices=("one_hand_100", "scene_200", "real_100", "window"))
    parser.add_argument("--protocol", choices=("qtm", "natnet"), default=None, help="default: both")
    parser.add_argument("--no-pin", action="store_true", help="window: do not pin this process to the first core")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    if args.only == "window":
        protocols = [args.protocol] if args.protocol else ["qtm", "natnet"]
        results = {f"window_{protocol}": window_case(args.seconds, protocol, not args.no_pin)
                   for protocol in protocols}
        for name, figures in results.items():
            print(f"{name}: " + json.dumps(figures), flush=True)
        print(json.dumps(results))
        return 0
    from handmocap.core.io import save_take
    from handmocap.core.model.objects import save_scene_spec
    from handmocap.core.simulate.scene import simulate_scene
    from handmocap.core.simulate.take import simulate_take

    protocols = [args.protocol] if args.protocol else ["qtm", "natnet"]
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench-live-") as tmp:
        folder = Path(tmp)
        cases = []
        if args.only in (None, "one_hand_100"):
            frames = int(args.seconds * 100) + 200
            take = simulate_take("glove-13", n_frames=frames, seed=11, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                                 unlabelled=True, frame_rate=100.0).take
            save_take(take, folder / "one_hand.c3d")
            cases.append(("one_hand_100", folder / "one_hand.c3d", 100.0, "glove-13", "auto", None))
        if args.only in (None, "scene_200"):
            frames = int(args.seconds * 200) + 400
            scene = simulate_scene("glove-13", n_frames=frames, seed=12, hands="both", n_objects=1,
                                   frame_rate=200.0)
            save_take(scene.take, folder / "scene.c3d")
            save_scene_spec(scene.objects, folder / "objects.json")
            cases.append(("scene_200", folder / "scene.c3d", 200.0, "glove-13", "both", folder / "objects.json"))
        if args.only in (None, "real_100") and REAL.exists():
            cases.append(("real_100", REAL, 100.0, "glove-13", "auto", None))
        for name, path, rate, layout, hands, objects in cases:
            for protocol in protocols:
                figures = run_case(name, path, rate, layout, hands, objects, protocol, args.seconds, folder)
                out = folder / f"{name}_{protocol}.c3d"
                figures |= agreement(out, folder / "session", figures["take"], layout, hands, objects)
                if name == "real_100":
                    figures |= real_truth(out, folder / "session", figures["take"])
                keep = ("frames_received", "frames_dropped", "latency_ms_p50", "latency_ms_p99", "latency_ms_max",
                        "startup_frames", "startup_ms", "labelled_share", "hands", "agreement",
                        "offline_online_labelled_share", "hand_correct_share", "hand_wrong_share",
                        "hand_missed_share", "summary")
                results[f"{name}_{protocol}"] = {key: figures[key] for key in keep if key in figures}
                print(f"{name} {protocol}: " + json.dumps(results[f'{name}_{protocol}']), flush=True)
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
