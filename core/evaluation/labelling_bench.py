"""Throughput of the automatic labelling (``handmocap bench label``): offline labelling + IK of
simulated unlabelled takes, one core (run under ``taskset -c 0`` to pin it)."""

from __future__ import annotations

import time

from handmocap.core.labelling.scene import label_scene


def bench_label(frames: int = 2000, seed: int = 1, layout: str = "dense", scene_layout: str = "dense",
                objects: int = 3) -> dict:
    """Frames per second of :func:`label_scene` (offline, subject calibration included) on

    * one right hand with ``layout`` (0.3 mm noise, occlusion, ghosts in 5 % of frames, shuffled), and
    * a scene of two hands with ``scene_layout`` and ``objects`` rigid objects (same conditions).

    A short run first loads the compiled kernels; the simulation is not timed. ``frames_per_s_*`` are
    wall-clock figures; ``cpu_frames_per_s_*`` divide by the process CPU time instead (the figure a
    core of its own would give when other programs share the machine).
    """
    from handmocap.core.simulate import simulate_scene, simulate_take

    one = simulate_take(layout=layout, n_frames=frames, seed=seed, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                        unlabelled=True)
    scene = simulate_scene(layout=scene_layout, n_frames=frames, seed=seed, n_objects=objects)
    warm = simulate_scene(layout=scene_layout, n_frames=60, seed=seed, n_objects=objects)
    label_scene(warm.take, "both", scene_layout, objects=warm.objects)
    start, cpu = time.perf_counter(), time.process_time()
    label_scene(one.take, "right", layout)
    one_seconds, one_cpu = time.perf_counter() - start, time.process_time() - cpu
    start, cpu = time.perf_counter(), time.process_time()
    label_scene(scene.take, "both", scene_layout, objects=scene.objects)
    scene_seconds, scene_cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"frames_per_s_one_hand": round(frames / one_seconds, 1),
            "frames_per_s_scene": round(frames / scene_seconds, 1),
            "frames": frames, "seed": seed, "layout_one_hand": layout, "layout_scene": scene_layout,
            "scene_hands": 2, "scene_objects": objects,
            "one_hand_markers": int(one.truth["marker_names"].size),
            "scene_markers": int(scene.truth["marker_names"].size),
            "seconds_one_hand": round(one_seconds, 3), "seconds_scene": round(scene_seconds, 3),
            "cpu_frames_per_s_one_hand": round(frames / max(one_cpu, 1e-9), 1),
            "cpu_frames_per_s_scene": round(frames / max(scene_cpu, 1e-9), 1)}
