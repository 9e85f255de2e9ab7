#!/usr/bin/env python3
"""Gaussian blur peer: OpenCV's GaussianBlur on the raster `bench_blur` wrote.

Usage: python3 tools/peers/blur_opencv.py DIR
DIR holds `input.f32` (little-endian float32, row-major) and `job.json`
({"width", "height", "threads", "reps", "runs": [{"sigma", "radius"}]}), written by
`cargo run --release -p regolith-validator --example bench_blur -- --peer`. For every run this
blurs with a (2·radius+1)² kernel of that sigma and replicated borders (regolith's
definition), writes `opencv_<i>.f32` and records the median time of `reps` runs in
`opencv.json`. Needs `pip install opencv-python-headless numpy`.
"""
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np


def main() -> int:
    d = Path(sys.argv[1])
    job = json.loads((d / "job.json").read_text())
    w, h = job["width"], job["height"]
    src = np.fromfile(d / "input.f32", dtype="<f4").reshape(h, w)
    cv2.setNumThreads(job["threads"])
    times = []
    for i, run in enumerate(job["runs"]):
        k = 2 * run["radius"] + 1
        taken = []
        for _ in range(job["reps"]):
            t = time.perf_counter()
            out = cv2.GaussianBlur(src, (k, k), run["sigma"], sigmaY=run["sigma"],
                                   borderType=cv2.BORDER_REPLICATE)
            taken.append(time.perf_counter() - t)
        out.astype("<f4").tofile(d / f"opencv_{i}.f32")
        times.append(sorted(taken)[len(taken) // 2] * 1000.0)
    (d / "opencv.json").write_text(json.dumps({"version": cv2.__version__, "ms": times}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
