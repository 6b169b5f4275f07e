"""The real DFKI glove recording (../shared/data/real): solve with glove-13 and fit marker placement."""


import numpy as np
import pytest

from handmocap.core.calibration.marker_placement import fit_marker_placement
from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.ik import solve_take
from handmocap.core.io import Take
from handmocap.core.model import MarkerLayout, MarkerSpec, load_layout, load_template

pytestmark = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")


@pytest.fixture
def real_take(real_recording) -> Take:
    take = real_recording
    return Take(take.marker_names, take.marker_positions[:600], take.frame_rate, take.first_frame, take.vendor)


def test_glove_layout_solves_the_real_recording(real_take):
    result = solve_take(real_take, load_template(), load_layout("glove-13"))
    assert result.joint_angles.shape == (600, 26)
    assert np.isfinite(result.joint_angles).all()
    assert result.mean_residual_mm < 5.0
    thumb_tip = result.marker_names.index("thumb_tip")
    observed = np.isfinite(real_take.marker_positions[:, real_take.marker_names.index("thumb_tip")]).all(axis=1)
    assert np.isnan(result.residuals_mm[~observed, thumb_tip]).all()


def test_fitting_the_placement_lowers_the_residual(real_take):
    model = load_template()
    start = load_layout("glove-13")
    # a rough hand-made placement: every marker straight on the dorsal side, 4 mm off the skin
    shifted = MarkerLayout(start.name, tuple(
        MarkerSpec(s.name, s.between, s.along, "dorsal", None, 4.0) for s in start.markers))
    fitted, residuals = fit_marker_placement(real_take.marker_positions, real_take.marker_names, model, shifted,
                                             iterations=2, max_frames=120)
    assert min(residuals) < 0.7 * residuals[0]
    assert fitted.names == start.names


def test_fitting_needs_portable_markers(real_take):
    layout = MarkerLayout("v", (MarkerSpec("hand_top", vertex=10),))
    with pytest.raises(InputError):
        fit_marker_placement(real_take.marker_positions, real_take.marker_names, load_template(), layout)
