#!/usr/bin/env bash
# Installs what Hand Mocap Studio needs: system libraries for Qt/VTK and Xvfb (Debian/Ubuntu, when
# missing), then the project and its Python dependencies into .venv/ in the project root.
# Usage: bash installer/setup.sh [--test]   (--test also installs the test tools)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

system_packages=(xvfb xauth libgl1 libegl1 libglx-mesa0 libgl1-mesa-dri libxkbcommon0 libxkbcommon-x11-0
  libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0 libxcb-render-util0
  libxcb-shape0 libxcb-xinerama0 libxcb-xkb1 libxrender1 libxt6 libxi6 libfontconfig1 libdbus-1-3)
if command -v dpkg-query >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1; then
  missing=()
  for package in "${system_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    echo "installing system packages: ${missing[*]}"
    sudo_cmd=""
    [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
    $sudo_cmd apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
fi

python_bin="${PYTHON:-}"
if [ -z "$python_bin" ]; then
  for candidate in python3.11 python3; do
    if command -v "$candidate" >/dev/null 2>&1 && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      python_bin="$candidate"; break
    fi
  done
fi
if [ -z "$python_bin" ]; then
  echo "Hand Mocap Studio needs Python 3.11 (set PYTHON=/path/to/python3.11)" >&2
  exit 1
fi

[ -x .venv/bin/python ] || "$python_bin" -m venv .venv

# The one import package handmocap of the development install: a real folder of links to the repository's
# __init__.py and folders. The editable install puts only .venv/src on sys.path (pyproject.toml: dev-mode-dirs),
# so what Python, mypy, import-linter, pytest, PyInstaller and numba see is the same handmocap as the wheel's.
mkdir -p .venv/src/handmocap
for entry in __init__.py app core widgets resources; do
  ln -sfn "../../../$entry" ".venv/src/handmocap/$entry"
done

# Install only when what decides the installation changed (the project file, this script, the extras
# asked for); the source itself is installed in editable mode and needs no reinstall.
extras=""
[ "${1:-}" = "--test" ] && extras="[test]"
install_stamp=".venv/.handmocap-install"
install_key="$(cat pyproject.toml installer/setup.sh | sha256sum | cut -c1-32)$extras"
installed_key="$(cat "$install_stamp" 2>/dev/null || true)"
# An installation with the test tools also serves the plain application.
if [ "$installed_key" != "$install_key" ] && [ "$installed_key" != "${install_key}[test]" ]; then
  echo "installing Hand Mocap Studio and its Python packages into .venv/"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".$extras"
  # numba's cache of a kernel names the kernel's module: a cache made under another package layout would load
  # and then fail to import that module, so a new installation compiles every kernel afresh
  find core -path '*/__pycache__/*' \( -name '*.nbi' -o -name '*.nbc' \) -delete
  rm -f .venv/.handmocap-kernels
  echo "$install_key" > "$install_stamp"
fi

# Compile the numba kernels now (cached next to the sources), not at an operator's first click; again
# whenever the computing code changed (numba recompiles a kernel whose source file changed).
kernels_stamp=".venv/.handmocap-kernels"
kernels_key="$(find core -name '*.py' -print0 | sort -z | xargs -0 cat | sha256sum | cut -c1-32)"
if [ "$(cat "$kernels_stamp" 2>/dev/null || true)" != "$kernels_key" ]; then
  echo "compiling the numba kernels (once after installing or updating; about a minute)"
  .venv/bin/python -m handmocap.core.workflows.warm_up
  echo "$kernels_key" > "$kernels_stamp"
fi
# Python's byte code of our own sources, written now: an environment with PYTHONDONTWRITEBYTECODE set (common in
# containers) would otherwise compile every module again at each start (about 1 s of the window's start-up).
.venv/bin/python -m compileall -q "$PWD"/.venv/src/handmocap/{__init__.py,app,core,widgets}
