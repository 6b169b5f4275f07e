"""Live capture figures (README "Live capture"): the stand-in server replays a take on 127.0.0.1 in a process of
its own (pinned to the second core), ``handmocap live record`` records it in another (pinned to the first:
the recording runs on one core), and the figures are read from its ``--json`` last line. Then the recorded
take is labelled offline in online mode and compared with the live labels (agreement: samples both give the
same point, over the samples either labels), and, where the replayed take's truth is known, the live labels are
checked against it.

    python tests/bench/bench_live.py [--seconds 30] [--only one_hand_100|scene_200|real_100] [--protocol qtm]

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

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT.parent / "shared" / "data" / "real" / "dfki_glove_right_hand_frames_0001_3000.tsv"
CLI = [sys.executable, "-m", "app.cli.main"]


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
    from core.io import load_take
    from core.labelling.scene import label_scene
    from core.session.session import Session

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
    from core.io import load_take
    from core.session.session import Session

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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--only", choices=("one_hand_100", "scene_200", "real_100"))
    parser.add_argument("--protocol", choices=("qtm", "natnet"), default=None, help="default: both")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from core.io import save_take
    from core.model.objects import save_scene_spec
    from core.simulate.scene import simulate_scene
    from core.simulate.take import simulate_take

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
