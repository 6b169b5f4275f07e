#!/usr/bin/env bash
# Installs Hand Mocap Studio for the current user (no root): the bundle under ~/.local/opt/handmocap, the
# `handmocap` launcher in ~/.local/bin, the menu entry, the icons and the file types (.c3d takes and
# session manifests). Run from the unpacked archive: bash install.sh   (again to update)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
data="${XDG_DATA_HOME:-$HOME/.local/share}"
opt="$HOME/.local/opt/handmocap"
bin="$HOME/.local/bin"

[ -x "$here/handmocap/handmocap" ] || { echo "install.sh: run it from the unpacked archive (handmocap/ is missing)" >&2; exit 1; }

echo "installing the application into $opt"
mkdir -p "$HOME/.local/opt" "$bin"
rm -rf "$opt.new"
cp -a "$here/handmocap" "$opt.new"
rm -rf "$opt"
mv "$opt.new" "$opt"
cp "$here/uninstall.sh" "$opt/uninstall.sh"

cat > "$bin/handmocap" <<LAUNCHER
#!/bin/sh
exec "$opt/handmocap" "\$@"
LAUNCHER
chmod +x "$bin/handmocap"

mkdir -p "$data/applications"
sed -e "s|^Exec=handmocap |Exec=$bin/handmocap |" -e "s|^TryExec=handmocap\$|TryExec=$bin/handmocap|" \
  "$here/handmocap.desktop" > "$data/applications/handmocap.desktop"
for png in "$opt"/_internal/handmocap/resources/icons/handmocap-*.png; do
  size="$(basename "$png" .png)"; size="${size#handmocap-}"
  mkdir -p "$data/icons/hicolor/${size}x${size}/apps"
  cp "$png" "$data/icons/hicolor/${size}x${size}/apps/handmocap.png"
done
mkdir -p "$data/icons/hicolor/scalable/apps"
cp "$opt/_internal/handmocap/resources/icons/handmocap.svg" "$data/icons/hicolor/scalable/apps/handmocap.svg"

mkdir -p "$data/mime/packages"
cp "$here/handmocap-mime.xml" "$data/mime/packages/handmocap.xml"
command -v update-mime-database >/dev/null 2>&1 && update-mime-database "$data/mime" || true
command -v update-desktop-database >/dev/null 2>&1 && update-desktop-database -q "$data/applications" || true
command -v gtk-update-icon-cache >/dev/null 2>&1 && gtk-update-icon-cache -q -t "$data/icons/hicolor" || true
if command -v xdg-mime >/dev/null 2>&1; then
  xdg-mime default handmocap.desktop application/x-c3d application/x-handmocap-session || true
fi

echo "Hand Mocap Studio is installed: in the application menu (Science, Graphics) or 'handmocap' in a terminal"
case ":$PATH:" in *":$bin:"*) ;; *) echo "note: $bin is not on your PATH; the menu entry works regardless" ;; esac
echo "to remove it: bash $opt/uninstall.sh"
