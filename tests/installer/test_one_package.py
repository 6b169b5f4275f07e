"""One import package: every module imports the project as ``handmocap``; the wheel's top level holds only
``handmocap`` (and its dist-info) and works from a fresh environment without the sources."""

import ast
import re
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("app", "core", "widgets", "resources")


def readme_api_example() -> str:
    """The Python script of the README's "Python API" section."""
    section = (ROOT / "README.md").read_text(encoding="utf-8").split("## Python API", 1)[1]
    return re.search(r"```python\n(.*?)```", section, flags=re.DOTALL).group(1)


def _python_files() -> list[Path]:
    files = [ROOT / "__init__.py"]
    for folder in (*FOLDERS, "tests", "installer"):
        files += [path for path in (ROOT / folder).rglob("*.py") if "__pycache__" not in path.parts]
    return files


def test_every_module_imports_the_project_as_handmocap():
    bare = []
    for path in _python_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([alias.name for alias in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
            bare += [f"{path.relative_to(ROOT)}:{node.lineno}: {name}" for name in names
                     if name.split(".")[0] in FOLDERS]
    assert bare == []


def test_handmocap_is_the_repository():
    import handmocap
    import handmocap.core.model

    assert isinstance(handmocap.__version__, str) and handmocap.__version__ != "0+unknown"
    assert Path(handmocap.core.model.__file__).resolve() == ROOT / "core" / "model" / "__init__.py"
    assert handmocap.core.model.TEMPLATE_PATH.is_file()


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(ROOT)],
                           capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr
    (path,) = out.glob("handmocap-*.whl")
    return path


def test_the_wheel_holds_only_handmocap(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    tops = {name.split("/")[0] for name in names}
    assert {top for top in tops if not top.endswith(".dist-info")} == {"handmocap"}
    for needed in ("handmocap/__init__.py", "handmocap/core/ik/kernel.py", "handmocap/app/cli/main.py",
                   "handmocap/widgets/viewport.py", "handmocap/resources/template/right_hand.npz",
                   "handmocap/resources/layouts/dense.json", "handmocap/resources/icons/handmocap.svg"):
        assert needed in names
    assert not any("screenshots" in name or "__pycache__" in name or name.startswith("handmocap/tests")
                   for name in names)
    entry_points = next(name for name in names if name.endswith("entry_points.txt"))
    assert "handmocap = handmocap.app.cli.main:main" in zipfile.ZipFile(wheel).read(entry_points).decode()


def test_the_wheel_runs_without_the_sources(wheel, tmp_path):
    """A fresh environment holding only the wheel (its dependencies are lent by this one's site-packages, whose
    own .pth files, the development install's among them, are not read) imports handmocap from the wheel."""
    environment = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(environment)
    python = environment / "bin" / "python"
    site = next((environment / "lib").glob("python3*/site-packages"))
    lent = next(Path(path) for path in sys.path if path.endswith("site-packages") and Path(path).is_dir())
    (site / "lent_dependencies.pth").write_text(f"{lent}\n")
    installed = subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
                               capture_output=True, text=True, timeout=300)
    assert installed.returncode == 0, installed.stderr
    code = ("import handmocap, handmocap.core.model as model; from handmocap.core.io import load_take; "
            "print(handmocap.__version__, handmocap.__file__, model.TEMPLATE_PATH.is_file())")
    shown = subprocess.run([str(python), "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0, shown.stderr
    version, where, template = shown.stdout.split()
    assert where.startswith(str(site)) and template == "True" and version != "0+unknown"
    example = subprocess.run([str(python), "-c", readme_api_example()], cwd=tmp_path, capture_output=True,
                             text=True, timeout=900)
    assert example.returncode == 0, example.stderr
    assert (tmp_path / "take.bvh").is_file() and (tmp_path / "take.c3d").is_file()


def test_the_readme_api_example_runs_as_written(tmp_path):
    completed = subprocess.run([sys.executable, "-c", readme_api_example()], cwd=tmp_path, capture_output=True,
                               text=True, timeout=600)
    assert completed.returncode == 0, completed.stderr
    lines = completed.stdout.splitlines()
    assert lines[0].startswith("Hand Mocap Studio ") and "labelled" in lines[1]
    share = float(re.search(r"labelled ([0-9.]+)%", lines[1]).group(1))
    assert share > 80
    assert any(line.startswith("right hand on ") for line in lines)
    correct = float(re.search(r"([0-9.]+) % correct", lines[-1]).group(1))
    assert correct > 90
    assert (tmp_path / "take.bvh").stat().st_size > 1000 and (tmp_path / "take.c3d").stat().st_size > 1000


def test_resources_are_found_in_a_frozen_bundles_multiplexed_folder(tmp_path):
    """PyInstaller's bundle gives handmocap.resources as a MultiplexedPath (joinpath takes one name in 3.11)."""
    from importlib.resources.readers import MultiplexedPath

    from handmocap.core.io.resources import joined_path

    (tmp_path / "template").mkdir()
    (tmp_path / "template" / "right_hand.npz").write_bytes(b"")
    found = joined_path(MultiplexedPath(tmp_path), ("template", "right_hand.npz"))
    assert found == tmp_path / "template" / "right_hand.npz" and found.is_file()
