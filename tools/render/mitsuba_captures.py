#!/usr/bin/env python3
"""Render physically based "real" camera captures of a regolith corpus scene with Mitsuba 3.

Why: regolith's own renderer is a fast direct-lighting shader (Lambert + ambient share). Real
testbed photographs also contain indirect light (rock-to-rock and wall-to-rock bounces), the
soft shadows of a finite lamp, a lab hall above the horizon and a non-Lambertian regolith. This
tool renders the scene description that the Rust corpus generator writes with Mitsuba's path
tracer so that those effects are present in the images the pipeline is tested on.

    python3 tools/render/mitsuba_captures.py SCENE.json OUT_DIR [--spp N] [--variant V]
                                             [--threads N] [--only SHOT_NAME]
    python3 tools/render/mitsuba_captures.py --self-test

Outputs, per shot, OUT_DIR/<shot name>.exr: one float32 channel named `Y`, linear radiance in
the scene's units (a white Lambertian surface facing the lamp at its target reads
irradiance/pi from the lamp; 1.0 is mapped to 255 DN by the Rust camera model), row 0 = image
top. OUT_DIR/renders.json records renderer, version, variant, spp, integrator, terrain BSDF and
per-shot timings (keys sorted).

Model (see tools/render/README.md for the JSON schema):
* integrator `path`, max_depth 4 (two indirect bounces), emitters visible;
* lamp: one-sided `rectangle` area emitter of side size_m facing the target, radiance chosen so
  that the on-axis irradiance at the target equals `irradiance` (exact square-source formula),
  with a dark housing box behind it; ambient: `constant` environment emitter, visible through
  the open top of the hall (there is no ceiling);
* terrain: the PLY mesh with a Python Oren-Nayar BSDF (qualitative model, Oren & Nayar 1994)
  textured by the albedo EXR (u right, v down, bilinear, raw linear values);
* hall: floor, four walls (procedural, seeded textures), a border frame around the bed and
  box/cylinder objects, all Lambertian; marker spheres Lambertian;
* camera: OpenCV pinhole (x right, y down, z forward; pixel centres at integers) converted to
  Mitsuba's `perspective` sensor (x left, y up, z forward; film coordinates in [0, 1]):
      to_world = ground_from_camera . diag(-1, -1, 1)
      fov (x axis) = 2 atan(W / (2 fx)), requires fx == fy (relative 1e-6)
      principal_point_offset_x = ((W - 1)/2 - cx) / W
      principal_point_offset_y = ((H - 1)/2 - cy) / H
  `--self-test` proves this by projecting a marker sphere for two principal points.

Variants: llvm_ad_mono (fast; needs libLLVM >= 16, e.g. Debian's libllvm19, located through
DRJIT_LIBLLVM_PATH) is preferred, then llvm_ad_rgb, then scalar_rgb (very slow with the Python
BSDF). Exit codes: 0 success, 1 self-test failure, 2 bad scene file / arguments, 3 mitsuba
missing.
"""
import argparse
import glob
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    import numpy as np
except ImportError:
    print("numpy is not installed: run tools/render/install.sh", file=sys.stderr)
    sys.exit(3)

PREFERRED_VARIANTS = ("llvm_ad_mono", "llvm_ad_rgb", "scalar_rgb")
INTEGRATOR = {"type": "path", "max_depth": 4, "hide_emitters": False}
HOUSING_DEPTH_M = 0.12
HOUSING_ALBEDO = 0.05
SCENE_FORMAT = "regolith-corpus-scene/1"


class SceneError(Exception):
    """A scene file that cannot be rendered; the message names the file and the key."""


# ----------------------------------------------------------------------------------------------
# Mitsuba set-up
# ----------------------------------------------------------------------------------------------

