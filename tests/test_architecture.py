"""Dependency direction: every core module imports without Qt, VTK or pyvista; the import contracts hold."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_core_imports_without_gui_modules():
    modules = sorted(".".join(("handmocap", *path.relative_to(ROOT).with_suffix("").parts))
                     for path in (ROOT / "core").rglob("*.py") if path.name != "__init__.py")
    code = (f"import sys, importlib; [importlib.import_module(m) for m in {modules!r}];"
            "bad = [m for m in ('PySide6', 'pyvista', 'pyvistaqt', 'vtk', 'pyqtgraph', 'handmocap.widgets',"
            " 'handmocap.app')"
            " if m in sys.modules]; print(bad); sys.exit(1 if bad else 0)")
    completed = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stdout + completed.stderr


def test_import_contracts_hold():
    linter = Path(sys.executable).with_name("lint-imports")
    completed = subprocess.run([str(linter)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stdout
