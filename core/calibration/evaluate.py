"""Figures of the scan calibration on synthetic subjects (issue 4) and the speed benchmark.

Each subject is the template generator with re-proportioned fingers (±15 %) and palm width (±10 %),
scanned near the flat calibration pose with 0.5 mm noise, holes, 1 % outliers and a table in the
background (:func:`core.calibration.synthetic_scan.synthetic_scan`), landmarks taken from the truth.
Figures:

* ``surface_mean_mm`` / ``surface_max_mm``: distance of the calibrated surface (its vertices) to the
  true surface (exact point-to-triangle), mean over vertices and subjects / max;
* ``joint_error_mm``: max over subjects and the 16 joints of the distance between the calibrated
  model's joints (posed at the fitted posture) and the true joints; ``joint_mean_mm`` their mean;
* ``alignment_gain_mm``: on a simulated take of each subject (dense layout, 0.5 mm marker noise, the
  simulator's mixed motion), mean IK marker residual with the template minus that with the calibrated
  model, averaged over subjects (``alignment_gain_glove13_mm``: the same with the 13-marker glove layout);
* ``seconds`` / ``scan_points`` of :func:`bench_calibrate`: the whole pipeline on a 200 000-point scan.

The alignment gain is bounded by the template's own residual: with these proportions the layered IK
absorbs most of the mismatch (pose, flexion), so the template's mean residual is only 2–4 mm and the
calibrated model's about 1.3 mm (the true subject model: 0.6 mm; the rest is marker placement on a
different mesh and the relocated joints).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from core.calibration.landmarks import landmarks_from_truth
from core.calibration.pipeline import calibrate_scan
from core.calibration.report import point_to_mesh_distances
from core.calibration.synthetic_scan import synthetic_scan
from core.errors import CancelledError
from core.ik import IKSettings, solve_positions
from core.model import HandModel, load_layout, load_template, marker_positions_batch, resolve_layout
from core.model.skeleton import HandProportions
from core.simulate import simulate_joint_angles

#: (finger length scale per digit thumb..little, palm width scale) of the evaluation subjects
SUBJECTS: tuple[tuple[tuple[float, float, float, float, float], float], ...] = (
    ((0.85, 0.85, 0.85, 0.85, 0.85), 0.90),     # small hand
    ((1.15, 1.15, 1.15, 1.15, 1.15), 1.10),     # large hand
    ((1.10, 0.90, 1.15, 0.88, 1.05), 1.00),     # uneven fingers
    ((0.92, 0.95, 0.90, 0.93, 0.90), 1.08),     # short fingers, wide palm
    ((1.08, 1.12, 1.06, 1.10, 1.12), 0.92),     # long fingers, narrow palm
)


def subject_proportions(index: int) -> HandProportions:
    """Proportions of evaluation subject ``index`` (see :data:`SUBJECTS`)."""
    fingers, palm = SUBJECTS[index]
    return HandProportions().scaled(finger_scale=np.array(fingers), palm_width_scale=palm)


def marker_alignment_error(subject: HandModel, models: dict[str, HandModel], frames: int = 150, seed: int = 0,
                           noise_mm: float = 0.5, layout: str = "dense") -> dict[str, float]:
    """Mean layered-IK marker residual (mm) of each of ``models`` on a simulated take of ``subject``."""
    spec = load_layout(layout)
    thetas = simulate_joint_angles(frames, seed, "mixed")
    targets = marker_positions_batch(subject, resolve_layout(subject, spec), thetas)
    targets = targets + np.random.default_rng(seed).normal(0.0, noise_mm, targets.shape)
    settings = IKSettings(method="layered")
    return {name: solve_positions(targets, model, resolve_layout(model, spec), settings=settings).mean_residual_mm
            for name, model in models.items()}


def evaluate_subject(index: int, n_points: int = 200_000, take_frames: int = 150, seed: int = 0) -> dict:
    """Calibrate synthetic subject ``index`` and measure it against the truth (figures in mm)."""
    scan, truth = synthetic_scan(subject_proportions(index), n_points=n_points, seed=seed + index)
    template = load_template()
    start = time.perf_counter()
    result = calibrate_scan(scan, landmarks_from_truth(truth), template=template)
    seconds = time.perf_counter() - start
    surface = point_to_mesh_distances(result.fitted_vertices, truth["vertices"], truth["model"].faces)
    joints = np.linalg.norm(result.joints - truth["joints"], axis=1)
    models = {"template": template, "calibrated": result.model}
    residuals = marker_alignment_error(truth["model"], models, frames=take_frames, seed=seed + index)
    glove = marker_alignment_error(truth["model"], models, frames=take_frames, seed=seed + index, layout="glove-13")
    return {"subject": index, "seconds": seconds, "surface_mean_mm": float(surface.mean()),
            "surface_max_mm": float(surface.max()), "joint_max_mm": float(joints.max()),
            "joint_mean_mm": float(joints.mean()), "template_residual_mm": residuals["template"],
            "calibrated_residual_mm": residuals["calibrated"],
            "glove13_gain_mm": glove["template"] - glove["calibrated"], "warnings": len(result.report.warnings)}


def evaluate_calibration(subjects: int = len(SUBJECTS), n_points: int = 200_000, take_frames: int = 150,
                         progress: Callable[[float], None] | None = None,
                         cancelled: Callable[[], bool] | None = None) -> dict:
    """The issue's figures over the first ``subjects`` synthetic subjects (keys in the module docstring)."""
    rows = []
    for index in range(subjects):
        if cancelled is not None and cancelled():
            raise CancelledError("evaluation cancelled")
        rows.append(evaluate_subject(index, n_points=n_points, take_frames=take_frames))
        if progress is not None:
            progress((index + 1) / subjects)
    gains = [row["template_residual_mm"] - row["calibrated_residual_mm"] for row in rows]
    return {
        "subjects": subjects,
        "scan_points": n_points,
        "surface_mean_mm": round(float(np.mean([row["surface_mean_mm"] for row in rows])), 3),
        "surface_max_mm": round(float(np.max([row["surface_max_mm"] for row in rows])), 3),
        "joint_error_mm": round(float(np.max([row["joint_max_mm"] for row in rows])), 3),
        "joint_mean_mm": round(float(np.mean([row["joint_mean_mm"] for row in rows])), 3),
        "template_residual_mm": round(float(np.mean([row["template_residual_mm"] for row in rows])), 3),
        "calibrated_residual_mm": round(float(np.mean([row["calibrated_residual_mm"] for row in rows])), 3),
        "alignment_gain_mm": round(float(np.mean(gains)), 3),
        "min_alignment_gain_mm": round(float(np.min(gains)), 3),
        "alignment_gain_glove13_mm": round(float(np.mean([row["glove13_gain_mm"] for row in rows])), 3),
        "seconds_per_subject": round(float(np.mean([row["seconds"] for row in rows])), 2),
    }


def bench_calibrate(n_points: int = 200_000, seed: int = 0) -> dict:
    """Seconds of the whole pipeline (load from memory, clean, align, fit, joints, report) on one scan of
    ``n_points`` hand samples plus outliers and background (the template's MVC cache is warmed first)."""
    scan, truth = synthetic_scan(subject_proportions(2), n_points=n_points, seed=seed)
    landmarks = landmarks_from_truth(truth)
    template = load_template()
    from core.calibration.pipeline import joint_coordinates

    joint_coordinates(template)
    start = time.perf_counter()
    result = calibrate_scan(scan, landmarks, template=template)
    seconds = time.perf_counter() - start
    return {"seconds": round(seconds, 2), "scan_points": len(scan), "hand_points": n_points,
            "kept_points": len(result.scan), "vertices": len(result.model.vertices),
            "landmark_rms_mm": result.report.to_json()["landmark_rms_mm"]}
