#!/usr/bin/env python3
"""OpenCV's detectors timed on one thread: the peer of regolith's `bench_detectors` example.

Usage (needs `pip install opencv-python-headless numpy`):

    python3 tools/peers/bench_detectors_opencv.py IMAGE... [--repeat N] [--json]

Each image is read as grey (8- or 16-bit; colour converted by OpenCV) and given the contrast
stretch `validate` applies before detecting (`features::contrast::stretch`: the 1 % and 99 %
levels of the 256-bin histogram mapped linearly to 0 and 1, tails saturated), then quantised to
8 bits, since OpenCV's FAST, SIFT and MSER take 8-bit images (regolith's FAST and MSER quantise
the same way; its Harris and SIFT work on the unquantised values). The stretch is not timed.
Then, with `cv2.setNumThreads(1)`, each detector runs once untimed (a warm-up, as the example
does) and N times timed (default 3) with the parameters
of regolith's `DetectorParams::default()`, and the script prints the median wall time and the
keypoint count, as a table or (`--json`) as one JSON object shaped like the example's.

- harris: `GFTTDetector(maxCorners=1000, qualityLevel=0.01, minDistance=1, blockSize=3,
  useHarrisDetector=True, k=0.04).detect` (goodFeaturesToTrack: Harris response + non-maximum
  suppression, as `HarrisParams`);
- fast: `FastFeatureDetector(threshold=20, nonmaxSuppression=True, TYPE_9_16).detect`
  (`FastParams`: 20/255, converted to 20 levels);
- sift: `SIFT_create()` (defaults = `SiftParams`) `.detectAndCompute`, since regolith's
  `compare::detect` computes the descriptors too;
- surf: `xfeatures2d.SURF_create(100, 4, 2).detect` (`SurfParams`; `compare::detect` computes no
  SURF descriptors) when this OpenCV build has the non-free contrib module; pip's
  opencv-python(-headless) and opencv-contrib-python wheels do not, so SURF is then reported
  as skipped;
- mser: `MSER_create(5, 60, 14400, 0.25, 0.2).detectRegions` (`MserParams`, OpenCV's defaults);
  the count is the number of regions. OpenCV 5 applies min_diversity differently from the
  classic rule regolith implements (see features_opencv.py), so counts may differ.
"""
import json
import sys
import time

import cv2
import numpy as np

USAGE = "usage: bench_detectors_opencv.py IMAGE... [--repeat N] [--json]"
DETECTORS = ["harris", "fast", "sift", "surf", "mser"]


def load_stretched(path):
    """The image as 8-bit levels after validate's linear 1-99 % stretch."""
    raw = cv2.imread(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_GRAYSCALE)
    if raw is None:
        raise SystemExit(f"{path}: cannot read image")
    scale = 65535.0 if raw.dtype == np.uint16 else 255.0
    v = raw.astype(np.float32) / np.float32(scale)
    levels = np.clip(np.floor(v * 255.0 + 0.5), 0, 255).astype(np.uint8)
    cum = np.cumsum(np.bincount(levels.ravel(), minlength=256)) / max(levels.size, 1)
    lo = int(np.argmax(cum > 0.01))
    hi = int(np.argmax(cum >= 0.99))
    lo, hi = (lo / 255.0, hi / 255.0) if lo < hi else (0.0, 1.0)
    lo, hi = np.float32(lo), np.float32(hi)
    out = np.clip((v - lo) * (np.float32(1.0) / (hi - lo)), 0.0, 1.0)
    return np.floor(out * 255.0 + 0.5).astype(np.uint8)


def runner(name):
    """A function img -> count for detector `name`, or a string saying why it is skipped."""
    if name == "harris":
        det = cv2.GFTTDetector_create(maxCorners=1000, qualityLevel=0.01, minDistance=1,
                                      blockSize=3, useHarrisDetector=True, k=0.04)
        return lambda img: len(det.detect(img, None))
    if name == "fast":
        det = cv2.FastFeatureDetector_create(threshold=20, nonmaxSuppression=True,
                                             type=cv2.FAST_FEATURE_DETECTOR_TYPE_9_16)
        return lambda img: len(det.detect(img, None))
    if name == "sift":
        det = cv2.SIFT_create()
        return lambda img: len(det.detectAndCompute(img, None)[0])
    if name == "surf":
        try:
            det = cv2.xfeatures2d.SURF_create(100, 4, 2)
        except (AttributeError, cv2.error):
            return ("SURF is patented (non-free): not in this OpenCV build "
                    "(pip wheels lack xfeatures2d.SURF_create)")
        return lambda img: len(det.detect(img, None))
    if name == "mser":
        det = cv2.MSER_create(5, 60, 14400, 0.25, 0.2)
        return lambda img: len(det.detectRegions(img)[0])
    raise ValueError(name)


def main():
    args = sys.argv[1:]
    repeat, as_json, paths = 3, False, []
    i = 0
    while i < len(args):
        a = args[i]
        if a == "--repeat" and i + 1 < len(args):
            repeat = int(args[i + 1])
            i += 1
        elif a == "--json":
            as_json = True
        elif a in ("-h", "--help"):
            print(USAGE)
            return 0
        elif a.startswith("--"):
            print(f"unknown option {a}; {USAGE}", file=sys.stderr)
            return 2
        else:
            paths.append(a)
        i += 1
    if not paths or repeat < 1:
        print(USAGE, file=sys.stderr)
        return 2
    cv2.setNumThreads(1)
    runners = {name: runner(name) for name in DETECTORS}
    images = []
    if not as_json:
        print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} thread")
        print(f"{'image':<40} {'size':>9} {'detector':>8} {'keypoints':>10} {'median ms':>10}")
    for path in paths:
        img = load_stretched(path)
        rows = []
        for name in DETECTORS:
            run = runners[name]
            if isinstance(run, str):
                rows.append({"detector": name, "skipped": run})
                if not as_json:
                    print(f"{path.rsplit('/', 1)[-1][:40]:<40} {'':>9} {name:>8} "
                          f"{'-':>10} {'-':>10}  {run}")
                continue
            count = run(img)  # untimed warm-up, as the example does
            runs = []
            for _ in range(repeat):
                t = time.perf_counter()
                count = run(img)
                runs.append((time.perf_counter() - t) * 1e3)
            med = sorted(runs)[len(runs) // 2]
            rows.append({"detector": name, "median_ms": med, "runs_ms": runs, "keypoints": count})
            if not as_json:
                size = f"{img.shape[1]}x{img.shape[0]}"
                print(f"{path.rsplit('/', 1)[-1][:40]:<40} {size:>9} {name:>8} {count:>10} "
                      f"{med:>10.1f}")
        images.append({"path": path, "width": int(img.shape[1]), "height": int(img.shape[0]),
                       "detectors": rows})
    if as_json:
        print(json.dumps({"implementation": f"OpenCV {cv2.__version__}",
                          "threads": cv2.getNumThreads(), "repeat": repeat, "images": images},
                         indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
