#!/usr/bin/env bash
# regolith's detectors against OpenCV's, one thread each, on the same images: per image and
# detector the median ms of both, the ratio regolith / OpenCV and both keypoint counts, and per
# image the sum over the detectors both have (a view's detection as `validate` runs it, SURF
# aside: pip's OpenCV has no SURF).
#
# Usage: tools/bench/detectors.sh [IMAGE...]        (REPEAT=N: timed runs per detector, default 3)
# Without images: corpus/demo/captures/loc01_left_a.png, plus OpenCV's sample graf1.png
# (Debian opencv-doc) and the Curiosity NavCam left JPEG in ../shared/realdata/rover/ when
# present. Pass an estec-scale campaign's captures (1280x1024) as arguments.
#
# Installs opencv-python-headless with pip into python3 when `import cv2` fails. Inputs that are
# not grey PNGs (colour, JPEG) are first converted to grey PNGs with OpenCV, so both sides read
# the same levels whatever their decoders. Timing only: nothing here passes or fails a test.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
repeat=${REPEAT:-3}

if [ $# -eq 0 ]; then
  set -- "$root/corpus/demo/captures/loc01_left_a.png"
  for f in /usr/share/doc/opencv-doc/examples/data/graf1.png \
    "$root/../shared/realdata/rover/NLB_524534514EDR_F0562034NCAM00280M_.jpeg"; do
    [ -f "$f" ] && set -- "$@" "$f"
  done
fi
for f in "$@"; do
  [ -f "$f" ] || { echo "no such image: $f" >&2; exit 2; }
done

if ! python3 -c 'import cv2, numpy' 2>/dev/null; then
  echo "installing opencv-python-headless (pip) ..." >&2
  python3 -m pip install --quiet opencv-python-headless numpy >&2
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Grey PNGs both sides read; one per argument, in order.
mapfile -t images < <(python3 - "$work" "$@" <<'EOF'
import os, sys
import cv2
out, paths = sys.argv[1], sys.argv[2:]
for i, p in enumerate(paths):
    img = cv2.imread(p, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit(f"{p}: cannot read image")
    if img.ndim == 2 and p.lower().endswith(".png"):
        print(os.path.abspath(p))
        continue
    grey = cv2.imread(p, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    stem = os.path.splitext(os.path.basename(p))[0]
    dst = os.path.join(out, f"{i}_{stem}.png")
    cv2.imwrite(dst, grey)
    print(dst)
EOF
)

(cd "$root" && cargo build --release -q -p regolith-validator --example bench_detectors)
(cd "$root" && cargo run --release -q -p regolith-validator --example bench_detectors -- \
  "${images[@]}" --repeat "$repeat" --json) >"$work/regolith.json"
python3 "$root/tools/peers/bench_detectors_opencv.py" "${images[@]}" --repeat "$repeat" --json \
  >"$work/opencv.json"

python3 - "$work/regolith.json" "$work/opencv.json" "$@" <<'EOF'
import json, os, sys
ours, cv = (json.load(open(p)) for p in sys.argv[1:3])
def label(path, paths):
    """The shortest trailing part of `path` that no other argument shares."""
    parts = os.path.normpath(path).split(os.sep)
    others = [os.path.normpath(q).split(os.sep) for q in paths if q != path]
    for k in range(1, len(parts) + 1):
        if all(o[-k:] != parts[-k:] for o in others):
            return os.path.join(*parts[-k:])
    return path
names = [label(p, sys.argv[3:]) for p in sys.argv[3:]]
load = os.getloadavg()[0]
print(f"regolith vs {cv['implementation']}: 1 thread each, median of {ours['repeat']} runs after "
      f"a warm-up; {os.cpu_count()} cores, load average {load:.1f}")
print(f"{'image':<36} {'size':>9} {'detector':>8} {'regolith ms':>12} {'OpenCV ms':>10} "
      f"{'ratio':>6} {'kp regolith':>12} {'kp OpenCV':>10}")
for name, a, b in zip(names, ours["images"], cv["images"]):
    size = f"{a['width']}x{a['height']}"
    cv_rows = {r["detector"]: r for r in b["detectors"]}
    both_a = both_b = 0.0
    for r in a["detectors"]:
        c = cv_rows.get(r["detector"], {"skipped": "missing"})
        if "skipped" in c:
            cv_ms, ratio, kp = "-", "-", "-"
        else:
            both_a += r["median_ms"]
            both_b += c["median_ms"]
            cv_ms, ratio, kp = (f"{c['median_ms']:.1f}", f"{r['median_ms'] / c['median_ms']:.2f}",
                                str(c["keypoints"]))
        print(f"{name[-36:]:<36} {size:>9} {r['detector']:>8} {r['median_ms']:>12.1f} "
              f"{cv_ms:>10} {ratio:>6} {r['keypoints']:>12} {kp:>10}")
    total = sum(r["median_ms"] for r in a["detectors"])
    print(f"{name[-36:]:<36} {size:>9} {'sum':>8} {both_a:>12.1f} {both_b:>10.1f} "
          f"{both_a / both_b:>6.2f}   (detectors both have; regolith with SURF: {total:.1f} ms)")
EOF
