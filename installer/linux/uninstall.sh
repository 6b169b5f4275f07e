#!/usr/bin/env bash
# Removes what install.sh put under ~/.local (the application, launcher, menu entry, icons, file types).
# Sessions, takes and the user cache (~/.cache/handmocap) are left alone.
set -euo pipefail
data="${XDG_DATA_HOME:-$HOME/.local/share}"
opt="$HOME/.local/opt/handmocap"
launcher="$HOME/.local/bin/handmocap"

if [ -f "$launcher" ] && grep -q "$opt/handmocap" "$launcher"; then rm -f "$launcher"; fi
rm -f "$data/applications/handmocap.desktop"
rm -f "$data"/icons/hicolor/*/apps/handmocap.png "$data/icons/hicolor/scalable/apps/handmocap.svg"
rm -f "$data/mime/packages/handmocap.xml"
defaults="${XDG_CONFIG_HOME:-$HOME/.config}/mimeapps.list"   # the associations install.sh made with xdg-mime
[ -f "$defaults" ] && sed -i '/^application\/x-\(c3d\|handmocap-session\)=handmocap\.desktop;\?$/d' "$defaults"
command -v update-mime-database >/dev/null 2>&1 && [ -d "$data/mime" ] && update-mime-database "$data/mime" || true
command -v update-desktop-database >/dev/null 2>&1 && update-desktop-database -q "$data/applications" || true
rm -rf "$opt"
echo "Hand Mocap Studio is removed (your sessions and takes are untouched)"
