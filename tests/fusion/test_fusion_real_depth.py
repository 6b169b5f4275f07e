"""Fitting the model to a real SR305 depth frame of an open hand (issue 15, item 7): from the bounding box of the
nearest object, with the depth and silhouette terms only, the fit ends with the fingers extended and apart."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from core.camera.model import Camera
from core.evaluation.data import RGBD_FRAMES
from core.fusion.depth_fit import fit_depth_frame
from core.fusion.pose import digit_points
from core.model import load_template

FRAME = RGBD_FRAMES / "sr305_open_right_hand" / "110.png"
#: SR305 intrinsics and depth unit from the data's README
SR305 = Camera(np.array([[476.007, 0.0, 313.683], [0.0, 476.007, 242.755], [0.0, 0.0, 1.0]]), np.zeros(5),
               (640, 480), registered=True, name="SR305")
DEPTH_UNIT_MM = 0.125


@pytest.mark.skipif(not FRAME.exists(), reason="real depth frames not available")
def test_fusion_real_depth_frame_fit_opens_the_hand():
    depth = cv2.imread(str(FRAME), cv2.IMREAD_UNCHANGED).astype(np.float32) * DEPTH_UNIT_MM
    fit = fit_depth_frame(depth, SR305)
    print(f"depth residual {fit.depth_residual_mm:.2f} mm, silhouette term {fit.silhouette:.3f}, start box {fit.box}")
    flexion = np.degrees(fit.theta[6:].reshape(5, 4)[1:, 1:])      # index..little: base, middle, distal flexion
    assert np.abs(flexion).max() < 45.0, flexion                      # extended
    tips = digit_points(load_template(), fit.theta)[1:, 2]
    gaps = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    assert gaps.min() > 18.0, gaps                                     # apart (a finger is ~16 mm wide)
    assert fit.depth_residual_mm < 6.0
    assert fit.silhouette < 0.5
