#!/usr/bin/env python3
"""DEM gridding vs scipy: Delaunay TIN + rasterisation speed and height accuracy (issue #4).

Usage (from the repository root; needs `pip install numpy scipy`):

    python3 tools/peers/gridding_scipy.py [OUT_DIR] [--no-build] [--points N] [--threads N]
        [--heights-only] [--tin-only]

Builds and runs the example `bench_gridding` (release) with `--export OUT_DIR` (default
`target/peer-gridding`): it generates the synthetic laser terrain with a known true surface
(~4 M points over 8.7 x 8.6 m, 8 mm noise), runs our `dem.tin` + `dem.raster` exactly as
`regolith compile` does for a laser terrain (local regression included) at 0.030 / 0.020 /
0.015 / 0.010 / 0.005 m cells, and writes the points, each grid's geometry, the true surface and
our heights at every cell centre, and our timings. `--threads N` is passed on (default: all
cores), and so is `--heights-only` (no albedo on our side; by default our TIN and rasters also
carry albedo, as the compile's do, which the peer does not compute). `--tin-only` is a
diagnostic: our rasters then skip the local regression and interpolate the TIN linearly at the
cell centres, as the peer does, so the two should agree to float precision wherever the two
Delaunay triangulations agree (they can differ only where four points are co-circular).

The peer then grids the SAME points at the SAME cell centres with scipy's linear gridding,
`scipy.interpolate.griddata(points, z, xi, method="linear")`, in its fair form for several
rasters: the Qhull Delaunay triangulation once (`scipy.spatial.Delaunay`, the triangulation
griddata builds) and one `LinearNDInterpolator` on it reused for every cell size (griddata
would re-triangulate per call). Timed separately: the triangulation, the per-simplex barycentric
transforms (`Delaunay.transform`, computed once on the interpolator's first call; timed apart
so it is not charged to the first raster) and each raster's interpolation. scipy evaluates
single-threaded (the interpolator holds the GIL: splitting the cells over threads was measured
slower), so the ratio compares our run on `--threads` cores with scipy's one. OpenBLAS is set to
one thread before numpy loads (unless OPENBLAS_NUM_THREADS is set): the transforms make one tiny
LAPACK call per simplex, which OpenBLAS's threading made ~10x slower on this machine.

Prints, per cell size, over the cells both call valid: our and the peer's seconds, the ratio
peer / ours, and the height RMS and max |error| of both against the true surface; then the
totals (TIN + all rasters: ours once with one `dem.raster` call per cell size as timed per row,
once with the compile's single call over all cell sizes, whose setup is shared) and, per cell
size, the RMS and max of ours - scipy. The speed verdict uses the per-cell total (the slower).
Writes `peer.json` next to the export. Exit code 1 if our height RMS is more than 10 % above the
peer's at any cell size. PDAL (`filters.delaunay` +
`writers.gdal`) is not compared: its Python bindings need the PDAL C++ library, which neither
Debian bookworm packages nor PyPI ships other than as source.
"""
import os

# Before numpy/scipy load OpenBLAS (see the docstring).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy.interpolate import LinearNDInterpolator  # noqa: E402
from scipy.spatial import Delaunay  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RMS_TOLERANCE = 1.10  # ours may be at most 10 % worse than the peer
SPEED_TARGET = 3.0  # issue #4: aim for >= 3x the peer's speed


def run_ours(out_dir, args):
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    exe = os.path.join(target, "release", "examples", "bench_gridding")
    if not args.no_build:
        subprocess.run(["cargo", "build", "--release", "-p", "regolith-compiler", "--example",
                        "bench_gridding"], cwd=ROOT, check=True)
    cmd = [exe, "--points", str(args.points), "--export", out_dir]
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    if args.heights_only:
        cmd.append("--heights-only")
    if args.tin_only:
        cmd.append("--tin-only")
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, cwd=ROOT, check=True)


