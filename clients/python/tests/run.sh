#!/usr/bin/env bash
# The Python client's tests, as a user installs it: a fresh venv that sees Debian's grpcio,
# numpy and OpenImageIO, `pip install ./clients/python` (offline: the in-tree build backend
# needs nothing from PyPI), then pytest against a real coordinator and worker from BUILD_DIR.
# usage: run.sh BUILD_DIR [pytest args]
set -euo pipefail
build=$(cd "$1" && pwd)
shift
here=$(cd "$(dirname "$0")/.." && pwd)
venv="$build/python-client-venv"
rm -rf "$venv"
/usr/bin/python3 -m venv --system-site-packages "$venv"
"$venv/bin/pip" install --quiet --no-index "$here"
# Run from outside the source tree so `import lightfarm` is the installed package.
cd "$build"
LIGHTFARM_BUILD_DIR="$build" LIGHTFARM_SOURCE_DIR="$(cd "$here/../.." && pwd)" \
  "$venv/bin/python" -m pytest -p no:cacheprovider -q "$here/tests" "$@"
