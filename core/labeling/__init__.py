"""Automatic labelling of unlabelled optical markers: per-frame Hungarian assignment + IK."""

from core.labeling.metrics import labelling_accuracy
from core.labeling.tracker import LabelingResult, TrackerSettings, initial_pose_from_points, label_take

__all__ = ["LabelingResult", "TrackerSettings", "initial_pose_from_points", "label_take", "labelling_accuracy"]
