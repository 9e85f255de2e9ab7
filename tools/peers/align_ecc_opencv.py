#!/usr/bin/env python3
"""OpenCV's dense alignment (ECC, `cv2.findTransformECC`) of each view's real frame to its
render: the peer of the gap workflow's geometric stage, which aligns the real frames to the
renders densely too (all views jointly, seven parameters, held-out refits).

Input: the real | render | difference strips that `dump_view` writes (grey PNGs three frames
wide; `cargo run --release -p regolith-validator --example dump_view -- DB ENTRY OUT`). Per
strip: a homography (eight parameters) from the render to the real frame, ECC on the pixels
where the render sees terrain, Gaussian pre-filter 5 px, at most 50 iterations or a step under
1e-6, one thread; the median milliseconds of `--repeat` timed runs after one untimed run, the
correlation reached and how far the homography moves the image centre.

Usage: align_ecc_opencv.py STRIP.png... [--repeat N] [--json]
Needs opencv-python-headless and numpy. Timing only: nothing here passes or fails a test.
"""

import argparse
import json
import statistics
import sys
import time

import cv2
import numpy as np


def align(real, render, mask):
    warp = np.eye(3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-6)
    cc, warp = cv2.findTransformECC(
        render, real, warp, cv2.MOTION_HOMOGRAPHY, criteria, mask, 5
    )
    return cc, warp


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("strips", nargs="+")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    cv2.setNumThreads(1)
    out = []
    for path in a.strips:
        strip = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if strip is None or strip.shape[1] % 3:
            sys.exit(f"{path}: expected a grey real | render | difference strip")
        w = strip.shape[1] // 3
        real = strip[:, :w].astype(np.float32) / 255.0
        render = strip[:, w : 2 * w].astype(np.float32) / 255.0
        mask = (strip[:, w : 2 * w] > 0).astype(np.uint8)
        try:
            align(real, render, mask)
        except cv2.error as e:
            out.append({"image": path, "error": str(e).strip().splitlines()[-1]})
            continue
        times = []
        for _ in range(max(1, a.repeat)):
            t0 = time.perf_counter()
            cc, warp = align(real, render, mask)
            times.append((time.perf_counter() - t0) * 1000.0)
        h, wd = real.shape
        c = np.array([wd / 2.0, h / 2.0, 1.0])
        moved = warp.astype(np.float64) @ c
        shift = float(np.hypot(*(moved[:2] / moved[2] - c[:2])))
        out.append(
            {
                "image": path,
                "median_ms": statistics.median(times),
                "correlation": float(cc),
                "centre_shift_px": shift,
            }
        )
    if a.json:
        json.dump({"opencv": cv2.__version__, "images": out}, sys.stdout, indent=1)
        print()
        return
    for r in out:
        if "error" in r:
            print(f"{r['image']}: ECC failed: {r['error']}")
        else:
            print(
                f"{r['image']}: {r['median_ms']:.1f} ms, correlation {r['correlation']:.3f}, "
                f"centre moved {r['centre_shift_px']:.2f} px"
            )


if __name__ == "__main__":
    main()
