# Sourced by the scripts that write docs/: what every generated report shares.
# Needs $root (the repository) and, where the script reads the shared scenes, $shared.

# repo_relative FILE...: generated reports name commands and files as a reader can use them from
# the repository, never as absolute paths of the machine they ran on: the repository's root goes,
# the shared scenes become ../shared (or $LIGHTFARM_SHARED where they were elsewhere).
repo_relative() {
  local args=(-e "s#$root/##g")
  if [ -n "${shared:-}" ]; then
    local shared_as='../shared'
    [ "$shared" -ef "$root/../shared" ] || shared_as='$LIGHTFARM_SHARED'
    args+=(-e "s#$shared/#$shared_as/#g" -e "s#$shared\\b#$shared_as#g")
  fi
  sed -i "${args[@]}" "$@"
}

# report_begin: builds lightfarm (its output hidden) and sets $build, $lf (the binary), $py
# (Debian's Python, which has OpenImageIO's module) and $work (a directory removed on exit).
report_begin() {
  build=${LIGHTFARM_BUILD:-$root/build}
  bash "$root/scripts/build.sh" "$build" >/dev/null
  lf="$build/lightfarm"
  py=/usr/bin/python3
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
}