def set_llvm_library_path():
    """Point Dr.Jit at a libLLVM it can use (LLVM 15 aborts; 16+ works), unless already set."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    for pattern in ("/usr/lib/x86_64-linux-gnu/libLLVM.so.1[6-9]*", "/usr/lib/x86_64-linux-gnu/libLLVM-1[6-9].so*",
                    "/usr/lib/llvm-1[6-9]/lib/libLLVM*.so*"):
        found = sorted(glob.glob(pattern))
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found[-1]
            return


def variant_works(variant):
    """Probe a variant in a child process: a broken LLVM aborts the process instead of raising."""
    probe = ("import mitsuba as mi, drjit as dr\n"
             f"mi.set_variant({variant!r})\n"
             "print(dr.arange(mi.Float, 8) * 2)\n")
    try:
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=300)
    except subprocess.TimeoutExpired:
        return False
    return done.returncode == 0


def import_mitsuba():
    set_llvm_library_path()
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        print("mitsuba is not installed: run tools/render/install.sh", file=sys.stderr)
        sys.exit(3)
    return mi, dr


def select_variant(mi, requested):
    """Set the requested variant, or the first working one of PREFERRED_VARIANTS."""
    available = mi.variants()
    if requested:
        if requested not in available:
            raise SceneError(f"--variant {requested}: not in this mitsuba build ({', '.join(available)})")
        if requested.startswith("llvm") and not variant_works(requested):
            raise SceneError(f"--variant {requested}: the LLVM backend does not start "
                             f"(DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH')}); run tools/render/install.sh")
        mi.set_variant(requested)
        return requested
    for variant in PREFERRED_VARIANTS:
        if variant in available and (not variant.startswith("llvm") or variant_works(variant)):
            if variant.startswith("scalar"):
                print("warning: no LLVM variant works (install libllvm19, see install.sh); "
                      "falling back to scalar_rgb, which is slow with the Python BSDF", file=sys.stderr)
            mi.set_variant(variant)
            return variant
    raise SceneError(f"no usable mitsuba variant among {', '.join(available)}")


def register_oren_nayar(mi, dr):
    """Register the Python BSDF `oren_nayar_py` (needs the variant to be set already)."""

    class OrenNayar(mi.BSDF):
        """Qualitative Oren-Nayar rough diffuse reflection (Oren & Nayar 1994).

        f = albedo/pi (A + B max(0, cos(phi_i - phi_o)) sin(alpha) tan(beta)), alpha = max(theta),
        beta = min(theta), A = 1 - 0.5 s^2/(s^2 + 0.33), B = 0.45 s^2/(s^2 + 0.09), s = sigma in
        radians. In the local frame cos(dphi) sin(alpha) tan(beta) equals
        (wi.x wo.x + wi.y wo.y) / max(cos theta_i, cos theta_o), which has no singularity.
        sigma = 0 is exactly Lambert. One-sided like Mitsuba's `diffuse`; cosine-weighted sampling.
        """

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.reflectance = props["reflectance"]
            sigma = math.radians(float(props["sigma_deg"]))
            s2 = sigma * sigma
            self.a = 1.0 - 0.5 * s2 / (s2 + 0.33)
            self.b = 0.45 * s2 / (s2 + 0.09)
            flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        def _shape(self, si, wo):
            """(A + B * angular term) and the mask of valid (both upper hemisphere) pairs."""
            cos_i = mi.Frame3f.cos_theta(si.wi)
            cos_o = mi.Frame3f.cos_theta(wo)
            valid = (cos_i > 0.0) & (cos_o > 0.0)
            dot_xy = si.wi.x * wo.x + si.wi.y * wo.y
            term = dr.maximum(dot_xy, 0.0) / dr.maximum(dr.maximum(cos_i, cos_o), 1e-7)
            return self.a + self.b * term, valid, cos_o

        def sample(self, ctx, si, sample1, sample2, active):
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs.pdf = mi.warp.square_to_cosine_hemisphere_pdf(bs.wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
            bs.sampled_component = mi.UInt32(0)
            shape, valid, _ = self._shape(si, bs.wo)
            active = active & valid & (bs.pdf > 0.0)
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection):
                active = mi.Bool(False)
            # f cos / pdf = albedo/pi * shape * cos / (cos/pi) = albedo * shape
            weight = self.reflectance.eval(si, active) * shape
            bs.pdf = dr.select(active, bs.pdf, 0.0)
            return bs, dr.select(active, weight, 0.0)

        def eval(self, ctx, si, wo, active):
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection):
                return mi.Spectrum(0.0)
            shape, valid, cos_o = self._shape(si, wo)
            active = active & valid
            value = self.reflectance.eval(si, active) * (shape * dr.inv_pi * cos_o)
            return dr.select(active, value, 0.0)

        def pdf(self, ctx, si, wo, active):
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection):
                return mi.Float(0.0)
            valid = (mi.Frame3f.cos_theta(si.wi) > 0.0) & (mi.Frame3f.cos_theta(wo) > 0.0)
            return dr.select(active & valid, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

        def eval_pdf(self, ctx, si, wo, active):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def traverse(self, callback):
            pass  # nothing is differentiated or edited after loading

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"OrenNayar[A={self.a:.4f}, B={self.b:.4f}]"

    mi.register_bsdf("oren_nayar_py", lambda props: OrenNayar(props))


# ----------------------------------------------------------------------------------------------
# Scene file
# ----------------------------------------------------------------------------------------------

class Reader:
    """Typed access to the scene JSON; every failure names the file and the dotted key."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            self.root = json.loads(self.path.read_text())
        except (OSError, ValueError) as err:
            raise SceneError(f"{self.path}: cannot read scene JSON: {err}") from None
        if self.get(self.root, "format", str, "") != SCENE_FORMAT:
            self.fail("format", f"expected {SCENE_FORMAT!r}")

    def fail(self, key, why):
        raise SceneError(f"{self.path}: key '{key}': {why}")

    def get(self, obj, key, kind, prefix):
        name = f"{prefix}.{key}" if prefix else key
        if not isinstance(obj, dict) or key not in obj:
            self.fail(name, "missing")
        value = obj[key]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                self.fail(name, f"expected a finite number, got {value!r}")
            return float(value)
        if kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                self.fail(name, f"expected an integer, got {value!r}")
            return value
        if not isinstance(value, kind):
            self.fail(name, f"expected {kind.__name__}, got {type(value).__name__}")
        return value

    def vec(self, obj, key, n, prefix):
        name = f"{prefix}.{key}" if prefix else key
        value = self.get(obj, key, list, prefix)
        arr = np.asarray(value, dtype=object)
        if arr.shape != (n,) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
            self.fail(name, f"expected {n} numbers")
        out = np.asarray(value, dtype=np.float64)
        if not np.all(np.isfinite(out)):
            self.fail(name, "non-finite value")
        return out

    def file(self, obj, key, prefix):
        path = self.path.parent / self.get(obj, key, str, prefix)
        if not path.is_file():
            self.fail(f"{prefix}.{key}", f"file {path} not found")
        return path