def errors(h, truth, mask):
    e = h[mask].astype(np.float64) - truth[mask].astype(np.float64)
    return float(np.sqrt(np.mean(e * e))), float(np.max(np.abs(e)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir", nargs="?", default=os.path.join(ROOT, "target", "peer-gridding"))
    ap.add_argument("--no-build", action="store_true", help="run the built example as it is")
    ap.add_argument("--points", type=int, default=4_000_000)
    ap.add_argument("--threads", type=int, default=0, help="our threads (0 = all cores)")
    ap.add_argument("--heights-only", action="store_true", help="no albedo on our side")
    ap.add_argument("--tin-only", action="store_true",
                    help="diagnostic: our rasters without the local regression")
    args = ap.parse_args()
    out = os.path.abspath(args.out_dir)

    run_ours(out, args)
    with open(os.path.join(out, "grid.json")) as f:
        grid = json.load(f)
    with open(os.path.join(out, "ours.json")) as f:
        ours = json.load(f)
    pts = np.fromfile(os.path.join(out, grid["points_file"]), dtype="<f8").reshape(-1, 3)
    print(f"\npeer: scipy {scipy.__version__} griddata(method='linear') on {len(pts)} points,"
          f" 1 thread (OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']})", flush=True)

    t = time.perf_counter()
    tri = Delaunay(pts[:, :2])
    delaunay_s = time.perf_counter() - t
    t = time.perf_counter()
    _ = tri.transform
    transform_s = time.perf_counter() - t
    interp = LinearNDInterpolator(tri, pts[:, 2])
    print(f"peer Delaunay: {len(tri.simplices)} triangles, {delaunay_s:.3f} s;"
          f" barycentric transforms {transform_s:.3f} s", flush=True)
    del pts

    rows = []
    for g in grid["rasters"]:
        cell, nr, nc = g["cell_m"], g["rows"], g["cols"]
        xs = g["origin"][0] + np.arange(nc) * cell
        ys = g["origin"][1] - np.arange(nr) * cell
        xx, yy = np.meshgrid(xs, ys)
        xi = np.column_stack([xx.ravel(), yy.ravel()])
        del xx, yy
        t = time.perf_counter()
        peer = interp(xi)
        peer_s = time.perf_counter() - t
        del xi
        truth = np.fromfile(os.path.join(out, g["truth"]), dtype="<f4")
        mine = np.fromfile(os.path.join(out, g["ours"]), dtype="<f4")
        assert truth.size == mine.size == peer.size == nr * nc, "grid sizes differ"
        ok_ours, ok_peer = np.isfinite(mine), np.isfinite(peer)
        both = ok_ours & ok_peer
        o_rms, o_max = errors(mine, truth, both)
        p_rms, p_max = errors(peer, truth, both)
        d_rms, d_max = errors(mine, peer, both)
        our_row = next(r for r in ours["rasters"] if r["cell_m"] == cell)
        rows.append({
            "cell_m": cell, "cells": nr * nc, "both_valid": int(both.sum()),
            "ours_only": int((ok_ours & ~ok_peer).sum()),
            "peer_only": int((ok_peer & ~ok_ours).sum()),
            "ours_s": our_row["seconds"], "peer_s": peer_s,
            "ours_rms_m": o_rms, "ours_max_m": o_max, "peer_rms_m": p_rms, "peer_max_m": p_max,
            "diff_rms_m": d_rms, "diff_max_m": d_max,
        })
        print(f"  {cell} m: {nr}x{nc}, peer {peer_s:.3f} s", flush=True)

    ours_total = ours["tin_s"] + sum(r["ours_s"] for r in rows)
    ours_compile = ours["one_call_total_s"]
    peer_tin = delaunay_s + transform_s
    peer_total = peer_tin + sum(r["peer_s"] for r in rows)
    mode = ("heights + albedo" if ours["albedo"] else "heights only") + (
        "" if ours["regression"] else ", TIN interpolation only")
    print(f"\n{ours['points']} points, ours on {ours['threads']} threads ({mode}), scipy on 1;"
          " errors vs the true surface over cells both call valid\n")
    print("| cell m | cells both valid | ours s | scipy s | scipy / ours | ours RMS mm |"
          " scipy RMS mm | ours max mm | scipy max mm |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| TIN | | {ours['tin_s']:.2f} | {peer_tin:.2f} ({delaunay_s:.2f} Delaunay +"
          f" {transform_s:.2f} transforms) | {peer_tin / ours['tin_s']:.1f}x | | | | |")
    for r in rows:
        print(f"| {r['cell_m']} | {r['both_valid']:,} | {r['ours_s']:.2f} | {r['peer_s']:.2f} |"
              f" {r['peer_s'] / r['ours_s']:.1f}x | {r['ours_rms_m'] * 1e3:.2f} |"
              f" {r['peer_rms_m'] * 1e3:.2f} | {r['ours_max_m'] * 1e3:.1f} |"
              f" {r['peer_max_m'] * 1e3:.1f} |")
    print(f"| total | | {ours_total:.2f} | {peer_total:.2f} | {peer_total / ours_total:.1f}x |"
          " | | | |")
    print(f"| total, ours as the compile (one `dem.raster` call) | | {ours_compile:.2f} |"
          f" {peer_total:.2f} | {peer_total / ours_compile:.1f}x | | | | |")
    print("\nours - scipy over cells both call valid: " + ", ".join(
        f"{r['cell_m']} m RMS {r['diff_rms_m'] * 1e3:.3g} mm max {r['diff_max_m'] * 1e3:.3g} mm"
        for r in rows))
    odd = [(r["cell_m"], r["ours_only"], r["peer_only"]) for r in rows
           if r["ours_only"] or r["peer_only"]]
    if odd:
        print("\ncells valid on one side only (cell, ours only, scipy only):", odd)

    with open(os.path.join(out, "peer.json"), "w") as f:
        json.dump({"scipy": scipy.__version__, "points": ours["points"],
                   "ours_threads": ours["threads"], "ours_albedo": ours["albedo"],
                   "ours_regression": ours["regression"],
                   "ours_tin_s": ours["tin_s"], "peer_delaunay_s": delaunay_s,
                   "peer_transform_s": transform_s, "ours_total_s": ours_total,
                   "ours_one_call_total_s": ours_compile,
                   "peer_total_s": peer_total, "rasters": rows}, f, indent=2)

    worse = [r["cell_m"] for r in rows if r["ours_rms_m"] > RMS_TOLERANCE * r["peer_rms_m"]]
    speed = peer_total / ours_total
    print(f"\nspeed: {speed:.1f}x scipy in total"
          f" ({'meets' if speed >= SPEED_TARGET else 'BELOW'} the {SPEED_TARGET:.0f}x target)")
    if worse:
        print(f"FAIL: our height RMS is more than {RMS_TOLERANCE - 1:.0%} above scipy's at"
              f" {worse} m")
        return 1
    print(f"OK: our height RMS is within {RMS_TOLERANCE - 1:.0%} of scipy's (or better) at every"
          " cell size")
    return 0


if __name__ == "__main__":
    sys.exit(main())
