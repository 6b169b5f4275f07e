"""Benchmark of ``handmocap batch``: takes per minute and frames per second with 1 and 2 workers.

Generates a study of simulated takes (one right hand, half glove-13 and half dense, noise, ghosts and
occlusion, unlabelled points) and runs the full pipeline (label, calibrate, fill ≤ 20 frames, solve,
export labelled C3D and joint-angle CSV) on it with 1 and then 2 local workers, each time on a fresh
copy of the session. Reports:

* takes per minute and frames per second per worker count, and the scaling (2 workers against 1);
* the overhead per take, in two parts: the session (a task run in this process against the bare steps,
  measured take by take in turn so that the machine's load weighs on both alike) and Dask (the batch's
  wall seconds per take with one worker against the seconds inside its tasks, same run); and the
  single-take CLI (``label``, ``fill``, ``solve`` as three calls per take, as operators script it today);
* the peak resident memory of each worker process, and numba compilations in the workers;
* the CPU seconds per take in one process and in a worker, on the same takes (the figure the machine's load
  changes least), their scaling with 2 workers, and the costliest take;
* the load average before and after each run (other work on the machine slows every figure).

The clusters are started as ``handmocap batch`` starts its own (:func:`core.batch.runner._local_cluster` under
:func:`core.batch.worker.local_worker_settings`: no ``MALLOC_TRIM_THRESHOLD_``, no profiler, a warming preload);
``--dask-defaults`` also runs the study on clusters with Dask's own settings, before them in the same run.

Usage: ``.venv/bin/python tests/bench/bench_batch.py [--takes 200] [--frames 1000] [--cli-takes 2]
[--dask-defaults]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Dask's nanny starts each worker with one BLAS/OpenMP thread; the plain-process and CLI baselines get the
# same, so that the overhead measured is the batch's own (set before numpy is imported)
SINGLE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
os.environ.update(SINGLE_THREAD)

LAYOUTS = ("glove-13", "dense")
SETTINGS = {"steps": ["label", "calibrate", "fill", "solve", "export"], "hands": "right", "max_gap": 20,
            "exports": ["c3d", "csv"]}


def make_study(folder: Path, takes: int, frames: int) -> list[Path]:
    """``takes`` raw C3D files in ``folder`` (alternating layouts; seeded, so the same every time)."""
    from handmocap.core.io import save_take
    from handmocap.core.simulate import simulate_take

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for number in range(takes):
        layout = LAYOUTS[number % 2]
        path = folder / f"{layout}_{number:04d}.c3d"
        take = simulate_take(layout=layout, n_frames=frames, seed=number, noise_mm=0.3, ghost_rate=0.05,
                             occlusion=True, unlabelled=True).take
        save_take(take, path)
        paths.append(path)
    return paths


def make_sessions(root: Path, paths: list[Path]):
    """One session per layout (the pipeline names one layout), holding that layout's takes."""
    from handmocap.core.session.session import Session

    sessions = {}
    for layout in LAYOUTS:
        session = Session.create(root / f"session-{layout}")
        for path in paths:
            if path.name.startswith(layout):
                session.add_take(path, layout=layout, hands=["right"])
        sessions[layout] = session
    return sessions


def baselines(paths: list[Path], root: Path) -> dict[str, float]:
    """Seconds per take, measured take by take in turn (so that the machine's load weighs on each alike):
    ``plain``: the pipeline's steps and exports in this process; ``task``: the same as a batch task
    (session take opened, one review step pushed and saved, batch state written) in this process, no
    Dask; ``cli``: ``handmocap label``, ``fill`` and ``solve`` as three calls. ``paths[0]`` warms this
    process up and is not counted."""
    from handmocap.core.batch.pipeline import pipeline_from_dict
    from handmocap.core.batch.steps import export_take, output_paths, run_steps
    from handmocap.core.batch.task import process_take
    from handmocap.core.io import load_take
    from handmocap.core.review import ReviewTake

    out = root / "baseline"
    out.mkdir(parents=True, exist_ok=True)
    sessions = make_sessions(root / "baseline-sessions", paths)
    times: dict[str, list[float]] = {"plain": [], "task": [], "cli": [], "plain_cpu": [], "task_cpu": []}
    for number, path in enumerate(paths):
        layout = path.name.split("_")[0]
        pipeline = pipeline_from_dict(SETTINGS | {"layout": layout, "output": str(out)})
        start, cpu = time.perf_counter(), time.process_time()
        review = ReviewTake.unlabelled(load_take(path))
        export_take(review, pipeline, run_steps(review, pipeline), output_paths(pipeline, out, path.stem))
        plain, plain_cpu = time.perf_counter() - start, time.process_time() - cpu
        entry = next(entry for entry in sessions[layout].takes if Path(entry.source) == path)
        start, cpu = time.perf_counter(), time.process_time()
        summary = process_take(str(sessions[layout].folder), entry.id, pipeline.to_dict(), "0" * 64, str(out),
                               f"task-{path.stem}")
        task, task_cpu = time.perf_counter() - start, time.process_time() - cpu
        assert summary["status"] == "done", summary
        if number:
            times["plain"].append(plain)
            times["task"].append(task)
            times["plain_cpu"].append(plain_cpu)
            times["task_cpu"].append(task_cpu)
            times["cli"].append(cli_seconds(path, out))
    return {name: sum(values) / len(values) for name, values in times.items()}