def parse_scene(path):
    """Read and check the scene JSON into plain Python/numpy values."""
    r = Reader(path)
    root = r.root
    terrain = r.get(root, "terrain", dict, "")
    bsdf = r.get(terrain, "bsdf", dict, "terrain")
    if r.get(bsdf, "model", str, "terrain.bsdf") != "oren-nayar":
        r.fail("terrain.bsdf.model", "only 'oren-nayar' is supported")
    sigma = r.get(bsdf, "sigma_deg", float, "terrain.bsdf")
    if not 0.0 <= sigma <= 90.0:
        r.fail("terrain.bsdf.sigma_deg", "must be in [0, 90]")
    scene = {
        "terrain": {"mesh": r.file(terrain, "mesh", "terrain"), "albedo": r.file(terrain, "albedo", "terrain"),
                    "sigma_deg": sigma},
        "spheres": [], "room": None, "shots": [],
    }
    for i, s in enumerate(r.get(root, "spheres", list, "")):
        p = f"spheres[{i}]"
        scene["spheres"].append({"centre": r.vec(s, "centre", 3, p), "radius": r.get(s, "radius", float, p),
                                 "albedo": r.get(s, "albedo", float, p)})
    lamp = r.get(root, "lamp", dict, "")
    scene["lamp"] = {"position": r.vec(lamp, "position", 3, "lamp"), "target": r.vec(lamp, "target", 3, "lamp"),
                     "size_m": r.get(lamp, "size_m", float, "lamp"),
                     "irradiance": r.get(lamp, "irradiance", float, "lamp")}
    if scene["lamp"]["size_m"] <= 0 or np.linalg.norm(scene["lamp"]["target"] - scene["lamp"]["position"]) <= 0:
        r.fail("lamp", "size_m must be > 0 and target must differ from position")
    scene["ambient"] = r.get(r.get(root, "ambient", dict, ""), "radiance", float, "ambient")
    if "room" in root:
        room = r.get(root, "room", dict, "")
        p = "room"
        parsed = {k: r.get(room, k, float, p) for k in ("floor_z", "border_height", "border_width", "border_albedo",
                                                       "wall_height", "wall_albedo", "floor_albedo")}
        parsed["bed"] = r.vec(room, "bed", 4, p)
        parsed["walls"] = r.vec(room, "walls", 4, p)
        parsed["texture_seed"] = r.get(room, "texture_seed", int, p)
        parsed["objects"] = []
        for i, o in enumerate(r.get(room, "objects", list, p)):
            q = f"room.objects[{i}]"
            kind = r.get(o, "type", str, q)
            if kind == "box":
                obj = {"type": "box", "min": r.vec(o, "min", 3, q), "max": r.vec(o, "max", 3, q)}
                if np.any(obj["max"] <= obj["min"]):
                    r.fail(q, "max must exceed min on every axis")
            elif kind == "cylinder":
                obj = {"type": "cylinder", "p0": r.vec(o, "p0", 3, q), "p1": r.vec(o, "p1", 3, q),
                       "radius": r.get(o, "radius", float, q)}
            else:
                r.fail(f"{q}.type", f"unknown object type {kind!r} (box, cylinder)")
            obj["albedo"] = r.get(o, "albedo", float, q)
            parsed["objects"].append(obj)
        scene["room"] = parsed
    names = set()
    for i, s in enumerate(r.get(root, "shots", list, "")):
        p = f"shots[{i}]"
        shot = {"name": r.get(s, "name", str, p), "seed": r.get(s, "seed", int, p),
                "width": r.get(s, "width", int, p), "height": r.get(s, "height", int, p)}
        for k in ("fx", "fy", "cx", "cy"):
            shot[k] = r.get(s, k, float, p)
        if not shot["name"] or "/" in shot["name"] or shot["name"] in names:
            r.fail(f"{p}.name", "must be a unique non-empty file name")
        names.add(shot["name"])
        if shot["width"] <= 0 or shot["height"] <= 0 or shot["fx"] <= 0:
            r.fail(p, "width, height and fx must be positive")
        if abs(shot["fx"] - shot["fy"]) > 1e-6 * shot["fx"]:
            r.fail(f"{p}.fy", f"Mitsuba's perspective sensor has square pixels: fx ({shot['fx']}) must equal fy "
                              f"({shot['fy']}) within 1e-6 relative")
        m = np.asarray(r.get(s, "ground_from_camera", list, p), dtype=object)
        try:
            m = np.asarray(m.tolist(), dtype=np.float64)
        except (TypeError, ValueError):
            r.fail(f"{p}.ground_from_camera", "expected a 4x4 matrix of numbers")
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            r.fail(f"{p}.ground_from_camera", "expected a 4x4 matrix of numbers")
        rot = m[:3, :3]
        if np.abs(rot.T @ rot - np.eye(3)).max() > 1e-5 or np.linalg.det(rot) < 0 or \
                np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
            r.fail(f"{p}.ground_from_camera", "rotation part must be orthonormal with det +1, last row 0 0 0 1")
        shot["ground_from_camera"] = m
        scene["shots"].append(shot)
    return scene


# ----------------------------------------------------------------------------------------------
# Geometry helpers
# ----------------------------------------------------------------------------------------------

def frame_for_normal(n):
    """Unit vectors (a, b) with a x b = n, so a shape's local +z maps to n."""
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[2]) > 0.9 else np.array([0.0, 0.0, 1.0])
    a = np.cross(helper, n)
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


def affine(cols, origin):
    """4x4 matrix whose first three columns are `cols` and whose translation is `origin`."""
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = cols
    m[:3, 3] = origin
    return m


def square_lamp_factor(size, distance):
    """E / L on the axis of a square Lambertian emitter of side `size` at `distance`, facing it.

    Sum of the four quadrant point-to-rectangle configuration factors: E = 4 L X/sqrt(1+X^2)
    atan(X/sqrt(1+X^2)), X = size / (2 distance). Tends to size^2/distance^2 for a small lamp.
    """
    x = size / (2.0 * distance)
    q = x / math.sqrt(1.0 + x * x)
    return 4.0 * q * math.atan(q)


def lamp_radiance(lamp):
    distance = float(np.linalg.norm(lamp["target"] - lamp["position"]))
    return lamp["irradiance"] / square_lamp_factor(lamp["size_m"], distance)


def camera_to_mitsuba(shot):
    """Mitsuba `perspective` parameters reproducing the OpenCV pinhole of `shot` (see docstring)."""
    w, h = shot["width"], shot["height"]
    to_world = shot["ground_from_camera"] @ np.diag([-1.0, -1.0, 1.0, 1.0])
    return {
        "fov": math.degrees(2.0 * math.atan(w / (2.0 * shot["fx"]))),
        "principal_point_offset_x": ((w - 1) / 2.0 - shot["cx"]) / w,
        "principal_point_offset_y": ((h - 1) / 2.0 - shot["cy"]) / h,
        "to_world": to_world,
    }


