#!/usr/bin/env python3
"""Peer check of regolith's renderer: ray-cast the same heightfield with Open3D.

Reads the files written by `cargo run -p regolith-validator --release --example bench_render
-- --export DIR`:

* heightfield.json + heightfield.f32: the grid (origin of the centre of the north-west cell,
  cell size, width, height; f32 LE heights, row 0 = north) triangulated exactly as regolith
  does it: each quad between four cell centres split along its NW-SE diagonal.
* view.json: pinhole intrinsics and ground_from_camera (translation, quaternion x y z w;
  camera x right, y down, z forward).
* depth.f32: regolith's undistorted depth (camera z, NaN = nothing seen).

* radiance.f32 + albedo.f32 + view.json's light: regolith's shaded image.

It casts one ray per pixel centre through `open3d.t.geometry.RaycastingScene`, converts the
hit distance to camera z, and prints the RMS and maximum depth difference over the pixels both
renderers see, plus the share of pixels whose hit/miss status differs. Target: RMS <= 1 mm.
It then shades Open3D's hits with the same model written independently here (Lambertian with
an ambient share, Open3D's triangle normal turned upward, albedo bilinear between cell centres
and clamped at the edges) and prints the image RMS against regolith's radiance, in 8-bit grey
levels (radiance x 255). Target: < 0.5 grey level.

Usage: python3 tools/peers/render_open3d.py DIR
"""
import json
import sys
from pathlib import Path

import numpy as np
import open3d as o3d


def quat_to_matrix(q):
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def heightfield_mesh(meta, z):
    w, h, cell = meta["width"], meta["height"], meta["cell_m"]
    ox, oy = meta["origin_m"]
    cols, rows = np.meshgrid(np.arange(w), np.arange(h))
    verts = np.stack([ox + cols * cell, oy - rows * cell, z.reshape(h, w)], axis=-1).reshape(-1, 3)
    r, c = np.meshgrid(np.arange(h - 1), np.arange(w - 1), indexing="ij")
    nw, ne = r * w + c, r * w + c + 1
    sw, se = (r + 1) * w + c, (r + 1) * w + c + 1
    tris = np.concatenate([np.stack([nw, ne, se], -1).reshape(-1, 3), np.stack([nw, se, sw], -1).reshape(-1, 3)])
    finite = np.isfinite(verts[:, 2])
    tris = tris[finite[tris].all(axis=1)]
    # Relative coordinates keep float32 precise (Open3D's scene is float32).
    centre = np.nanmean(verts, axis=0)
    return (verts - centre).astype(np.float32), tris.astype(np.uint32), centre


def main(folder):
    d = Path(folder)
    meta = json.loads((d / "heightfield.json").read_text())
    view = json.loads((d / "view.json").read_text())
    z = np.fromfile(d / "heightfield.f32", dtype="<f4").astype(np.float64)
    ours = np.fromfile(d / "depth.f32", dtype="<f4").reshape(view["height"], view["width"])
    verts, tris, centre = heightfield_mesh(meta, z)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))

    pose = view["ground_from_camera"]
    rot = quat_to_matrix(pose["rotation_xyzw"])
    eye = np.asarray(pose["translation_m"]) - centre
    u, v = np.meshgrid(np.arange(view["width"]), np.arange(view["height"]))
    cam_dirs = np.stack([(u - view["cx"]) / view["fx"], (v - view["cy"]) / view["fy"], np.ones_like(u, dtype=np.float64)], -1)
    dirs = cam_dirs @ rot.T  # ground-frame directions with camera z = 1
    rays = np.concatenate([np.broadcast_to(eye, dirs.shape), dirs], axis=-1).reshape(-1, 6).astype(np.float32)
    t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().reshape(ours.shape).astype(np.float64)
    # With un-normalised directions of camera z = 1, t_hit is the camera z directly.
    theirs = np.where(np.isfinite(t_hit), t_hit, np.nan)

    both = np.isfinite(ours) & np.isfinite(theirs)
    status_differs = np.mean(np.isfinite(ours) != np.isfinite(theirs))
    diff = ours[both] - theirs[both]
    rms = float(np.sqrt(np.mean(diff ** 2)))
    print(f"open3d {o3d.__version__}: {both.sum()} pixels compared, depth RMS {rms * 1e3:.4f} mm, "
          f"max {np.abs(diff).max() * 1e3:.4f} mm, 99th pct {np.percentile(np.abs(diff), 99) * 1e3:.4f} mm, "
          f"hit/miss differs at {status_differs * 100:.3f}% of pixels")
    # The image: shade Open3D's hits independently and compare with regolith's radiance.
    light = view["light"]
    az, el = np.radians(light["azimuth_deg"]), np.radians(light["elevation_deg"])
    to_light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    normals = hits["primitive_normals"].numpy().reshape(ours.shape + (3,)).astype(np.float64)
    normals *= np.where(normals[..., 2:3] < 0, -1.0, 1.0)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True).clip(1e-12)
    points = dirs * t_hit[..., None] + np.asarray(pose["translation_m"])
    am = meta["albedo"]
    alb = np.fromfile(d / am["file"], dtype="<f4").astype(np.float64).reshape(am["height"], am["width"])
    uu = ((points[..., 0] - am["origin_m"][0]) / am["cell_m"]).clip(0, am["width"] - 1)
    vv = ((am["origin_m"][1] - points[..., 1]) / am["cell_m"]).clip(0, am["height"] - 1)
    uu, vv = np.nan_to_num(uu), np.nan_to_num(vv)
    c0, r0 = np.floor(uu).astype(int), np.floor(vv).astype(int)
    c1, r1 = np.minimum(c0 + 1, am["width"] - 1), np.minimum(r0 + 1, am["height"] - 1)
    fu, fv = uu - c0, vv - r0
    albedo = ((1 - fu) * (1 - fv) * alb[r0, c0] + fu * (1 - fv) * alb[r0, c1]
              + (1 - fu) * fv * alb[r1, c0] + fu * fv * alb[r1, c1])
    n_dot_l = np.clip((normals * to_light).sum(-1), 0.0, None)
    peer = albedo * (light["ambient"] + (1 - light["ambient"]) * n_dot_l)
    ours_rad = np.fromfile(d / "radiance.f32", dtype="<f4").astype(np.float64).reshape(ours.shape)
    dimg = (ours_rad[both] - peer[both]) * 255.0
    img_rms = float(np.sqrt(np.mean(dimg ** 2)))
    print(f"image: {both.sum()} pixels compared, RMS {img_rms:.4f} grey levels, "
          f"99th pct {np.percentile(np.abs(dimg), 99):.4f}, max {np.abs(dimg).max():.3f} "
          f"(mean radiance ours {ours_rad[both].mean():.4f}, Open3D-shaded {peer[both].mean():.4f})")
    return 0 if rms <= 1e-3 and img_rms < 0.5 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "target/peer-render"))
