#!/usr/bin/env python3
"""Cross-check regolith's image undistortion against OpenCV's cv2.undistort.

Needs: pip install opencv-python-headless numpy   (and cargo, run from the repository root).

  python3 tools/peers/undistort_opencv.py write-fixture [DIR]
      Writes a seeded 8-bit test image (raw.png), its calibration (camera.json, regolith's
      CameraModel JSON: OpenCV and regolith share the pixel-centre convention, so K and D are
      used unchanged) and OpenCV's result (opencv.png = cv2.undistort(raw, K, D, newCameraMatrix=K))
      into DIR (default compiler/tests/data/images/undistort). The regolith test
      `undistort_matches_opencv_peer` compares against these committed files in CI.

  python3 tools/peers/undistort_opencv.py compare [DIR]
      Runs that test with REGOLITH_UNDISTORT_OUT=DIR so it writes regolith's result (ours.png),
      re-runs cv2.undistort with the installed OpenCV, and prints the RMS difference in grey
      levels over pixels at least MARGIN pixels away from the invalid border.
"""
import json
import os
import subprocess
import sys

import cv2
import numpy as np

MARGIN = 2
CAMERA = {
    "model": "pinhole-brown-conrady", "width": 160, "height": 120,
    "fx": 118.0, "fy": 117.0, "cx": 79.3, "cy": 60.1, "skew": 0.0,
    "distortion": {"k1": -0.28, "k2": 0.09, "p1": 0.0012, "p2": -0.0007, "k3": -0.012},
}


def k_and_d(cam):
    k = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]], np.float64)
    d = cam["distortion"]
    return k, np.array([d["k1"], d["k2"], d["p1"], d["p2"], d["k3"]], np.float64)


def test_image(w, h):
    """Smooth shading, hard-edged blocks, a disc and seeded noise: every interpolation case."""
    rng = np.random.default_rng(20240611)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = 60 + 50 * np.sin(x / 9.0) * np.cos(y / 7.0)
    for _ in range(25):
        x0, y0 = rng.integers(0, w - 10), rng.integers(0, h - 10)
        img[y0:y0 + rng.integers(3, 20), x0:x0 + rng.integers(3, 20)] = rng.integers(0, 256)
    img[(x - w / 2) ** 2 + (y - h / 2) ** 2 < (h / 5) ** 2] = 235
    img += rng.normal(0, 6, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def opencv_undistort(raw, cam):
    k, d = k_and_d(cam)
    return cv2.undistort(raw, k, d, None, k)


def interior_mask(cam, margin):
    """Output pixels whose sampling position (and a margin around it) lies inside the raw image."""
    k, d = k_and_d(cam)
    mapx, mapy = cv2.initUndistortRectifyMap(k, d, None, k, (cam["width"], cam["height"]), cv2.CV_32FC1)
    inside = (mapx >= 0) & (mapy >= 0) & (mapx <= cam["width"] - 1) & (mapy <= cam["height"] - 1)
    return cv2.erode(inside.astype(np.uint8), np.ones((2 * margin + 1,) * 2, np.uint8)) > 0


def main():
    cmd = sys.argv[1] if len(sys.argv) > 1 else "compare"
    out = sys.argv[2] if len(sys.argv) > 2 else "compiler/tests/data/images/undistort"
    os.makedirs(out, exist_ok=True)
    if cmd == "write-fixture":
        raw = test_image(CAMERA["width"], CAMERA["height"])
        cv2.imwrite(f"{out}/raw.png", raw)
        with open(f"{out}/camera.json", "w") as f:
            json.dump(CAMERA, f, indent=2)
        cv2.imwrite(f"{out}/opencv.png", opencv_undistort(raw, CAMERA))
        print(f"wrote raw.png, camera.json, opencv.png (OpenCV {cv2.__version__}) to {out}")
        return
    env = dict(os.environ, REGOLITH_UNDISTORT_OUT=os.path.abspath(out))
    subprocess.run(["cargo", "test", "-p", "regolith-compiler", "--test", "ingest_mesh_images",
                    "undistort_matches_opencv_peer"], check=True, env=env)
    with open(f"{out}/camera.json") as f:
        cam = json.load(f)
    raw = cv2.imread(f"{out}/raw.png", cv2.IMREAD_UNCHANGED)
    ref = opencv_undistort(raw, cam).astype(np.float64)
    ours = cv2.imread(f"{out}/ours.png", cv2.IMREAD_UNCHANGED).astype(np.float64)
    mask = interior_mask(cam, MARGIN)
    diff = (ours - ref)[mask]
    print(f"OpenCV {cv2.__version__}: {mask.sum()} interior pixels, "
          f"RMS {np.sqrt(np.mean(diff ** 2)):.4f} grey levels, max |diff| {np.abs(diff).max():.0f}, "
          f"{np.count_nonzero(diff)} pixels differ")


if __name__ == "__main__":
    main()