# ----------------------------------------------------------------------------------------------
# Procedural hall textures
# ----------------------------------------------------------------------------------------------

def value_noise(rng, rows, cols, cell_px):
    """Bilinearly interpolated random lattice with spacing cell_px pixels, values in [0, 1]."""
    gy, gx = rows // cell_px + 2, cols // cell_px + 2
    grid = rng.random((gy + 1, gx + 1))
    y = np.arange(rows) / cell_px
    x = np.arange(cols) / cell_px
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    fy, fx = (y - y0)[:, None], (x - x0)[None, :]
    g00, g01 = grid[y0][:, x0], grid[y0][:, x0 + 1]
    g10, g11 = grid[y0 + 1][:, x0], grid[y0 + 1][:, x0 + 1]
    return (g00 * (1 - fx) + g01 * fx) * (1 - fy) + (g10 * (1 - fx) + g11 * fx) * fy


def hall_texture(rng, width_m, height_m, mean_albedo, kind):
    """Grey albedo image (row 0 = top of a wall / one floor edge) with panels, stains, posters."""
    px_per_m = min(64.0, 2048.0 / max(width_m, height_m))
    cols, rows = max(8, int(round(width_m * px_per_m))), max(8, int(round(height_m * px_per_m)))
    tex = np.ones((rows, cols))
    for cell_m, amp in ((2.0, 0.25), (0.5, 0.15), (0.12, 0.10), (0.03, 0.06)):
        tex += amp * (value_noise(rng, rows, cols, max(2, int(cell_m * px_per_m))) - 0.5)
    yy, xx = np.mgrid[0:rows, 0:cols] / px_per_m  # metres from the top-left corner
    seam = max(1, int(0.012 * px_per_m))
    if kind == "wall":
        panel = rng.uniform(1.0, 1.4)
        tex[:, (np.arange(cols) % int(panel * px_per_m)) < seam] *= 0.55
        tex[yy > height_m - 0.15] *= 0.45  # skirting board
        for _ in range(rng.integers(2, 7)):  # posters, notice boards, doors
            w, h = rng.uniform(0.3, 1.1), rng.uniform(0.4, 1.4)
            x0, top = rng.uniform(0, max(0.01, width_m - w)), height_m - rng.uniform(1.0, 2.4) - h / 2
            inside = (xx >= x0) & (xx < x0 + w) & (yy >= top) & (yy < top + h)
            tex[inside] *= rng.uniform(0.25, 1.7) * (1 + 0.3 * (value_noise(rng, rows, cols, 6)[inside] - 0.5))
    else:
        tile = rng.uniform(0.5, 0.7)
        tex[:, (np.arange(cols) % int(tile * px_per_m)) < seam] *= 0.6
        tex[(np.arange(rows) % int(tile * px_per_m)) < seam, :] *= 0.6
    for _ in range(rng.integers(4, 12)):  # stains
        cx, cy, r = rng.uniform(0, width_m), rng.uniform(0, height_m), rng.uniform(0.05, 0.6)
        tex *= 1 - rng.uniform(0.1, 0.4) * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * r * r))
    for _ in range(2):  # clip to physical albedo, keep the requested mean
        tex = np.clip(tex * (mean_albedo / tex.mean()), 0.01, 0.95)
    return tex.astype(np.float32)


# ----------------------------------------------------------------------------------------------
# Mitsuba scene
# ----------------------------------------------------------------------------------------------

def bitmap_texture(mi, image):
    """Raw (linear) bilinear texture of a (rows, cols) float image; uv (0,0) = row 0, col 0."""
    bmp = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32)[:, :, None], pixel_format=mi.Bitmap.PixelFormat.Y)
    return {"type": "bitmap", "bitmap": bmp, "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp"}


def diffuse(albedo):
    return {"type": "diffuse", "reflectance": albedo}


def load_albedo(mi, path):
    try:
        bmp = mi.Bitmap(str(path))
    except RuntimeError as err:
        raise SceneError(f"terrain.albedo: cannot read {path}: {err}") from None
    img = np.array(bmp, dtype=np.float32)
    if img.ndim == 3:
        if img.shape[2] != 1:
            raise SceneError(f"terrain.albedo: {path} has {img.shape[2]} channels, expected one 'Y' channel")
        img = img[:, :, 0]
    return img


def terrain_shape(mi, terrain, albedo):
    """The terrain PLY with the Oren-Nayar BSDF; normals flipped if the mesh winds clockwise."""
    mesh = {"type": "ply", "filename": str(terrain["mesh"]), "face_normals": False}
    try:
        probe = mi.load_dict(mesh)
    except RuntimeError as err:
        raise SceneError(f"terrain.mesh: cannot load {terrain['mesh']}: {err}") from None
    if not probe.has_vertex_texcoords():
        raise SceneError(f"terrain.mesh: {terrain['mesh']} has no u,v vertex properties")
    params = mi.traverse(probe)
    v = np.array(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    f = np.array(params["faces"], dtype=np.int64).reshape(-1, 3)
    up = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])[:, 2].sum()
    mesh["flip_normals"] = bool(up < 0)
    mesh["bsdf"] = {"type": "oren_nayar_py", "reflectance": bitmap_texture(mi, albedo),
                    "sigma_deg": terrain["sigma_deg"]}
    return mesh


