#!/usr/bin/env python3
"""How much of a fitted pose bias's error lies where real-to-real comparisons cannot see it.

A pose bias B fixed to the rig moves every capture's pose from P_k to P_k B. Two captures
related by the motion M = P_1^-1 P_2 see the bias through B^-1 M B; a B that commutes with M
(a rotation about M's screw axis and a shift along it) leaves that unchanged, so the pairs of
real images of the two captures cannot see it and only the entry decides it. This script takes
the per-case lines of `gap_matrix` (pose-bias cases) and the case directories it wrote, finds
the two-dimensional family of biases the captures' relative motions leave unseen (the null
space of Ad(M) - I, linearised, rotations scaled by a 1.5 m lever arm), and prints which share
of each fitted bias's error lies in it.

Usage: weak_plane.py MATRIX_OUTPUT CASES_DIR   (CASES_DIR/pose-bias-<seed>/camp/truth/...)
Needs numpy.
"""
import json
import re
import sys

import numpy as np

LEVER_M = 1.5


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def pose(p):
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(p["rotation_xyzw"])
    m[:3, 3] = p["translation_m"]
    return m


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def adjoint(m):
    """Adjoint of a rigid motion acting on twists (rotation, translation)."""
    r, p = m[:3, :3], m[:3, 3]
    a = np.zeros((6, 6))
    a[:3, :3] = r
    a[3:, 3:] = r
    a[3:, :3] = skew(p) @ r
    return a


def fitted_biases(path):
    out = {}
    for line in open(path):
        if not line.startswith("pose-bias "):
            continue
        seed = int(re.search(r"seed (\d+)", line).group(1))
        out[seed] = {
            name: (float(t), float(v))
            for name, t, v in re.findall(
                r"pose-bias\.(\w+\.[xyz])=([-0-9.]+)→([-0-9.]+)", line)
        }
    return out


def main():
    matrix, cases = sys.argv[1], sys.argv[2]
    scale = np.diag([1 / LEVER_M] * 3 + [1] * 3)
    for seed, fit in sorted(fitted_biases(matrix).items()):
        if "rotation_deg.x" not in fit:
            continue
        caps = json.load(open(f"{cases}/pose-bias-{seed}/camp/truth/captures.json"))
        rigs = [pose(c["ground_from_rig"]) for c in caps]
        a = np.vstack([adjoint(np.linalg.inv(rigs[0]) @ r) - np.eye(6) for r in rigs[1:]])
        _, sing, vt = np.linalg.svd(a @ scale)
        unseen = vt[-2:]
        err = np.array(
            [np.radians(fit[f"rotation_deg.{k}"][1] - fit[f"rotation_deg.{k}"][0]) for k in "xyz"]
            + [fit[f"translation_m.{k}"][1] - fit[f"translation_m.{k}"][0] for k in "xyz"])
        e = np.linalg.solve(scale, err)
        share = np.linalg.norm(unseen.T @ (unseen @ e)) / np.linalg.norm(e)
        print(f"seed {seed}: error {np.linalg.norm(e) * 1e3:.1f} mm at {LEVER_M} m, "
              f"{100 * share:.0f} % of it unseen by the pairs "
              f"(smallest singular values {np.round(sing[-3:], 3)})")


if __name__ == "__main__":
    main()
