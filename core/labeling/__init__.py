"""Automatic labelling of unlabelled optical markers: scenes of hands and rigid objects, per-frame
joint Hungarian assignment + IK, initialisation, subject calibration, evaluation."""

from core.labeling.metrics import labelling_accuracy
from core.labeling.models import SceneSettings
from core.labeling.objects import ObjectSpec, load_scene_spec, rigid_body_from_points, save_scene_spec
from core.labeling.scene import SceneLabeling, SceneModel, label_scene
from core.labeling.tracker import LabelingResult, TrackerSettings, initial_pose_from_points, label_take

__all__ = ["LabelingResult", "ObjectSpec", "SceneLabeling", "SceneModel", "SceneSettings", "TrackerSettings",
           "initial_pose_from_points", "label_scene", "label_take", "labelling_accuracy", "load_scene_spec",
           "rigid_body_from_points", "save_scene_spec"]
