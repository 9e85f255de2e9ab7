#!/usr/bin/env python3
"""SIFT matching + RANSAC vs OpenCV on the Curiosity NavCam stereo pair (thesis Table 6.1).

Usage (from the repository root; needs `pip install opencv-python-headless numpy`):

    python3 tools/peers/matching_opencv.py [OUT_DIR] [--no-build]

Runs `REGOLITH_MATCHING_OUT=OUT_DIR cargo test --release -p regolith-validator --test matching
navcam_stereo_pair_sift_ransac`, which writes the exact 8-bit inputs (`left.png`, `right.png`),
our SIFT keypoints (`<side>.keypoints.json`) and descriptors (`<side>.descriptors.f32`), our
ratio-test matches (`matches.json`) and our reports (`ours.json`: keypoints, matches, inliers,
iterations for F at 1 px, F with cross check, H at 3 px). Then, with OpenCV:

1. Same keypoints and descriptors (isolates matching and RANSAC): `BFMatcher(NORM_L2)`
   `knnMatch(k=2)` with ratio 0.8 (and a mutual check), compared pair by pair with our matches;
   `findFundamentalMat(FM_RANSAC, 1.0, 0.99, 2000)` and `findHomography(RANSAC, 3.0, 2000,
   0.99)` on those matches, and how many of OpenCV's F inliers have a Sampson distance <= 1 px
   under OpenCV's own F (our inlier test), so the inlier definitions can be compared.
2. End to end: `cv2.SIFT_create()` on the same PNGs, the same matching and RANSAC.

Exit code 1 if the match sets differ on more than 1 % of pairs, or if our F inlier count is
more than 10 % away from OpenCV's on the same matches.
"""
import json
import os
import subprocess
import sys

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load_side(out, name):
    kps = np.array(json.load(open(os.path.join(out, f"{name}.keypoints.json"))), dtype=np.float64)
    desc = np.fromfile(os.path.join(out, f"{name}.descriptors.f32"), dtype="<f4")
    desc = desc.reshape(len(kps), -1) if len(kps) else desc.reshape(0, 128)
    img = cv2.imread(os.path.join(out, f"{name}.png"), cv2.IMREAD_GRAYSCALE)
    return img, kps, desc


def ratio_matches(da, db, ratio=0.8, mutual=False):
    bf = cv2.BFMatcher(cv2.NORM_L2)
    pairs = []
    for m in bf.knnMatch(da, db, k=2):
        if len(m) == 1 or (len(m) == 2 and m[0].distance < ratio * m[1].distance):
            pairs.append((m[0].queryIdx, m[0].trainIdx))
    if mutual:
        back = {m.queryIdx: m.trainIdx for m in bf.match(db, da)}
        pairs = [(i, j) for (i, j) in pairs if back.get(j) == i]
    return pairs


def sampson(F, pa, pb):
    xa = np.c_[pa, np.ones(len(pa))]
    xb = np.c_[pb, np.ones(len(pb))]
    fa = xa @ F.T
    ftb = xb @ F
    e = np.sum(xb * fa, axis=1)
    den = fa[:, 0] ** 2 + fa[:, 1] ** 2 + ftb[:, 0] ** 2 + ftb[:, 1] ** 2
    return np.sqrt(e * e / den)