def cli_seconds(path: Path, out: Path) -> float:
    """Wall seconds of ``handmocap label``, ``fill`` and ``solve`` of one take as separate calls."""
    handmocap = str(Path(sys.executable).with_name("handmocap"))
    layout = path.name.split("_")[0]
    labelled, filled = out / f"cli-{path.stem}.c3d", out / f"cli-{path.stem}.filled.c3d"
    start = time.perf_counter()
    for command in (["label", str(path), "--layout", layout, "--hands", "right", "--out", str(labelled)],
                    ["fill", str(labelled), "--max-gap", "20", "--out", str(filled)],
                    ["solve", str(filled), "--layout", layout, "--out", str(out / f"cli-{path.stem}.npz"),
                     "--csv", str(out / f"cli-{path.stem}.csv")]):
        subprocess.run([handmocap, *command, "--quiet", "--overwrite"], check=True, capture_output=True,
                       env=os.environ | SINGLE_THREAD)
    return time.perf_counter() - start


def batch_run(root: Path, paths: list[Path], workers: int, dask_defaults: bool = False) -> dict:
    """The study on ``workers`` local workers (fresh sessions), started as ``handmocap batch`` starts them or,
    with ``dask_defaults``, with Dask's own settings: wall seconds with and without the cluster's start, frames,
    and the workers' peak memory (MiB) and compilations."""
    import contextlib

    from distributed import Client, LocalCluster

    from handmocap.core.batch.pipeline import pipeline_from_dict
    from handmocap.core.batch.runner import _local_cluster, plan_batch, run_batch
    from handmocap.core.batch.worker import local_worker_settings

    folder = root / f"run-{workers}{'-dask-defaults' if dask_defaults else ''}"
    sessions = make_sessions(folder, paths)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with contextlib.ExitStack() as stack:
        if dask_defaults:
            cluster = stack.enter_context(LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                       dashboard_address=None))
        else:
            stack.enter_context(local_worker_settings())
            cluster = stack.enter_context(_local_cluster(workers))
        client = stack.enter_context(Client(cluster))
        ready = time.perf_counter()
        trim = set(client.run(_trim_threshold).values())
        frames, summaries = 0, []
        for layout, session in sessions.items():
            pipeline = pipeline_from_dict(SETTINGS | {"layout": layout, "output": str(folder / "out")})
            progress = run_batch(plan_batch(session, pipeline), scheduler=cluster.scheduler_address)
            frames += progress.frames
            summaries += list(progress.summaries.values())
        end = time.perf_counter()
        memory = client.run(_peak_rss_mib)
    failed = [summary for summary in summaries if summary["status"] != "done"]
    return {"workers": workers, "dask_defaults": dask_defaults, "worker_trim_threshold": sorted(map(str, trim)),
            "load_before": round(load, 2), "takes": len(summaries), "failed": len(failed),
            "frames": frames, "seconds": round(end - start, 2), "seconds_without_start": round(end - ready, 2),
            "start_s": round(ready - start, 2),
            "takes_per_min": round(60 * len(summaries) / (end - start), 2),
            "frames_per_s": round(frames / (end - start), 1),
            "peak_worker_mib": round(max(memory.values()), 1),
            "compilations": sum(summary.get("compilations", 0) for summary in summaries),
            "mean_task_s": round(sum(s.get("seconds", 0) for s in summaries) / max(len(summaries), 1), 3),
            "mean_task_cpu_s": round(sum(s.get("cpu_seconds", 0) for s in summaries) / max(len(summaries), 1), 3),
            "max_task_cpu_s": round(max((s.get("cpu_seconds", 0) for s in summaries), default=0.0), 3),
            "costliest_take": max(summaries, key=lambda s: s.get("cpu_seconds", 0), default={}).get("name", ""),
            "task_cpu_by_take": {s.get("name", ""): s.get("cpu_seconds", 0) for s in summaries},
            "load_after": round(os.getloadavg()[0], 2)}


def _trim_threshold() -> str:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_", "unset")


