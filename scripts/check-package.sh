#!/usr/bin/env bash
# The Debian package (`cpack -G DEB`, CMakeLists.txt) holds what a render needs: built from the
# build directory into a temporary one, unpacked, its lightfarm renders the example scene with
# the image module beside it, and its dependencies name the runtime libraries. ctest runs it.
# Usage: scripts/check-package.sh BUILD_DIR
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "$1" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$build" && cpack -G DEB -B "$tmp/pkg" >/dev/null)
deb=$(ls "$tmp"/pkg/lightfarm_*.deb)
dpkg -x "$deb" "$tmp/root"
for program in lightfarm lightfarm-coordinator lightfarm-worker; do
  [ -x "$tmp/root/usr/local/bin/$program" ] || { echo "package lacks bin/$program" >&2; exit 1; }
done
depends=$(dpkg-deb -f "$deb" Depends)
for lib in libembree3 libgrpc++ libopenimageio libtbb libsqlite3; do
  case "$depends" in *"$lib"*) ;; *) echo "package Depends lacks $lib: $depends" >&2; exit 1 ;; esac
done
"$tmp/root/usr/local/bin/lightfarm" render "$root/scenes/cornell-box/scene.pbrt" --resolution 16x16 \
  --lights 200 --out "$tmp/out.exr" >/dev/null
[ -s "$tmp/out.exr" ] && [ -s "$tmp/out.png" ] || { echo "the packaged lightfarm wrote no image" >&2; exit 1; }
echo "package OK: $(basename "$deb")"
