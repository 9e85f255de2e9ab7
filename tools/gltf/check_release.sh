#!/usr/bin/env bash
# Exports every mesh entry of a release and runs the Khronos glTF-Validator on each LOD.
# Usage: tools/gltf/check_release.sh REGOLITH_BIN DB RELEASE   (validator: npm install --prefix tools/gltf)
set -euo pipefail
bin=$1 db=$2 release=$3
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
node "$here/validate.mjs" "${files[@]}"
