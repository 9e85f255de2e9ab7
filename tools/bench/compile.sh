#!/usr/bin/env bash
# `regolith compile` of one campaign against scipy's linear gridding of as many laser points:
# the median of REPEAT compiles (default 3) into a fresh database each (wall, CPU, peak memory,
# seconds per stage), then the DEM stages (`dem.tin` + `dem.raster`) next to the gridding peer
# (tools/peers/gridding_scipy.py: a Delaunay TIN and linear rasters at the compile's five cell
# sizes) on as many points as the compile triangulated, and their ratio. The peer grids a
# synthetic terrain with a known surface of that size, not the campaign's own points, and runs
# our TIN and rasters on the same points in the same run: its table gives both, with the height
# errors of both against the truth.
#
# Usage: tools/bench/compile.sh [CAMPAIGN]
#   CAMPAIGN: a campaign folder (campaign.toml); default: mini seed 301 from the checked-in
#   Mitsuba renders (corpus/renders), made here. For the issue's headline run an estec one:
#     regolith corpus generate --preset estec --full --seed 11 --renderer model --out /tmp/e11
#     tools/bench/compile.sh /tmp/e11
#   POINTS=N grids N points on the peer's side instead (scipy's Delaunay of the estec
#   campaign's 18 M points needs several GB and minutes; POINTS=0 skips the peer).
#
# Installs numpy and scipy with pip when they are missing. Timing only: nothing here passes or
# fails a test.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
repeat=${REPEAT:-3}

source "$root/tools/bench/campaign.sh"
for i in $(seq 1 "$repeat"); do
  echo "compile run $i of $repeat ..." >&2
  /usr/bin/time -f '%e %U %S %M' -o "$work/time$i" \
    "$bin" compile "$campaign" --db "$work/db$i" -q --json >"$work/compile$i.json"
  rm -rf "$work/db$i"
done

points=${POINTS:-$(python3 -c 'import json, sys
d = json.load(open(sys.argv[1]))
print(max(r["stats"]["tin_points"] for r in d["dem"]))' "$work/compile1.json")}
if [ "$points" -gt 0 ]; then
  if ! python3 -c 'import numpy, scipy' 2>/dev/null; then
    echo "installing numpy and scipy (pip) ..." >&2
    python3 -m pip install --quiet numpy scipy >&2
  fi
  echo "gridding peer on $points points ..." >&2
  (cd "$root" && python3 tools/peers/gridding_scipy.py "$work/peer" --points "$points") \
    >"$work/peer.log" 2>&1 || { cat "$work/peer.log" >&2; exit 1; }
fi

python3 - "$work" "$repeat" "$points" <<'PY'
import json, os, statistics, sys
work, repeat, points = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
med = statistics.median
runs = []
for i in range(1, repeat + 1):
    wall, user, sys_s, rss = open(f"{work}/time{i}").read().split()
    stages = {}
    for name, s in json.load(open(f"{work}/compile{i}.json"))["stage_seconds"]:
        stages[name] = stages.get(name, 0.0) + s
    runs.append((float(wall), float(user) + float(sys_s), int(rss) / 1e6, stages))
print(f"regolith compile, median of {repeat}; {os.cpu_count()} cores")
print(f"  wall {med(r[0] for r in runs):.1f} s (runs: "
      + ", ".join(f"{r[0]:.1f}" for r in runs) + f"), CPU {med(r[1] for r in runs):.1f} s,"
      f" peak {med(r[2] for r in runs):.2f} GB")
names = sorted(runs[0][3], key=lambda n: -runs[0][3][n])
for n in names:
    print(f"  {n:<24} {med(r[3].get(n, 0.0) for r in runs):7.2f} s")
dem = med(r[3].get("dem.tin", 0.0) + r[3].get("dem.raster", 0.0) for r in runs)
if points > 0:
    peer = json.load(open(f"{work}/peer/peer.json"))
    print(open(f"{work}/peer.log").read().split("\n\n", 1)[-1].rstrip())
    tin = max(r["stats"]["tin_points"] for r in json.load(open(f"{work}/compile1.json"))["dem"])
    same = abs(peer["points"] - tin) <= 0.01 * tin  # the generator jitters the count
    print(f"\nDEM stages of the compile (dem.tin + dem.raster, median): {dem:.1f} s on {tin:,}"
          f" points; scipy's TIN + rasters on {peer['points']:,} points: {peer['peer_total_s']:.1f} s"
          + (f", scipy / compile {peer['peer_total_s'] / dem:.1f}x" if same and dem > 0 else
             " (POINTS is not the compile's count: no ratio)")
          + f"; ours on the peer's points, one call as the compile: {peer['ours_one_call_total_s']:.1f} s,"
          f" scipy / ours {peer['peer_total_s'] / peer['ours_one_call_total_s']:.1f}x")
PY
