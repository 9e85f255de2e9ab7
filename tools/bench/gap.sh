#!/usr/bin/env bash
# `regolith gap` on one entry, and its geometric stage against OpenCV's dense alignment (ECC)
# of the same views: the median of REPEAT runs (default 3) of `gap --entry ENTRY` (wall, CPU,
# peak memory, seconds per step), then the geometric stage's wall seconds per view next to
# what `cv2.findTransformECC` needs to align one view's real frame to its render (a
# homography, one thread; `tools/peers/align_ecc_opencv.py`), and their ratio. The stage fits
# every view jointly and refits each candidate set with each capture held out (four sets ×
# eight captures on estec), so the ratio says how far that is from aligning each view once.
#
# Usage: tools/bench/gap.sh [CAMPAIGN [ENTRY]]
#   CAMPAIGN: a campaign folder (campaign.toml); default: mini seed 301 from the checked-in
#   Mitsuba renders (corpus/renders), made here. ENTRY: default laser/0.01 (mini's finest).
#   For the issue's headline run an estec campaign:
#     regolith corpus generate --preset estec --full --seed 11 --renderer model --out /tmp/e11
#     tools/bench/gap.sh /tmp/e11 laser/0.015
#
# Installs opencv-python-headless with pip when `import cv2` fails. Timing only: nothing here
# passes or fails a test.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
entry=${2:-laser/0.01}
repeat=${REPEAT:-3}

source "$root/tools/bench/setup.sh"
(cd "$root" && cargo build --release -q -p regolith-validator --example dump_view)
for i in $(seq 1 "$repeat"); do
  echo "gap run $i of $repeat ..." >&2
  /usr/bin/time -f '%e %U %S %M' -o "$work/time$i" \
    "$bin" gap "$work/db" --entry "$entry" -q --json >"$work/gap$i.json"
done
echo "rendering the views ..." >&2
"$root/target/release/examples/dump_view" "$work/db" "$entry" "$work/views" >/dev/null
python3 "$root/tools/peers/align_ecc_opencv.py" "$work"/views/*.png --repeat 1 --json \
  >"$work/opencv.json"

python3 - "$work" "$repeat" "$entry" <<'EOF'
import json, os, statistics, sys
work, repeat, entry = sys.argv[1], int(sys.argv[2]), sys.argv[3]
runs = []
for i in range(1, repeat + 1):
    wall, user, system, peak_kb = open(f"{work}/time{i}").read().split()
    steps = dict(json.load(open(f"{work}/gap{i}.json"))["step_seconds"])
    runs.append((float(wall), float(user) + float(system), int(peak_kb) / 1e6, steps))
med = lambda xs: statistics.median(xs)
wall, cpu, peak = med([r[0] for r in runs]), med([r[1] for r in runs]), med([r[2] for r in runs])
cv = json.load(open(f"{work}/opencv.json"))
ok = [im for im in cv["images"] if "error" not in im]
views = len(cv["images"])
print(f"regolith gap --entry {entry}, median of {repeat}; {os.cpu_count()} cores, "
      f"load average {os.getloadavg()[0]:.1f}")
print(f"  wall {wall:.1f} s (runs {', '.join(f'{r[0]:.1f}' for r in runs)}), "
      f"CPU {cpu:.1f} s, peak {peak:.2f} GB")
for step in runs[0][3]:
    print(f"    {step}: {med([r[3].get(step, 0.0) for r in runs]):.1f} s")
geometry = med([r[3].get("geometry: distortion, pose bias", 0.0) for r in runs])
if ok:
    ecc = med([im["median_ms"] for im in ok]) / 1000.0
    print(f"  OpenCV {cv['opencv']} ECC homography, one thread: {ecc:.3f} s a view "
          f"({len(ok)} of {views} views aligned; correlation "
          f"{med([im['correlation'] for im in ok]):.3f})")
    per_view = geometry / max(views, 1)
    print(f"  geometric stage {per_view:.2f} s wall a view; ratio to ECC {per_view / ecc:.1f}")
else:
    print(f"  OpenCV's ECC aligned none of the {views} views")
EOF
