#!/usr/bin/env bash
# `regolith validate` per view against OpenCV's detectors on the same views: the wall and CPU
# seconds of validating one entry, divided by its views, next to what OpenCV needs to detect
# (FAST, Harris, SIFT, MSER; one thread) on the two images a view compares (real frame a and
# the render, both the real frame's size), and their ratio. The validation renders, detects
# with all five detectors on both images (the real frames' once per release), matches and
# measures; the peer only detects, so the ratio says how far a view's whole work is from the
# detection alone that any implementation must do.
#
# Usage: tools/bench/validate.sh [CAMPAIGN [ENTRY]]
#   CAMPAIGN: a campaign folder (campaign.toml); default: mini seed 301 from the checked-in
#   Mitsuba renders (corpus/renders), made here. ENTRY: default laser/0.01 (mini's finest).
#   For the issue's headline run an estec campaign:
#     regolith corpus generate --preset estec --full --seed 11 --renderer model --out /tmp/e11
#     tools/bench/validate.sh /tmp/e11 laser/0.015
#
# Installs opencv-python-headless with pip when `import cv2` fails. Timing only: nothing here
# passes or fails a test.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
entry=${2:-laser/0.01}

source "$root/tools/bench/setup.sh"
echo "validating $entry ..." >&2
/usr/bin/time -f '%e %U %S %M' -o "$work/time" \
  "$bin" validate "$work/db" --entry "$entry" -q --json >"$work/validate.json" || true

# Frame a of every view: what the peer detects on (twice per view: real and render).
mapfile -t frames < <(python3 - "$campaign/campaign.toml" <<'EOF'
import os, sys, tomllib
path = sys.argv[1]
cfg = tomllib.load(open(path, "rb"))
for cap in cfg.get("capture", []):
    for side in ("left", "right"):
        frames = cap.get(side) or []
        if frames:
            print(os.path.join(os.path.dirname(path), frames[0]))
EOF
)
python3 "$root/tools/peers/bench_detectors_opencv.py" "${frames[@]}" --repeat 3 --json \
  >"$work/opencv.json"

python3 - "$work/time" "$work/validate.json" "$work/opencv.json" "$entry" <<'EOF'
import json, os, sys
wall, user, system, peak_kb = open(sys.argv[1]).read().split()
report = json.load(open(sys.argv[2]))
cv = json.load(open(sys.argv[3]))
entry = sys.argv[4]
views = len(cv["images"])
detect_ms = [sum(d["median_ms"] for d in img["detectors"] if "skipped" not in d)
             for img in cv["images"]]
per_view_cv = 2 * sum(detect_ms) / views / 1000.0
wall, cpu = float(wall), float(user) + float(system)
verdict = next((e["passed"] for e in report.get("entries", []) if e["entry"] == entry), None)
print(f"regolith validate --entry {entry} vs OpenCV detection (FAST, Harris, SIFT, MSER; 1 thread) "
      f"on {views} views; {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
print(f"  regolith: {wall:.1f} s wall, {cpu:.1f} s CPU, {int(peak_kb) / 1e6:.2f} GB peak "
      f"(passed: {verdict}); per view {wall / views:.2f} s wall, {cpu / views:.2f} s CPU")
print(f"  OpenCV:   {per_view_cv:.3f} s a view (two images)")
print(f"  ratio regolith CPU / OpenCV per view: {cpu / views / per_view_cv:.1f}")
EOF
