"""Scan calibration benchmark and figures: the whole pipeline on a 200 000-point synthetic scan (one core),
then the accuracy over the five re-proportioned synthetic subjects of ``core.evaluation.calibration``
(surface and joint errors against the truth, marker alignment gain over the template on simulated takes).

Run: taskset -c 0 python tests/bench/bench_calibrate.py [--points 200000] [--subjects 5] [--skip-evaluation]
The last line is JSON with seconds, scan_points and (unless skipped) surface_mean_mm, surface_max_mm,
joint_error_mm, alignment_gain_mm and the per-subject breakdown.
"""

import argparse
import json

from handmocap.core.evaluation.calibration import SUBJECTS, bench_calibrate, evaluate_subject


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=200_000)
    parser.add_argument("--subjects", type=int, default=len(SUBJECTS))
    parser.add_argument("--skip-evaluation", action="store_true")
    args = parser.parse_args()
    figures = bench_calibrate(n_points=args.points)
    print(f"pipeline on a {figures['scan_points']:,}-point scan: {figures['seconds']:.1f} s")
    if not args.skip_evaluation:
        rows = []
        for index in range(min(args.subjects, len(SUBJECTS))):
            row = evaluate_subject(index, n_points=args.points)
            rows.append({key: round(value, 3) if isinstance(value, float) else value for key, value in row.items()})
            print(f"subject {index} {SUBJECTS[index]}: surface mean {row['surface_mean_mm']:.2f} mm max "
                  f"{row['surface_max_mm']:.2f} mm, joints max {row['joint_max_mm']:.2f} mm ({row['worst_joint']}) "
                  f"mean {row['joint_mean_mm']:.2f} mm, marker alignment template {row['template_residual_mm']:.2f} mm "
                  f"-> calibrated {row['calibrated_residual_mm']:.2f} mm (true model {row['true_residual_mm']:.2f} mm)",
                  flush=True)
        figures.update({
            "surface_mean_mm": round(sum(r["surface_mean_mm"] for r in rows) / len(rows), 3),
            "surface_max_mm": max(r["surface_max_mm"] for r in rows),
            "joint_error_mm": max(r["joint_max_mm"] for r in rows),
            "alignment_gain_mm": round(sum(r["alignment_gain_mm"] for r in rows) / len(rows), 3),
            "alignment_gain_bound_mm": round(sum(r["template_residual_mm"] - r["true_residual_mm"] for r in rows)
                                             / len(rows), 3),
            "subjects": rows,
        })
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
