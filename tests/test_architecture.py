"""Dependency direction: core runs without Qt, VTK or pyvista; widgets never import app."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_core_imports_without_gui_modules():
    code = ("import sys, core.model, core.ik, core.io, core.prior, core.simulate, core.evaluation.ik, core.layout,"
            " core.gaps, core.labelling, core.review, core.session, core.workflows, core.calibration.marker_placement,"
            " core.calibration.scan, core.calibration.pipeline, core.evaluation.calibration, core.model.gltf,"
            " core.calibration.cleaning, core.calibration.rigid, core.calibration.synthetic_scan;"
            "bad = [m for m in ('PySide6', 'pyvista', 'pyvistaqt', 'vtk', 'pyqtgraph', 'widgets', 'app')"
            " if m in sys.modules]; print(bad); sys.exit(1 if bad else 0)")
    completed = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stdout + completed.stderr


def test_import_contracts_hold():
    linter = Path(sys.executable).with_name("lint-imports")
    completed = subprocess.run([str(linter)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stdout
