#!/usr/bin/env bash
# Installs everything, then starts Hand Mocap Studio (on the demo session when no file is given).
# Usage: bash installer/run.sh [FILE ...]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/installer/setup.sh"
if [ -z "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ] && command -v xvfb-run >/dev/null 2>&1; then
  echo "no display found: starting on a virtual screen (xvfb-run)"
  exec xvfb-run -a -s "-screen 0 1600x1000x24" "$root/.venv/bin/handmocap" gui "$@"
fi
exec "$root/.venv/bin/handmocap" gui "$@"
