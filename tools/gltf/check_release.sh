#!/usr/bin/env bash
# Exports every mesh entry of a release and checks each LOD with the Khronos glTF-Validator
# (default) or by importing it into Blender (`blender`: Blender's own glTF importer, headless;
# see blender_import.py for what is compared).
# Usage: tools/gltf/check_release.sh REGOLITH_BIN DB RELEASE [validator|blender]
#   (validator: npm install --prefix tools/gltf; blender: apt-get install blender)
set -euo pipefail
bin=$1 db=$2 release=$3 tool=${4:-validator}
here=$(cd "$(dirname "$0")" && pwd)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
meshes=$("$bin" --json inspect "$db" "$release" | node -e '
  const d = JSON.parse(require("fs").readFileSync(0, "utf8"));
  for (const e of d.manifest.entries) if (e.kind === "mesh") console.log(e.name);')
[ -n "$meshes" ] || { echo "no mesh entries in $release" >&2; exit 1; }
files=()
for m in $meshes; do
  dir="$out/${m//\//_}"
  "$bin" export "$db" "$release" "$m" --to "$dir" >/dev/null
  files+=("$dir"/*.glb)
done
case "$tool" in
  validator) node "$here/validate.mjs" "${files[@]}" ;;
  blender) blender --background --factory-startup --python "$here/blender_import.py" -- "${files[@]}" 2>&1 |
    grep -E '^(blender |[0-9]+ of |Error|Traceback)' ; exit "${PIPESTATUS[0]}" ;;
  *) echo "unknown check '$tool', expected validator or blender" >&2; exit 2 ;;
esac