def _peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=200)
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--cli-takes", type=int, default=2,
                        help="takes of each layout timed alone: in one process, as a task, through the CLI")
    parser.add_argument("--dask-defaults", action="store_true",
                        help="also run the study on clusters with Dask's own settings (before, same run)")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    try:
        paths = make_study(root / "raw", args.takes, args.frames)
        base = baselines(paths[:1 + 2 * args.cli_takes], root)  # as many of each layout after the first
        before = [batch_run(root, paths, workers, dask_defaults=True) for workers in (1, 2) if args.dask_defaults]
        runs = [batch_run(root, paths, workers) for workers in (1, 2)]
        one, two = runs
        per_take = one["seconds"] / one["takes"]
        measured = [path.stem for path in paths[1:1 + 2 * args.cli_takes]]  # the takes the baselines timed

        def same_takes_cpu(run: dict) -> float:  # CPU per take in the workers, over the baselines' takes
            return sum(run["task_cpu_by_take"][name] for name in measured) / len(measured)

        figures = {
            "takes": args.takes, "frames_per_take": args.frames, "cpu_count": os.cpu_count(),
            "plain_s_per_take": round(base["plain"], 3), "task_s_per_take": round(base["task"], 3),
            "plain_cpu_s_per_take": round(base["plain_cpu"], 3), "task_cpu_s_per_take": round(base["task_cpu"], 3),
            "worker_cpu_same_takes_s": round(same_takes_cpu(one), 3),
            "worker_cpu_over_process_cpu": round(same_takes_cpu(one) / base["task_cpu"], 3),
            "cpu_scaling_2_workers": round(one["mean_task_cpu_s"] / two["mean_task_cpu_s"], 3),
            "cli_s_per_take": round(base["cli"], 3),
            "session_overhead": round(base["task"] / base["plain"] - 1, 3),
            "cli_over_plain": round(base["cli"] / base["plain"], 3),
            "batch_1_worker_s_per_take": round(per_take, 3),
            "dask_overhead": round(per_take / one["mean_task_s"] - 1, 3),
            "scaling_2_workers": round(one["seconds"] / two["seconds"], 3),
            "scaling_2_workers_without_start": round(one["seconds_without_start"] / two["seconds_without_start"], 3),
            "runs": runs,
        }
        if before:
            figures |= {
                "dask_defaults_worker_cpu_same_takes_s": round(same_takes_cpu(before[0]), 3),
                "dask_defaults_worker_cpu_over_process_cpu": round(same_takes_cpu(before[0]) / base["task_cpu"], 3),
                "dask_defaults_scaling_2_workers": round(before[0]["seconds"] / before[1]["seconds"], 3),
                "dask_defaults_runs": before}
        for run in before + runs:
            print(f"{'Dask defaults, ' if run['dask_defaults'] else ''}{run['workers']} worker(s) "
                  f"(MALLOC_TRIM_THRESHOLD_ in the workers: {', '.join(run['worker_trim_threshold'])}; cluster start "
                  f"{run['start_s']} s): "
                  f"{run['takes']} takes ({run['failed']} failed) in {run['seconds']} s "
                  f"({run['seconds_without_start']} s after the cluster started): {run['takes_per_min']} takes/min, "
                  f"{run['frames_per_s']} frames/s; mean task {run['mean_task_s']} s ({run['mean_task_cpu_s']} s CPU); "
                  f"peak worker memory {run['peak_worker_mib']} MiB; {run['compilations']} numba compilations; "
                  f"costliest task {run['max_task_cpu_s']} s CPU ({run['costliest_take']}); load average before "
                  f"{run['load_before']}, "
                  f"after {run['load_after']}")
        print(f"per take, measured in turn: steps in one process {base['plain']:.2f} s, as a batch task without "
              f"Dask {base['task']:.2f} s (session: +{100 * figures['session_overhead']:.1f} %), single-take CLI "
              f"(label, fill, solve) {base['cli']:.2f} s ({figures['cli_over_plain']:.2f}× the steps)")
        print(f"CPU per take ({', '.join(measured)}): {base['plain_cpu']:.2f} s in one process "
              f"({base['task_cpu']:.2f} s as a task without Dask), {figures['worker_cpu_same_takes_s']:.2f} s in a "
              f"worker ({figures['worker_cpu_over_process_cpu']:.2f}x the task in one process); over all the takes "
              f"{one['mean_task_cpu_s']:.2f} s in a worker, {two['mean_task_cpu_s']:.2f} s with 2 workers (CPU-time "
              f"scaling {figures['cpu_scaling_2_workers']:.2f}: 1.00 when the two workers do not slow each other)")
        if before:
            print(f"Dask's defaults, same run: {figures['dask_defaults_worker_cpu_same_takes_s']:.2f} s CPU per take "
                  f"in a worker ({figures['dask_defaults_worker_cpu_over_process_cpu']:.2f}x the task in one process; "
                  f"{before[0]['mean_task_cpu_s']:.2f} s over all the takes), scaling with 2 workers "
                  f"{figures['dask_defaults_scaling_2_workers']:.2f}x")
        print(f"batch, 1 worker: {per_take:.2f} s per take against {one['mean_task_s']:.2f} s inside the tasks "
              f"(Dask and cluster start: +{100 * figures['dask_overhead']:.1f} %); scaling with 2 workers "
              f"{figures['scaling_2_workers']:.2f}× ({figures['scaling_2_workers_without_start']:.2f}× without the "
              "cluster start)")
        print(json.dumps(figures))
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
