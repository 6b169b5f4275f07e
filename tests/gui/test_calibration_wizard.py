"""The calibration wizard driven end to end on a synthetic scan with landmarks loaded from JSON."""

import numpy as np
import pytest
from conftest import release

from handmocap.core.calibration.landmarks import landmarks_from_truth, save_landmarks
from handmocap.core.calibration.scan import save_ply
from handmocap.core.calibration.synthetic_scan import synthetic_scan
from handmocap.core.model import HandModel

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def scan_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wizard")
    scan, truth = synthetic_scan(n_points=30_000, background_points=3000, seed=8)
    save_ply(scan, folder / "hand.ply")
    save_landmarks(landmarks_from_truth(truth), folder / "landmarks.json")
    return folder


def test_wizard_calibrates_a_scan(qtbot, scan_files, tmp_path):
    from handmocap.app.gui.calibration_wizard import open_calibration_wizard

    wizard = open_calibration_wizard(None)
    qtbot.addWidget(wizard)
    pages = wizard.pages
    pages["scan"].path_edit.setText(str(scan_files / "hand.ply"))
    wizard.next()
    assert wizard.currentPage() is pages["clean"]
    pages["clean"].slider.setValue(80)
    assert "removed" in pages["clean"].counts.text()
    wizard.next()
    assert wizard.currentPage() is pages["landmarks"]
    landmarks = pages["landmarks"]
    assert not landmarks.isComplete()
    landmarks.pick_point(0)                                    # a click places the current landmark...
    assert wizard.state.picked_count() == 1 and landmarks.current_name() == "thumb_ip"
    landmarks.undo()                                           # ...and undo takes it back
    assert wizard.state.picked_count() == 0
    landmarks.load(scan_files / "landmarks.json")
    assert landmarks.isComplete() and wizard.state.picked_count() == 20
    landmarks.save(tmp_path / "copy.json")
    assert (tmp_path / "copy.json").exists()

    wizard.next()
    assert wizard.currentPage() is pages["align"]
    qtbot.waitUntil(lambda: pages["align"].done, timeout=120_000)
    assert wizard.state.alignment.landmark_rms_mm[-1] < 5.0
    wizard.next()
    fit = pages["fit"]
    fit.runner.cancel()                                         # cancel keeps everything; run it again
    qtbot.waitUntil(lambda: not fit.runner.is_busy(), timeout=120_000)
    if not fit.done:
        assert "cancelled" in fit.status.text()
        fit.start()
    qtbot.waitUntil(lambda: fit.done, timeout=180_000)
    assert len(fit.scene.surface_points()) == len(wizard.state.template.vertices)
    wizard.next()
    review = pages["review"]
    assert review.table.rowCount() == 20
    assert float(review.table.item(0, 1).text()) < 2.0
    assert "scan to model" in review.statistics.text()
    wizard.show()
    wizard.grab().save(str(tmp_path / "review.png"))
    wizard.next()
    save = pages["save"]
    save.model_edit.setText(str(tmp_path / "subject.npz"))
    save.gltf_edit.setText(str(tmp_path / "subject.glb"))
    assert save.save()
    model = HandModel.load(tmp_path / "subject.npz")
    assert (tmp_path / "subject.glb").exists()
    assert np.isfinite(model.skeleton.rest_positions).all()
    wizard.close()
    release(wizard)


def test_wizard_shows_bad_scan_and_keeps_landmarks_after_a_failed_alignment(qtbot, scan_files, tmp_path):
    from handmocap.app.gui.calibration_wizard import open_calibration_wizard

    wizard = open_calibration_wizard(None)
    qtbot.addWidget(wizard)
    pages = wizard.pages
    (tmp_path / "bad.ply").write_text("ply\nformat ascii 1.0\nend_header\n")
    pages["scan"].path_edit.setText(str(tmp_path / "bad.ply"))
    wizard.next()
    assert wizard.currentPage() is pages["scan"] and "vertex" in pages["scan"].error.text()
    pages["scan"].path_edit.setText(str(scan_files / "hand.ply"))
    wizard.next()
    wizard.next()
    pages["landmarks"].load(scan_files / "landmarks.json")
    state = wizard.state
    landmarks = state.landmarks
    landmarks["index_tip"], landmarks["ring_tip"] = landmarks["ring_tip"], landmarks["index_tip"]
    wizard.next()
    qtbot.waitUntil(lambda: not pages["align"].runner.is_busy(), timeout=60_000)
    assert not pages["align"].done and "swapped" in pages["align"].status.text()
    wizard.back()
    assert wizard.currentPage() is pages["landmarks"] and state.picked_count() == 20
    wizard.close()
    release(wizard)


def test_a_scan_without_colours_skips_the_clean_page(qtbot, tmp_path):
    from handmocap.app.gui.calibration_wizard import open_calibration_wizard
    from handmocap.core.calibration.scan import Scan

    scan, _ = synthetic_scan(n_points=8000, background_points=0, outlier_share=0.0, seed=1)
    save_ply(Scan(scan.points, scan.normals), tmp_path / "grey.ply")
    wizard = open_calibration_wizard(None)
    qtbot.addWidget(wizard)
    wizard.pages["scan"].template_combo.setCurrentIndex(1)          # the shipped left hand
    wizard.pages["scan"].path_edit.setText(str(tmp_path / "grey.ply"))
    wizard.next()
    assert wizard.currentPage() is wizard.pages["landmarks"]
    assert wizard.state.template.side == "left" and len(wizard.state.scan) > 7000
    wizard.back()
    assert wizard.currentPage() is wizard.pages["scan"]
    wizard.close()
    release(wizard)
