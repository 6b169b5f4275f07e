"""Accuracy evaluations and benchmarks on simulated takes with ground truth and on the real recording.

* :mod:`core.evaluation.ik` — IK throughput and the journal's Table 1 experiment;
* :mod:`core.evaluation.labelling`, :mod:`~core.evaluation.labelling_metrics`,
  :mod:`~core.evaluation.labelling_robustness`, :mod:`~core.evaluation.labelling_bench` — labelling accuracy,
  the robustness sweep and held-out seeds, labelling speed;
* :mod:`core.evaluation.gaps` — gap-fill error on hidden gaps;
* :mod:`core.evaluation.calibration` — subject calibration on re-proportioned synthetic subjects.
"""
