"""Accuracy of the automatic labelling on simulated takes and scenes and on the real DFKI glove
recording (issue 3 figures).

``evaluate_labelling``: per layout and seed, one right hand (:func:`core.simulate.simulate_take`) and a
two-hand scene with rigid objects (:func:`core.simulate.simulate_scene`), 0.3 mm noise, ghosts in
~5 % of frames, occlusion, shuffled points: ``correct_share``, ``ghost_labelled_share``,
``longest_swap_frames`` (see :func:`core.labelling.labelling_accuracy`) against the targets
(≥ 99.5 %, < 0.5 %, ≤ 10 frames).

``evaluate_real_recording``: the glove recording's 21 labelled markers (13 glove markers, elbow,
shoulder, three back and three pillow markers) with the labels stripped, ghosts added in 5 % of the
frames and the points shuffled per frame; labelled with ``glove-13`` (right hand); reports the share
of glove-marker samples given the recording's label, how many samples of the other markers got a hand
label (must be 0), and the mean IK residual after subject calibration (target ≤ 3 mm).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.evaluation.labelling_metrics import labelling_accuracy
from handmocap.core.labelling.models import SceneSettings
from handmocap.core.labelling.scene import label_scene

TARGETS = {"correct_share": 0.995, "ghost_labelled_share": 0.005, "longest_swap_frames": 10}


def _meets(accuracy: dict) -> bool:
    return (accuracy["correct_share"] >= TARGETS["correct_share"]
            and accuracy["ghost_labelled_share"] < TARGETS["ghost_labelled_share"]
            and accuracy["longest_swap_frames"] <= TARGETS["longest_swap_frames"])


def _rounded(accuracy: dict) -> dict:
    return {key: (round(value, 5) if isinstance(value, float) else value) for key, value in accuracy.items()}


def evaluate_labelling(layouts: Sequence[str] = ("dense", "glove-13"), seeds: Sequence[int] = (1, 2, 3),
                       frames: int = 2000, scene: bool = True, scene_objects: int = 2,
                       settings: SceneSettings | None = None, online: bool = False) -> dict:
    """Label simulated takes (one right hand) and, with ``scene``, two-hand scenes with
    ``scene_objects`` rigid objects, per layout and seed (``online``: in online mode); returns
    ``{"runs": [...], "summary": {...}}`` with each run's accuracy, time and whether it meets the
    targets, and the pooled figures per layout and case."""
    from handmocap.core.simulate import SimulatedScene, SimulatedTake, simulate_scene, simulate_take

    runs = []
    for layout in layouts:
        for seed in seeds:
            cases = [("one_hand", None)] + ([("scene", None)] if scene else [])
            for case, _ in cases:
                simulated: SimulatedTake | SimulatedScene
                if case == "one_hand":
                    simulated = simulate_take(layout=layout, n_frames=frames, seed=seed, noise_mm=0.3,
                                              ghost_rate=0.05, occlusion=True, unlabelled=True)
                    start = time.perf_counter()
                    result = label_scene(simulated.take, "right", layout, settings=settings, online=online)
                else:
                    simulated = simulate_scene(layout=layout, n_frames=frames, seed=seed, n_objects=scene_objects)
                    start = time.perf_counter()
                    result = label_scene(simulated.take, "both", layout, objects=simulated.objects,
                                         settings=settings, online=online)
                seconds = time.perf_counter() - start
                accuracy = labelling_accuracy(result, simulated.truth["point_marker"])
                runs.append({"layout": layout, "seed": int(seed), "case": case, "frames": frames,
                             "seconds": round(seconds, 2), "meets_targets": _meets(accuracy),
                             "models": [[model.name, model.kind, model.init_frame] for model in result.models],
                             **_rounded(accuracy)})
    summary = {}
    for layout in layouts:
        for case in ("one_hand", "scene"):
            chosen = [run for run in runs if run["layout"] == layout and run["case"] == case]
            if not chosen:
                continue
            observed = sum(run["observed_samples"] for run in chosen)
            ghosts = sum(run["ghost_points"] for run in chosen)
            summary[f"{layout}/{case}"] = {
                "correct_share": round(sum(run["correct_share"] * run["observed_samples"] for run in chosen)
                                       / max(observed, 1), 5),
                "ghost_labelled_share": round(sum(run["ghost_labelled_share"] * run["ghost_points"] for run in chosen)
                                              / max(ghosts, 1), 5),
                "longest_swap_frames": max(run["longest_swap_frames"] for run in chosen),
                "min_correct_share": min(run["correct_share"] for run in chosen),
                "all_meet_targets": all(run["meets_targets"] for run in chosen)}
    return {"runs": runs, "summary": summary, "targets": TARGETS}


def unlabelled_real_take(path: str | Path = REAL_RECORDING, frames: int | None = None, ghost_rate: float = 0.05,
                         seed: int = 0, noise_mm: float = 0.0):
    """The recording with its labels stripped: per-frame shuffled points plus ghosts in ``ghost_rate``
    of the frames, and Gaussian noise of ``noise_mm`` per axis added to every point. Returns ``(take,
    point_marker (F,P) index into the recording's markers (-1 ghost),
    recording marker names)``."""
    from handmocap.core.io import Take, load_take
    from handmocap.core.simulate.take import _ghosts, _shuffled_points

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path.name}: the real recording is not there ({path.parent})")
    recording = load_take(path)
    positions = recording.marker_positions if frames is None else recording.marker_positions[:frames]
    rng = np.random.default_rng([seed, 3])
    ghosts = _ghosts(positions, ghost_rate, rng)
    observed = np.concatenate([positions, ghosts], axis=1)
    observed = observed + rng.normal(0.0, noise_mm, observed.shape) if noise_mm > 0 else observed
    points, point_marker = _shuffled_points(observed, positions.shape[1], rng)
    take = Take(marker_names=[f"point_{index:03d}" for index in range(points.shape[1])], marker_positions=points,
                frame_rate=recording.frame_rate, first_frame=recording.first_frame, vendor=recording.vendor)
    return take, point_marker, list(recording.marker_names)


def evaluate_real_recording(path: str | Path = REAL_RECORDING, frames: int | None = None, layout: str = "glove-13",
                            compare_uncalibrated: bool = True, settings: SceneSettings | None = None,
                            online: bool = False) -> dict:
    """Label the stripped, shuffled real recording with ``layout`` on the right hand (module docstring;
    ``online``: in online mode)."""
    from handmocap.core.model import load_layout, marker_columns

    take, point_marker, recording_names = unlabelled_real_take(path, frames)
    hand_names = load_layout(layout).names
    recording_to_layout = marker_columns(hand_names, recording_names)      # per recording marker: layout index
    start = time.perf_counter()
    result = label_scene(take, "right", layout, settings=settings, online=online)
    seconds = time.perf_counter() - start
    truth = np.where(point_marker >= 0, recording_to_layout[np.maximum(point_marker, 0)], -1)
    other = (point_marker >= 0) & (truth < 0)                                   # arm, back, pillow markers
    accuracy = labelling_accuracy(result, truth)
    labelled_points = np.zeros(point_marker.shape, dtype=bool)
    label_frames, label_markers = np.nonzero(result.assignment >= 0)
    labelled_points[label_frames, result.assignment[label_frames, label_markers]] = True
    other_names = [name for name, index in zip(recording_names, recording_to_layout, strict=True) if index < 0]
    correct = round(accuracy["correct_share"], 5)
    other_labelled = int((other & labelled_points).sum())
    mean_residual = round(float(np.nanmean(result.residuals_mm)), 4)
    report = {"frames": int(take.n_frames), "layout": layout, "hand_markers": len(hand_names),
              "other_markers": other_names, "seconds": round(seconds, 2),
              "hand_samples_correct_share": correct,
              "hand_samples_missed_share": round(accuracy["missed_share"], 5),
              "hand_samples_wrong_share": round(accuracy["wrong_share"], 5),
              "hand_samples": accuracy["observed_samples"],
              "other_marker_samples_given_hand_label": other_labelled,
              "other_marker_samples": int(other.sum()),
              "ghost_points_given_hand_label": int(((point_marker < 0) & labelled_points
                                                    & np.isfinite(take.marker_positions).all(axis=2)).sum()),
              "ghost_points": int(((point_marker < 0) & np.isfinite(take.marker_positions).all(axis=2)).sum()),
              "longest_swap_frames": accuracy["longest_swap_frames"],
              "mean_ik_residual_mm": mean_residual,
              "calibration": result.models[0].calibration}
    if compare_uncalibrated:
        base = settings or SceneSettings()
        plain = label_scene(take, "right", layout, online=online,
                            settings=SceneSettings(**{**base.__dict__, "calibrate": False}))
        report["mean_ik_residual_uncalibrated_mm"] = round(float(np.nanmean(plain.residuals_mm)), 4)
    report["meets_targets"] = correct >= 0.995 and other_labelled == 0 and mean_residual <= 3.0
    return report