def room_shapes(mi, room):
    """Floor, walls, bed border frame and objects of the lab hall (all Lambertian)."""
    rng = np.random.default_rng(room["texture_seed"])
    shapes = {}
    x0, y0, x1, y1 = room["walls"]
    z0, wh = room["floor_z"], room["wall_height"]
    shapes["room_floor"] = {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f(affine(((x1 - x0) / 2 * np.array([1.0, 0, 0]), (y1 - y0) / 2 * np.array([0, 1.0, 0]),
                                                 np.array([0, 0, 1.0])), [(x0 + x1) / 2, (y0 + y1) / 2, z0])),
        "bsdf": {"type": "diffuse", "reflectance": bitmap_texture(
            mi, hall_texture(rng, x1 - x0, y1 - y0, room["floor_albedo"], "floor"))},
    }
    down = np.array([0.0, 0.0, -1.0])
    for name, centre, inward, length in (("south", [(x0 + x1) / 2, y0], [0, 1.0, 0], x1 - x0),
                                         ("north", [(x0 + x1) / 2, y1], [0, -1.0, 0], x1 - x0),
                                         ("west", [x0, (y0 + y1) / 2], [1.0, 0, 0], y1 - y0),
                                         ("east", [x1, (y0 + y1) / 2], [-1.0, 0, 0], y1 - y0)):
        n = np.array(inward)
        along = np.cross(down, n)  # along x down = n: local +y runs down the wall (texture row 0 = top)
        shapes[f"room_wall_{name}"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f(affine((along * length / 2, down * wh / 2, n), [*centre, z0 + wh / 2])),
            "bsdf": {"type": "diffuse", "reflectance": bitmap_texture(
                mi, hall_texture(rng, length, wh, room["wall_albedo"], "wall"))},
        }
    bx0, by0, bx1, by1 = room["bed"]
    bw = room["border_width"]
    boxes = [([bx0 - bw, by0 - bw], [bx1 + bw, by0]), ([bx0 - bw, by1], [bx1 + bw, by1 + bw]),
             ([bx0 - bw, by0], [bx0, by1]), ([bx1, by0], [bx1 + bw, by1])]
    for i, (lo, hi) in enumerate(boxes):
        shapes[f"room_border_{i}"] = box_shape(mi, [*lo, z0], [*hi, room["border_height"]], room["border_albedo"])
    for i, obj in enumerate(room["objects"]):
        if obj["type"] == "box":
            shapes[f"room_object_{i}"] = box_shape(mi, obj["min"], obj["max"], obj["albedo"])
        else:
            shapes.update(cylinder_shapes(mi, f"room_object_{i}", obj))
    return shapes


def box_shape(mi, lo, hi, albedo):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    half = (hi - lo) / 2
    return {"type": "cube", "to_world": mi.ScalarTransform4f(affine(np.diag(half), (lo + hi) / 2)), "bsdf": diffuse(albedo)}


def cylinder_shapes(mi, name, obj):
    """Mitsuba's `cylinder` is open: close it with two disks facing outward."""
    axis = obj["p1"] - obj["p0"]
    r = obj["radius"]
    shapes = {name: {"type": "cylinder", "p0": obj["p0"].tolist(), "p1": obj["p1"].tolist(), "radius": r,
                     "bsdf": diffuse(obj["albedo"])}}
    for end, point, n in (("cap0", obj["p0"], -axis), ("cap1", obj["p1"], axis)):
        a, b = frame_for_normal(n)
        shapes[f"{name}_{end}"] = {"type": "disk", "to_world": mi.ScalarTransform4f(
            affine((a * r, b * r, n / np.linalg.norm(n)), point)), "bsdf": diffuse(obj["albedo"])}
    return shapes


def scene_dict(mi, scene):
    """The Mitsuba scene (without sensors) for a parsed scene file."""
    d = {"type": "scene", "integrator": dict(INTEGRATOR)}
    d["terrain"] = terrain_shape(mi, scene["terrain"], load_albedo(mi, scene["terrain"]["albedo"]))
    for i, s in enumerate(scene["spheres"]):
        d[f"sphere_{i}"] = {"type": "sphere", "center": s["centre"].tolist(), "radius": s["radius"],
                            "bsdf": diffuse(s["albedo"])}
    lamp = scene["lamp"]
    n = lamp["target"] - lamp["position"]
    n /= np.linalg.norm(n)
    a, b = frame_for_normal(n)
    half = lamp["size_m"] / 2
    d["lamp"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(affine((a * half, b * half, n), lamp["position"])),
                 "emitter": {"type": "area", "radiance": lamp_radiance(lamp)}}
    d["lamp_housing"] = {"type": "cube", "bsdf": diffuse(HOUSING_ALBEDO), "to_world": mi.ScalarTransform4f(
        affine((a * half, b * half, n * HOUSING_DEPTH_M / 2), lamp["position"] - n * (HOUSING_DEPTH_M / 2 + 0.002)))}
    d["ambient"] = {"type": "constant", "radiance": scene["ambient"]}
    if scene["room"] is not None:
        d.update(room_shapes(mi, scene["room"]))
    return d


def sensor_dict(mi, shot, variant, spp):
    cam = camera_to_mitsuba(shot)
    return {
        "type": "perspective", "fov_axis": "x", "fov": cam["fov"],
        "principal_point_offset_x": cam["principal_point_offset_x"],
        "principal_point_offset_y": cam["principal_point_offset_y"],
        "near_clip": 0.005, "far_clip": 1.0e4,
        "to_world": mi.ScalarTransform4f(cam["to_world"]),
        "sampler": {"type": "multijitter", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": shot["width"], "height": shot["height"], "rfilter": {"type": "box"},
                 "pixel_format": "luminance" if "mono" in variant else "rgb", "component_format": "float32"},
    }


