"""The installer's files are well-formed: the PyInstaller spec, the .desktop entry, the MIME types (whose
magic matches the C3D files we write and the vendors' files, and the session manifests we write), the shell
scripts; and install.sh/uninstall.sh put a bundle under ~/.local and take it away again."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path
from xml.etree import ElementTree

import pytest

from handmocap.core.evaluation.data import VENDOR_C3D

ROOT = Path(__file__).resolve().parents[2]
INSTALLER = ROOT / "installer"
LINUX = INSTALLER / "linux"
MIME_NS = "{http://www.freedesktop.org/standards/shared-mime-info}"


def desktop_entry() -> dict[str, str]:
    lines = (LINUX / "handmocap.desktop").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "[Desktop Entry]"
    return dict(line.split("=", 1) for line in lines[1:] if line and not line.startswith("#"))


def mime_types() -> dict[str, ElementTree.Element]:
    root = ElementTree.parse(LINUX / "handmocap-mime.xml").getroot()
    assert root.tag == f"{MIME_NS}mime-info"
    return {element.get("type"): element for element in root.findall(f"{MIME_NS}mime-type")}


def test_desktop_entry_opens_takes_and_sessions_with_the_icon():
    entry = desktop_entry()
    assert entry["Type"] == "Application"
    assert entry["Exec"].split()[0] == "handmocap" and entry["Exec"].endswith("%F")
    assert entry["Icon"] == "handmocap"
    assert {"Science", "Graphics"} <= set(entry["Categories"].rstrip(";").split(";"))
    assert set(entry["MimeType"].rstrip(";").split(";")) == set(mime_types())


@pytest.mark.skipif(shutil.which("desktop-file-validate") is None, reason="desktop-file-validate not installed")
def test_desktop_entry_passes_desktop_file_validate():
    result = subprocess.run(["desktop-file-validate", str(LINUX / "handmocap.desktop")], capture_output=True,
                            text=True)
    assert result.returncode == 0 and "error" not in result.stdout, result.stdout


def big16_magic(element: ElementTree.Element) -> bytes:
    match = element.find(f"{MIME_NS}magic/{MIME_NS}match")
    assert match is not None and match.get("type") == "big16" and match.get("offset") == "0"
    return int(match.get("value"), 16).to_bytes(2, "big")


def test_c3d_magic_matches_the_files_we_write_and_the_vendors(tmp_path):
    from handmocap.core.io import save_take
    from handmocap.core.simulate import simulate_take

    c3d = mime_types()["application/x-c3d"]
    assert [glob.get("pattern") for glob in c3d.findall(f"{MIME_NS}glob")] == ["*.c3d"]
    magic = big16_magic(c3d)
    save_take(simulate_take(layout="grasp-4", n_frames=5, seed=0).take, tmp_path / "take.c3d")
    files = [tmp_path / "take.c3d", *sorted(VENDOR_C3D.glob("*.c3d"))]
    assert [path.name for path in files if path.read_bytes()[:2] != magic] == []


def test_session_magic_is_in_the_manifests_we_write(tmp_path):
    from handmocap.core.session import Session
    from handmocap.core.session.session import MANIFEST_NAME

    session = mime_types()["application/x-handmocap-session"]
    assert [glob.get("pattern") for glob in session.findall(f"{MIME_NS}glob")] == [MANIFEST_NAME]
    match = session.find(f"{MIME_NS}magic/{MIME_NS}match")
    assert match is not None and match.get("type") == "string"
    first, last = (int(value) for value in match.get("offset").split(":"))
    Session.create(tmp_path / "session", name="x").close()
    manifest = (tmp_path / "session" / MANIFEST_NAME).read_bytes()
    assert match.get("value").encode() in manifest[first:last + len(match.get("value"))]


def test_spec_is_python_portable_and_ships_the_resources():
    text = (INSTALLER / "handmocap.spec").read_text(encoding="utf-8")
    compile(text, "handmocap.spec", "exec")
    assert re.findall(r"[\"'](/(?:usr|home|work|opt|tmp)\b[^\"']*)", text) == []
    assert "\\\\" not in text   # no Windows paths either: every path is joined with os.path.join
    for folder in ("template", "priors", "layouts", "icons"):
        assert f'"{folder}"' in text and (ROOT / "resources" / folder).is_dir()
    for unused in ("QtWebEngineCore", "Qt3DCore", "QtQuick", "QtQml", "QtMultimedia"):
        assert f'"{unused}"' in text
    assert '"handmocap.core": "py"' in text   # numba's cache needs the kernels' source files in the bundle


def test_shell_scripts_parse():
    for script in [*INSTALLER.glob("*.sh"), *LINUX.glob("*.sh")]:
        result = subprocess.run(["bash", "-n", str(script)], capture_output=True, text=True)
        assert result.returncode == 0, f"{script.name}: {result.stderr}"


def test_install_and_uninstall_under_a_home_folder(tmp_path):
    unpacked = tmp_path / "handmocap-0-linux-x86_64"
    icons = unpacked / "handmocap" / "_internal" / "handmocap" / "resources" / "icons"
    shutil.copytree(ROOT / "resources" / "icons", icons)
    executable = unpacked / "handmocap" / "handmocap"
    executable.write_text('#!/bin/sh\necho "handmocap $*"\n')
    executable.chmod(0o755)
    for name in ("install.sh", "uninstall.sh", "handmocap.desktop", "handmocap-mime.xml"):
        shutil.copy(LINUX / name, unpacked / name)
    home = tmp_path / "home"
    home.mkdir()
    environment = {"HOME": str(home), "PATH": os.environ["PATH"]}

    subprocess.run(["bash", str(unpacked / "install.sh")], env=environment, check=True, capture_output=True)
    launcher = home / ".local" / "bin" / "handmocap"
    answer = subprocess.run([str(launcher), "--version"], capture_output=True, text=True).stdout
    assert answer == "handmocap --version\n"
    desktop = (home / ".local/share/applications/handmocap.desktop").read_text()
    assert f"Exec={launcher} gui %F" in desktop
    sizes = sorted(int(path.parent.parent.name.split("x")[0])
                   for path in (home / ".local/share/icons/hicolor").glob("*x*/apps/handmocap.png"))
    assert sizes == [16, 32, 48, 64, 128, 256, 512]
    assert (home / ".local/share/mime/packages/handmocap.xml").exists()
    if shutil.which("update-mime-database"):
        types = (home / ".local/share/mime/types").read_text().split()
        assert {"application/x-c3d", "application/x-handmocap-session"} <= set(types)

    subprocess.run(["bash", str(home / ".local/opt/handmocap/uninstall.sh")], env=environment, check=True,
                   capture_output=True)
    left = sorted(str(path.relative_to(home)) for path in home.rglob("*") if path.is_file())
    assert [path for path in left if "handmocap" in path] == []
    assert not any(path.startswith(".local/opt") for path in left)
    defaults = home / ".config" / "mimeapps.list"
    assert not defaults.exists() or "handmocap" not in defaults.read_text()


def test_a_session_folder_or_its_manifest_opens_the_session(tmp_path):
    """What the file manager hands over ("Open with" on session.json or the folder) opens the session."""
    from handmocap.app.gui.launch import session_folder
    from handmocap.core.session import Session

    Session.create(tmp_path / "session", name="x").close()
    take = tmp_path / "take.c3d"
    take.write_bytes(b"")
    assert session_folder(tmp_path / "session") == tmp_path / "session"
    assert session_folder(tmp_path / "session" / "session.json") == tmp_path / "session"
    assert session_folder(take) is None and session_folder(tmp_path) is None
