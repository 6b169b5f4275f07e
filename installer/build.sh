#!/usr/bin/env bash
# Builds what a lab hands to an operator:
#   dist/handmocap/                                 the frozen one-folder application (PyInstaller)
#   dist/handmocap-<version>-<os>-<arch>.tar.gz     that folder with install.sh/uninstall.sh (Linux)
#   dist/handmocap-<version>-py3-none-any.whl       the wheel (pip install into any Python 3.11 venv)
# The bundle is started once on a virtual screen so that its numba kernels are compiled into the
# bundle (<bundle>/_internal/handmocap/core/**/__pycache__) before it is packed.
# Usage: bash installer/build.sh        (about 10-20 minutes on 2 cores; build/ and dist/ are git-ignored)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
start=$SECONDS

bash installer/setup.sh
if ! .venv/bin/python -c "import PyInstaller, build" 2>/dev/null; then
  echo "installing the build tools (the [build] extra) into .venv/"
  .venv/bin/python -m pip install -q -e ".[build]"
fi
version="$(.venv/bin/python -c 'import importlib.metadata as m; print(m.version("handmocap"))')"

echo "building the wheel"
rm -rf dist/handmocap-*.whl
.venv/bin/python -m pip wheel -q --no-deps -w dist .

echo "freezing the application (PyInstaller)"
.venv/bin/pyinstaller --noconfirm --log-level WARN --distpath dist --workpath build/pyinstaller \
  installer/handmocap.spec
bundle="dist/handmocap"
.venv/bin/python -m compileall -q "$bundle/_internal/handmocap/core"    # byte code of the shipped sources

echo "first start of the bundle: compiling its numba kernels into the bundle"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
run_screen=()
if [ -z "${DISPLAY:-}" ]; then
  if command -v xvfb-run >/dev/null 2>&1; then run_screen=(xvfb-run -a -s "-screen 0 1600x1000x24"); else export QT_QPA_PLATFORM=offscreen; fi
fi
XDG_CACHE_HOME="$scratch/cache" HANDMOCAP_DATA="$scratch/data" HANDMOCAP_DEMO_SESSION="$scratch/demo" \
  "${run_screen[@]}" "$bundle/handmocap" gui --screenshot "$scratch/first-start.png" >/dev/null
[ -s "$scratch/first-start.png" ] || { echo "build.sh: the bundle did not start" >&2; exit 1; }

if [ "$(uname -s)" = "Linux" ]; then
  name="handmocap-$version-linux-$(uname -m)"
  echo "packing dist/$name.tar.gz"
  stage="build/package/$name"
  rm -rf build/package && mkdir -p "$stage"
  cp -al "$bundle" "$stage/handmocap"        # hard links: no second copy of the bundle
  cp installer/linux/install.sh installer/linux/uninstall.sh installer/linux/handmocap.desktop "$stage/"
  cp installer/linux/handmocap-mime.xml "$stage/"
  tar -C build/package -czf "dist/$name.tar.gz" "$name"
  rm -rf build/package
fi

echo "built in $((SECONDS - start)) s: $(du -sh "$bundle" | cut -f1) bundle ($bundle)"
ls -l dist/*.tar.gz dist/*.whl 2>/dev/null || true
