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


GUI_MODULE_LINES = 700          # the most lines a module of app/gui may have
GUI_OVER_THE_LIMIT = {          # older modules already longer: they may shrink, not grow (their size once typed
    "main_window.py": 838,      # for mypy: the narrowing of optional values added 7 and 11 lines)
    "calibration_wizard.py": 761,
}
REVIEW_PART_LINES = 300         # the review controller's parts (app/gui/review) and the solve controller stay small


def test_gui_modules_stay_small():
    gui = ROOT / "app" / "gui"
    sizes = {path.relative_to(gui).as_posix(): len(path.read_text(encoding="utf-8").splitlines())
             for path in gui.rglob("*.py")}
    too_long = {name: lines for name, lines in sizes.items()
                if lines > GUI_OVER_THE_LIMIT.get(name, GUI_MODULE_LINES)}
    assert not too_long, too_long
    parts = {name: lines for name, lines in sizes.items()
             if (name.startswith("review/") or name == "solve_controller.py") and lines > REVIEW_PART_LINES}
    assert not parts, parts
    assert not (gui / "review_controller.py").exists()
