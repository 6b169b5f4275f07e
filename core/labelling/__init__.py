"""Automatic labelling of unlabelled optical markers: scenes of hands and rigid objects, per-frame
joint Hungarian assignment + IK, initialisation, side decision, swap repair, labelling health."""

from handmocap.core.labelling.models import SceneSettings
from handmocap.core.labelling.result import SceneLabelling, SceneModel
from handmocap.core.labelling.scene import label_scene

__all__ = ["SceneLabelling", "SceneModel", "SceneSettings", "label_scene"]