def render_shot(mi, scene_obj, shot, variant, spp):
    """Linear luminance image (height, width) float32 of one shot."""
    sensor = mi.load_dict(sensor_dict(mi, shot, variant, spp))
    img = np.array(mi.render(scene_obj, sensor=sensor, spp=spp, seed=shot["seed"]), dtype=np.float64)
    if img.shape[2] == 1:
        y = img[:, :, 0]
    else:  # Rec. 709 luminance of linear RGB
        y = 0.2126 * img[:, :, 0] + 0.7152 * img[:, :, 1] + 0.0722 * img[:, :, 2]
    return y.astype(np.float32)


def write_exr_y(mi, path, image):
    mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32)[:, :, None],
              pixel_format=mi.Bitmap.PixelFormat.Y).write(str(path))


def exr_channels_and_size(path):
    """(channel list [(name, pixel type)], (width, height)) from an OpenEXR header; type 2 = FLOAT."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path} is not an OpenEXR file")
    pos, channels, size = 8, [], None
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        kind = data[end + 1:tend].decode()
        (length,) = struct.unpack_from("<i", data, tend + 1)
        value = data[tend + 5:tend + 5 + length]
        if name == "channels" and kind == "chlist":
            p = 0
            while value[p] != 0:
                e = value.index(b"\0", p)
                channels.append((value[p:e].decode(), struct.unpack_from("<i", value, e + 1)[0]))
                p = e + 1 + 16
        elif name == "dataWindow" and kind == "box2i":
            xmin, ymin, xmax, ymax = struct.unpack("<4i", value)
            size = (xmax - xmin + 1, ymax - ymin + 1)
        pos = tend + 5 + length
    return channels, size


# ----------------------------------------------------------------------------------------------
# Command line
# ----------------------------------------------------------------------------------------------

def render_scene_file(args):
    scene_path = Path(args.scene)
    scene = parse_scene(scene_path)
    shots = scene["shots"]
    if args.only is not None:
        shots = [s for s in shots if s["name"] == args.only]
        if not shots:
            raise SceneError(f"{scene_path}: key 'shots': no shot named {args.only!r}")
    mi, dr = import_mitsuba()
    variant = select_variant(mi, args.variant)
    if args.threads:
        dr.set_thread_count(args.threads)
    register_oren_nayar(mi, dr)
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    scene_obj = mi.load_dict(scene_dict(mi, scene))
    print(f"scene loaded in {time.perf_counter() - t0:.1f} s (variant {variant}, spp {args.spp})", file=sys.stderr)
    records = []
    for i, shot in enumerate(shots, 1):
        t = time.perf_counter()
        image = render_shot(mi, scene_obj, shot, variant, args.spp)
        write_exr_y(mi, out / f"{shot['name']}.exr", image)
        seconds = time.perf_counter() - t
        records.append({"name": shot["name"], "file": f"{shot['name']}.exr", "seconds": round(seconds, 3)})
        print(f"shot {i}/{len(shots)} {shot['name']} {seconds:.1f} s", file=sys.stderr)
    meta = {
        "renderer": "mitsuba", "mitsuba_version": mi.__version__, "variant": variant, "spp": args.spp,
        "integrator": INTEGRATOR, "threads": args.threads or os.cpu_count(),
        "lamp_radiance": lamp_radiance(scene["lamp"]),
        "bsdf": {"terrain": {"model": "oren-nayar", "sigma_deg": scene["terrain"]["sigma_deg"]}},
        "shots": records, "python": sys.version,
    }
    (out / "renders.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return 0


# ----------------------------------------------------------------------------------------------
# Self-test
# ----------------------------------------------------------------------------------------------

def write_ply(path, verts, uv, faces):
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float u\nproperty float v\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as fh:
        fh.write(header.encode())
        fh.write(np.hstack([verts, uv]).astype("<f4").tobytes())
        rec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
        rec["n"], rec["i"] = 3, faces
        fh.write(rec.tobytes())


def look_from(eye, target, roll_deg):
    """ground_from_camera (OpenCV axes) for a camera at `eye` looking at `target`, rolled."""
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = math.cos(math.radians(roll_deg)), math.sin(math.radians(roll_deg))
    x, y = c * x + s * y, -s * x + c * y
    return affine((x, y, z), eye)


def oren_nayar_f(albedo, sigma_deg, wi, wo):
    """Reference BRDF in numpy (surface normal +z), for the analytic expectations."""
    s2 = math.radians(sigma_deg) ** 2
    a, b = 1 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)
    term = np.maximum(wi[..., 0] * wo[0] + wi[..., 1] * wo[1], 0) / np.maximum(np.maximum(wi[..., 2], wo[2]), 1e-9)
    return albedo / math.pi * (a + b * term)


def expected_radiance(scene, point, eye, albedo, sigma_deg):
    """Radiance towards `eye` of a horizontal terrain point lit by the lamp and the sky.

    The lamp is integrated over its area (64x64 midpoints); the sky over the upper hemisphere,
    minus the solid angle the lamp covers. Interreflections and the lamp housing are ignored.
    """
    wo = (eye - point) / np.linalg.norm(eye - point)
    lamp = scene["lamp"]
    n = (lamp["target"] - lamp["position"]) / np.linalg.norm(lamp["target"] - lamp["position"])
    a, b = frame_for_normal(n)
    k = (np.arange(64) + 0.5) / 64 - 0.5
    qa, qb = np.meshgrid(k * lamp["size_m"], k * lamp["size_m"])
    q = lamp["position"] + qa[..., None] * a + qb[..., None] * b
    d = q - point
    r = np.linalg.norm(d, axis=-1)
    wi = d / r[..., None]
    geom = np.clip(wi[..., 2], 0, None) * np.clip(-(wi @ n), 0, None) / r ** 2 * (lamp["size_m"] / 64) ** 2
    f_lamp = oren_nayar_f(albedo, sigma_deg, wi, wo)
    lamp_l = lamp_radiance(lamp)
    th = (np.arange(256) + 0.5) / 256 * math.pi / 2
    ph = (np.arange(512) + 0.5) / 512 * 2 * math.pi
    th, ph = np.meshgrid(th, ph, indexing="ij")
    sky = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    sky_int = (oren_nayar_f(albedo, sigma_deg, sky, wo) * np.cos(th) * np.sin(th)).sum() * (math.pi / 2 / 256) * (
        2 * math.pi / 512)
    return (lamp_l - scene["ambient"]) * (f_lamp * geom).sum() + scene["ambient"] * sky_int


def project(shot, p):
    cam = np.linalg.inv(shot["ground_from_camera"]) @ np.append(p, 1.0)
    return np.array([shot["fx"] * cam[0] / cam[2] + shot["cx"], shot["fy"] * cam[1] / cam[2] + shot["cy"]])


def ground_point(shot, u, v):
    """Where the ray through pixel (u, v) meets the plane z = 0."""
    g = shot["ground_from_camera"]
    d = g[:3, :3] @ np.array([(u - shot["cx"]) / shot["fx"], (v - shot["cy"]) / shot["fy"], 1.0])
    t = -g[2, 3] / d[2]
    return g[:3, 3] + t * d


def self_test(args):
    mi, dr = import_mitsuba()
    variant = select_variant(mi, args.variant)
    if args.threads:
        dr.set_thread_count(args.threads)
    register_oren_nayar(mi, dr)
    print(f"self-test with mitsuba {mi.__version__}, variant {variant}", file=sys.stderr)
    failures = []

    def check(ok, what):
        print(f"{'PASS' if ok else 'FAIL'} {what}")
        if not ok:
            failures.append(what)

    tmp_dir = tempfile.TemporaryDirectory(prefix="mitsuba_selftest_")  # removed at exit
    tmp = Path(tmp_dir.name)
    n = 11
    g = np.linspace(-1.0, 1.0, n)
    xx, yy = np.meshgrid(g, g)
    verts = np.stack([xx.ravel(), yy.ravel(), np.zeros(n * n)], 1)
    uv = np.stack([(xx.ravel() + 1) / 2, (1 - yy.ravel()) / 2], 1)
    idx = np.arange(n * n).reshape(n, n)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    write_ply(tmp / "terrain.ply", verts, uv, faces)
    write_exr_y(mi, tmp / "albedo.exr", np.full((16, 16), 0.5, np.float32))

    # Texture orientation: uv (0, 0) must read image row 0 (the top), u along columns.
    tex_img = np.zeros((4, 4), np.float32)
    tex_img[0, :] = 1.0
    tex_img[:, 0] += 0.5
    tex = mi.load_dict(bitmap_texture(mi, tex_img))
    si = dr.zeros(mi.SurfaceInteraction3f, 4)
    si.uv = mi.Point2f([0.1, 0.9, 0.1, 0.9], [0.1, 0.1, 0.9, 0.9])
    got = np.array(tex.eval(si)).reshape(4, -1)[:, 0]
    check(np.allclose(got, [1.5, 1.0, 0.5, 0.0], atol=1e-5), f"albedo texture: v=0 is the top row, u runs along "
                                                            f"columns (samples {np.round(got, 3).tolist()})")

    sphere_c = [0.22, 0.12, 0.05]
    target = np.array([0.0, 0.0, 0.0])
    eye = target + 1.5 * np.array([math.cos(math.radians(200)) * math.cos(math.radians(45)),
                                   math.sin(math.radians(200)) * math.cos(math.radians(45)), math.sin(math.radians(45))])
    gfc = look_from(eye, target, 12.0)
    base = {
        "format": SCENE_FORMAT,
        "terrain": {"mesh": "terrain.ply", "albedo": "albedo.exr", "bsdf": {"model": "oren-nayar", "sigma_deg": 0.0}},
        "spheres": [{"centre": sphere_c, "radius": 0.05, "albedo": 1.0}],
        "lamp": {"position": [0.0, 0.0, 2.0], "target": [0.0, 0.0, 0.0], "size_m": 0.4, "irradiance": math.pi * 0.7},
        "ambient": {"radiance": 0.3},
        "shots": [{"name": name, "seed": 3, "width": 200, "height": 160, "fx": 300.0, "fy": 300.0, "cx": cx, "cy": cy,
                   "ground_from_camera": gfc.tolist()}
                  for name, cx, cy in (("cam_a", 87.3, 91.6), ("cam_b", 112.8, 70.2))],
    }

    def load(overrides, name):
        doc = json.loads(json.dumps(base))
        for key, value in overrides.items():
            doc[key] = value
        path = tmp / f"{name}.json"
        path.write_text(json.dumps(doc))
        return parse_scene(path)

    # 1. Geometry: the marker sphere made a unit emitter, seen alone (max_depth 1, no lamp, no sky):
    #    its area centroid must sit on the pinhole projection of its centre.
    scene = load({}, "lambert")
    d = scene_dict(mi, scene)
    for key in ("lamp", "lamp_housing", "ambient"):
        del d[key]
    d["integrator"] = {"type": "path", "max_depth": 1}
    d["sphere_0"]["emitter"] = {"type": "area", "radiance": 1.0}
    mask_scene = mi.load_dict(d)
    for shot in scene["shots"]:
        img = render_shot(mi, mask_scene, shot, variant, 16).astype(np.float64)
        vv, uu = np.mgrid[0:shot["height"], 0:shot["width"]]
        cu, cv = (img * uu).sum() / img.sum(), (img * vv).sum() / img.sum()
        pu, pv = project(shot, np.array(sphere_c))
        err = math.hypot(cu - pu, cv - pv)
        check(err < 1.0, f"{shot['name']} (cx {shot['cx']}, cy {shot['cy']}): sphere centroid ({cu:.2f}, {cv:.2f}) vs "
                         f"projection ({pu:.2f}, {pv:.2f}): {err:.3f} px")

    # 2. Radiometry at the image centre (away from the sphere): Lambert, then Oren-Nayar sigma 30.
    shot = scene["shots"][0]
    uc, vc = (shot["width"] - 1) / 2, (shot["height"] - 1) / 2
    check(np.linalg.norm(project(shot, np.array(sphere_c)) - [uc, vc]) > 25, "the image centre patch is clear of the sphere")
    point = ground_point(shot, uc, vc)
    patch = (slice(int(vc) - 6, int(vc) + 8), slice(int(uc) - 6, int(uc) + 8))
    means = {}
    for sigma in (0.0, 30.0):
        sc = load({"terrain": {**base["terrain"], "bsdf": {"model": "oren-nayar", "sigma_deg": sigma}}}, f"s{sigma:g}")
        d = scene_dict(mi, sc)
        img = render_shot(mi, mi.load_dict(d), shot, variant, 256)
        means[sigma] = float(img[patch].mean())
        if sigma == 0.0:  # the plugin at sigma 0 against Mitsuba's own Lambertian `diffuse`
            d["terrain"]["bsdf"] = {"type": "diffuse", "reflectance": d["terrain"]["bsdf"]["reflectance"]}
            ref = render_shot(mi, mi.load_dict(d), shot, variant, 256)
            ratio = float(img.mean() / ref.mean())
            check(abs(ratio - 1) < 0.005, f"sigma 0 plugin vs built-in diffuse, whole image mean ratio {ratio:.5f}")
        want = expected_radiance(sc, point, eye, 0.5, sigma)
        check(abs(means[sigma] / want - 1) < 0.05, f"sigma {sigma:g}: centre radiance {means[sigma]:.4f} vs analytic "
                                                   f"{want:.4f} ({100 * (means[sigma] / want - 1):+.2f} %)")
        if sigma == 0.0:
            lambert_img = img
            write_exr_y(mi, tmp / "cam_a.exr", img)
    check(means[30.0] < means[0.0], f"sigma 30 darker than Lambert away from backscatter "
                                    f"({means[30.0]:.4f} < {means[0.0]:.4f})")

    # Backscatter: lamp behind a grazing camera (25 deg elevation), no sky: sigma 30 must be brighter.
    back_dir = np.array([math.cos(math.radians(200)) * math.cos(math.radians(25)),
                         math.sin(math.radians(200)) * math.cos(math.radians(25)), math.sin(math.radians(25))])
    back_eye = 1.5 * back_dir
    back_shot = {**shot, "cx": 99.5, "cy": 79.5, "ground_from_camera": look_from(back_eye, target, 0.0)}
    lamp = {"position": (2.6 * back_dir + [0, 0, 0.25]).tolist(), "target": [0.0, 0.0, 0.0], "size_m": 0.4,
            "irradiance": math.pi * 0.7}
    back = {}
    for sigma in (0.0, 30.0):
        sc = load({"terrain": {**base["terrain"], "bsdf": {"model": "oren-nayar", "sigma_deg": sigma}},
                   "lamp": lamp, "ambient": {"radiance": 0.0}, "spheres": []}, f"back{sigma:g}")
        img = render_shot(mi, mi.load_dict(scene_dict(mi, sc)), back_shot, variant, 64)
        back[sigma] = float(img[70:90, 90:110].mean())
        want = expected_radiance(sc, np.zeros(3), back_eye, 0.5, sigma)
        print(f"     backscatter sigma {sigma:g}: {back[sigma]:.4f} (analytic {want:.4f})")
    check(back[30.0] > back[0.0], f"sigma 30 brighter than Lambert in backscatter ({back[30.0]:.4f} > {back[0.0]:.4f})")

    # 3. Output file: one float32 channel named Y, the shot's size, values read back intact.
    channels, size = exr_channels_and_size(tmp / "cam_a.exr")
    check(channels == [("Y", 2)] and size == (shot["width"], shot["height"]),
          f"EXR channels {channels} (name, 2 = float32), size {size}")
    read = np.array(mi.Bitmap(str(tmp / "cam_a.exr")), dtype=np.float32).reshape(lambert_img.shape)
    check(np.array_equal(read, lambert_img) and np.isfinite(read).all(), "EXR reads back bit-identical and finite")

    print(f"self-test: {'FAIL (' + '; '.join(failures) + ')' if failures else 'PASS'}")
    return 1 if failures else 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", help="scene JSON written by the corpus generator")
    ap.add_argument("out_dir", nargs="?", help="folder for <shot>.exr and renders.json")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel (default 64)")
    ap.add_argument("--variant", help=f"mitsuba variant (default: first working of {', '.join(PREFERRED_VARIANTS)})")
    ap.add_argument("--threads", type=int, help="worker threads, at least 2 (default: all cores)")
    ap.add_argument("--only", metavar="SHOT_NAME", help="render only this shot")
    ap.add_argument("--self-test", action="store_true", help="check camera, radiometry and EXR output, then exit")
    ap.add_argument("--fast-variant", action="store_true",
                    help="exit 0 if an LLVM variant works here (renders take a minute, not an hour), else 4")
    args = ap.parse_args(argv)
    try:
        if args.spp <= 0:
            raise SceneError("--spp must be positive")
        if args.threads is not None and args.threads < 2:
            raise SceneError("--threads must be at least 2: Mitsuba 3.9.1 deadlocks reading or writing EXR "
                             "with a one-thread pool")
        if args.fast_variant:
            set_llvm_library_path()
            try:
                import mitsuba as mi
            except ImportError:
                return 3
            ok = any(v in mi.variants() and variant_works(v) for v in PREFERRED_VARIANTS if v.startswith("llvm"))
            return 0 if ok else 4
        if args.self_test:
            return self_test(args)
        if not args.scene or not args.out_dir:
            ap.error("SCENE.json and OUT_DIR are required (or --self-test)")
        return render_scene_file(args)
    except SceneError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
