"""Automatic labelling of unlabelled optical markers: scenes of hands and rigid objects, per-frame
joint Hungarian assignment + IK, initialisation, subject calibration, evaluation."""

from core.labeling.metrics import labelling_accuracy
from core.labeling.models import SceneSettings
from core.labeling.objects import ObjectSpec, load_scene_spec, rigid_body_from_points, save_scene_spec
from core.labeling.scene import SceneLabeling, SceneModel, label_scene

__all__ = ["ObjectSpec", "SceneLabeling", "SceneModel", "SceneSettings", "label_scene", "labelling_accuracy",
           "load_scene_spec", "rigid_body_from_points", "save_scene_spec"]