def geometry(pa, pb):
    out = {}
    if len(pa) < 8:
        return {"fundamental": 0, "fundamental_sampson_1px": 0, "homography": 0}
    F, mask = cv2.findFundamentalMat(pa, pb, cv2.FM_RANSAC, 1.0, 0.99, 2000)
    out["fundamental"] = int(mask.sum()) if mask is not None else 0
    out["fundamental_sampson_1px"] = (
        int((sampson(F[:3], pa, pb) <= 1.0).sum()) if F is not None else 0
    )
    H, hmask = cv2.findHomography(pa, pb, cv2.RANSAC, 3.0, maxIters=2000, confidence=0.99)
    out["homography"] = int(hmask.sum()) if hmask is not None else 0
    return out


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    out = os.path.abspath(args[0] if args else os.path.join(ROOT, "target", "peer-matching"))
    if "--no-build" not in sys.argv:
        env = dict(os.environ, REGOLITH_MATCHING_OUT=out)
        subprocess.run(
            ["cargo", "test", "--release", "-p", "regolith-validator", "--test", "matching",
             "navcam_stereo_pair_sift_ransac", "--", "--nocapture"],
            cwd=ROOT, env=env, check=True)
    ours = json.load(open(os.path.join(out, "ours.json")))
    our_pairs = [tuple(p) for p in json.load(open(os.path.join(out, "matches.json")))]
    li, kl, dl = load_side(out, "left")
    ri, kr, dr = load_side(out, "right")
    print(f"OpenCV {cv2.__version__}; images {li.shape[1]}x{li.shape[0]}")

    # 1. Same keypoints and descriptors.
    cv_pairs = ratio_matches(dl, dr)
    cv_mutual = ratio_matches(dl, dr, mutual=True)
    common = len(set(cv_pairs) & set(our_pairs))
    differ = len(set(cv_pairs) ^ set(our_pairs))
    print("\n1. our SIFT keypoints + descriptors")
    print(f"   keypoints            ours {len(kl)} / {len(kr)}")
    print(f"   ratio-test matches   ours {ours['fundamental']['matches']}  OpenCV {len(cv_pairs)}"
          f"  common {common}  differing {differ}")
    print(f"   + cross check        ours {ours['fundamental_mutual']['matches']}"
          f"  OpenCV {len(cv_mutual)}")
    idx = np.array(cv_pairs, dtype=np.int64).reshape(-1, 2)
    pa = kl[idx[:, 0], :2].astype(np.float64)
    pb = kr[idx[:, 1], :2].astype(np.float64)
    g = geometry(pa, pb)
    print(f"   F inliers (1 px)     ours {ours['fundamental']['inliers']}"
          f" ({ours['fundamental']['iterations']} it.)  OpenCV FM_RANSAC {g['fundamental']}"
          f"  Sampson<=1px under OpenCV's F {g['fundamental_sampson_1px']}")
    print(f"   H inliers (3 px)     ours {ours['homography']['inliers']}"
          f" ({ours['homography']['iterations']} it.)  OpenCV RANSAC {g['homography']}")

    # 2. OpenCV end to end.
    sift = cv2.SIFT_create()
    ckl, cdl = sift.detectAndCompute(li, None)
    ckr, cdr = sift.detectAndCompute(ri, None)
    e2e = ratio_matches(cdl, cdr)
    idx = np.array(e2e, dtype=np.int64).reshape(-1, 2)
    qa = np.array([ckl[i].pt for i in idx[:, 0]], dtype=np.float64).reshape(-1, 2)
    qb = np.array([ckr[j].pt for j in idx[:, 1]], dtype=np.float64).reshape(-1, 2)
    g2 = geometry(qa, qb)
    f = ours["fundamental"]
    print("\n2. end to end (Table 6.1 analogue)     ours      OpenCV")
    print(f"   keypoints left / right        {f['keypoints_a']:5d} / {f['keypoints_b']:5d}"
          f"   {len(ckl):5d} / {len(ckr):5d}")
    print(f"   ratio-test matches            {f['matches']:13d}   {len(e2e):13d}")
    print(f"   F inliers (1 px)              {f['inliers']:13d}   {g2['fundamental']:13d}")
    print(f"   H inliers (3 px)              {ours['homography']['inliers']:13d}"
          f"   {g2['homography']:13d}")

    bad = differ > 0.01 * max(len(cv_pairs), 1) or abs(
        f["inliers"] - g["fundamental"]) > 0.1 * max(g["fundamental"], 1)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
