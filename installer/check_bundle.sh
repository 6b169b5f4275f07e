#!/usr/bin/env bash
# Smoke test of what build.sh makes, run as an operator would, from a folder outside the source tree:
#   the frozen bundle (dist/handmocap/handmocap) and the wheel installed into a new virtual environment.
# Each answers --version and the --help of every subcommand, simulates a take, labels it, reads a vendor
# C3D (shared/data/c3d when present, else the simulated take) with info, processes a folder of two takes
# with batch (Dask worker processes), and starts the GUI on a virtual screen on the demo session, saves a
# screenshot and exits. Screenshots go to dist/check/.
# Slow (a full build, then a pip install of every dependency): not part of the test run.
# Usage: bash installer/check_bundle.sh [--no-build]   (--no-build: check the artefacts already in dist/)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
[ "${1:-}" = "--no-build" ] || bash installer/build.sh
version="$(.venv/bin/python -c 'import importlib.metadata as m; print(m.version("handmocap"))')"
wheel="$(ls dist/handmocap-"$version"-*.whl)"
[ -x dist/handmocap/handmocap ] || { echo "check_bundle.sh: dist/handmocap/handmocap is missing" >&2; exit 1; }

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p dist/check
vendor="$(ls "$root"/../shared/data/c3d/*.c3d 2>/dev/null | head -1 || true)"
screen=()
if [ -z "${DISPLAY:-}" ]; then screen=(xvfb-run -a -s "-screen 0 1600x1000x24"); fi
# every command line of the CLI ("gui", "bench ik", ...), read from its parser
commands_py='
import argparse
from handmocap.app.cli.main import build_parser
def walk(parser, prefix):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                print(" ".join(prefix + [name]))
                walk(sub, prefix + [name])
walk(build_parser(), [])
'

check() {  # check NAME EXECUTABLE PYTHON: the executable's CLI and GUI, run from $work/NAME
  local name="$1" exe="$2" python="$3"
  local here="$work/$name"
  mkdir -p "$here"
  cd "$here"
  export XDG_CACHE_HOME="$here/cache" HANDMOCAP_DATA="$here/data" HANDMOCAP_DEMO_SESSION="$here/demo"
  echo "== $name: $exe"
  "$exe" --version | grep -qx "handmocap $version" || { echo "$name: --version is not handmocap $version" >&2; return 1; }
  local count=0
  while read -r line; do
    # shellcheck disable=SC2086
    "$exe" $line --help >/dev/null || { echo "$name: 'handmocap $line --help' failed" >&2; return 1; }
    count=$((count + 1))
  done < <("$python" -c "$commands_py")
  [ "$count" -gt 20 ] || { echo "$name: only $count subcommands were listed from the parser" >&2; return 1; }
  echo "   --version and the --help of $count subcommands"
  "$exe" simulate --layout dense --frames 300 --seed 2 --noise 0.3 --unlabelled --out raw.c3d --truth truth.npz >/dev/null
  "$exe" label raw.c3d --layout dense --out labelled.c3d --report report.json --quiet >label.log
  [ -s labelled.c3d ] && [ -s report.json ] || { echo "$name: label wrote nothing" >&2; return 1; }
  "$exe" info "${vendor:-labelled.c3d}" --json >info.json
  echo "   simulate, label, info ($(basename "${vendor:-labelled.c3d}")): $(head -c 120 info.json)…"
  mkdir takes && cp raw.c3d takes/a.c3d
  "$exe" simulate --layout dense --frames 200 --seed 3 --noise 0.3 --unlabelled --out takes/b.c3d --truth b.npz >/dev/null
  printf 'steps = ["label", "export"]\nlayout = "dense"\nhands = "right"\nexports = ["c3d"]\n' >pipeline.toml
  "$exe" batch takes --pipeline pipeline.toml --workers 2 >batch.log 2>&1 || { cat batch.log >&2; return 1; }
  grep -q "2 takes processed" batch.log || { cat batch.log >&2; return 1; }
  echo "   batch of 2 takes on 2 local Dask worker processes"
  local start=$SECONDS
  "${screen[@]}" "$exe" gui --screenshot gui.png >gui.log 2>&1 || { cat gui.log >&2; return 1; }
  [ "$(stat -c %s gui.png)" -gt 50000 ] || { echo "$name: the GUI screenshot is empty" >&2; return 1; }
  cp gui.png "$root/dist/check/$name-gui.png"
  echo "   GUI on the demo session: screenshot in $((SECONDS - start)) s (dist/check/$name-gui.png)"
  cd "$root"
}

check bundle "$root/dist/handmocap/handmocap" "$root/.venv/bin/python"

echo "== wheel: installing $(basename "$wheel") into a new virtual environment"
python_bin="${PYTHON:-python3.11}"
"$python_bin" -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q --upgrade pip
"$work/venv/bin/python" -m pip install -q "$wheel"
# one import package, and the resources come from it, not from the source tree
(cd "$work" && "$work/venv/bin/python" -c '
import sys
import handmocap
from handmocap.core.model import TEMPLATE_PATH
from handmocap.core.model.markers import LAYOUT_DIR
from handmocap.core.prior.pca_prior import DEFAULT_PRIOR_PATH
for path in (TEMPLATE_PATH, LAYOUT_DIR, DEFAULT_PRIOR_PATH):
    assert path.exists() and sys.prefix in str(path), path
print("   handmocap", handmocap.__version__, "resources found in", TEMPLATE_PATH.parents[1])
')
check wheel "$work/venv/bin/handmocap" "$work/venv/bin/python"
echo "check_bundle.sh: the bundle and the wheel work"
