#!/usr/bin/env python3
"""Cross-check radlab's Monte Carlo reference against Mitsuba 3 at points of builtin:cornell.

Issue 15 §1: irradiance meters at >= 32 points, B = rho * E_irr + E, compared with
`radlab reference --point-file` at the same points; agreement within 3 combined standard errors at
>= 95 % of the points. Mitsuba is a tool to check with, not a dependency of radlab (not in CI):

    python3 -m venv /tmp/mi && /tmp/mi/bin/pip install mitsuba numpy
    cargo build --release --no-default-features
    /tmp/mi/bin/python scripts/mitsuba_crosscheck.py --radlab target/release/radlab \
        --out docs/reference_crosscheck.md

How it works:
- the scene's patches (vertices, normal, rho, E) come from `radlab solve builtin:cornell --json`
  (one element per patch, so the solve is instant; only the geometry and materials are used);
- every patch becomes a Mitsuba mesh (fan triangles, face normals from the same winding, so the
  front side is radlab's), a one-sided `diffuse` BSDF with radlab's rho, and, for the light, an
  `area` emitter of radiance E / pi (a Lambertian exitance E);
- the points: two fixed positions on each non-emitting patch (quads by their bilinear map,
  triangles by barycentric coordinates), kept off edges;
- at each point an `irradiancemeter` is attached to a disk of radius METER_RADIUS, lifted
  METER_LIFT off the surface along its normal; Mitsuba's `path` integrator (unbounded depth,
  Russian roulette) gives the irradiance H; B = rho H + E;
- standard errors: BATCHES independent renders (different seeds) per meter, the standard error
  of their mean; radlab's come from `estimate_points` (the sample standard deviation of the
  path estimates / sqrt(paths)).
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

# Meter disk radius and lift off the surface, in scene units (the Cornell box is in mm, ~550 mm
# across): small against any variation of B (the disk averages over 0.1 mm) and far above f32
# rounding of the coordinates (~3e-5 mm at 550 mm).
METER_RADIUS = 0.05
METER_LIFT = 0.01
# Fixed positions on each patch (bilinear (u, v) for quads; for triangles, barycentric (u, v)
# with u + v <= 1 after folding).
POSITIONS = [(0.3, 0.35), (0.7, 0.6)]


def run(cmd):
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{res.stderr}")
    return res.stdout


def patch_points(p):
    vs = np.array(p["vertices"])
    out = []
    for u, v in POSITIONS:
        if len(vs) == 4:
            a = vs[0] * (1 - u) + vs[1] * u
            b = vs[3] * (1 - u) + vs[2] * u
            x = a * (1 - v) + b * v
        else:
            if u + v > 1:
                u, v = 1 - u, 1 - v
            u, v = 0.6 * u + 0.1, 0.6 * v + 0.1  # keep off the edges
            x = vs[0] + (vs[1] - vs[0]) * u + (vs[2] - vs[0]) * v
        out.append(x)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--radlab", default="target/release/radlab", help="radlab binary")
    ap.add_argument("--scene", default="builtin:cornell")
    ap.add_argument("--spp", type=int, default=1 << 15, help="Mitsuba paths per meter and batch")
    ap.add_argument("--batches", type=int, default=8, help="independent Mitsuba renders per meter")
    ap.add_argument("--radlab-samples", type=int, default=1 << 18, help="radlab paths per point")
    ap.add_argument("--out", default="docs/reference_crosscheck.md")
    ap.add_argument("--json-out", default=None, help="also write the raw table as JSON")
    ap.add_argument("--include-emitters", action="store_true",
                    help="also put meters on emitting patches (e.g. to check the pipeline on builtin:furnace)")
    args = ap.parse_args()

    tmp = tempfile.mkdtemp(prefix="radlab-mitsuba-")
    sol = os.path.join(tmp, "solve.json")
    run([args.radlab, "solve", args.scene, "--method", "uniform", "--element-size", "1e9", "--rays", "0",
         "--json", sol, "--quiet"])
    patches = json.load(open(sol))["patches"]

    specs = []
    for i, p in enumerate(patches):
        if max(p["emission"]) > 0 and not args.include_emitters:
            continue
        for x in patch_points(p):
            specs.append({"patch": i, "point": [float(c) for c in x]})
    pts_file = os.path.join(tmp, "points.json")
    json.dump(specs, open(pts_file, "w"))
    ref_file = os.path.join(tmp, "reference.json")
    run([args.radlab, "reference", args.scene, "--point-file", pts_file, "--samples", str(args.radlab_samples),
         "--json", ref_file])
    ref = json.load(open(ref_file))["points"]

    # Mitsuba: the patches once, one meter per point.
    base = {"type": "scene", "integrator": {"type": "path", "max_depth": -1}}
    for i, p in enumerate(patches):
        vs = np.array(p["vertices"], dtype=np.float64)
        n = len(vs)
        faces = np.array([[0, k, k + 1] for k in range(1, n - 1)], dtype=np.uint32)
        geo_n = np.cross(vs[1] - vs[0], vs[2] - vs[0])
        assert np.dot(geo_n, p["normal"]) > 0, f"patch {i}: winding disagrees with radlab's normal"
        props = mi.Properties()
        props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": p["reflectance"]}})
        if max(p["emission"]) > 0:
            props["emitter"] = mi.load_dict(
                {"type": "area", "radiance": {"type": "rgb", "value": [c / math.pi for c in p["emission"]]}})
        mesh = mi.Mesh(f"patch{i}", n, len(faces), props=props, has_vertex_normals=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = vs.astype(np.float32).ravel()
        params["faces"] = faces.ravel()
        params.update()
        base[f"patch{i}"] = mesh

    rows = []
    for k, (s, r) in enumerate(zip(specs, ref)):
        p = patches[s["patch"]]
        n = np.array(p["normal"])
        x = np.array(s["point"]) + METER_LIFT * n
        up = [0, 1, 0] if abs(n[1]) < 0.9 else [1, 0, 0]
        to_world = mi.ScalarTransform4f().look_at(origin=x.tolist(), target=(x + n).tolist(), up=up) \
            @ mi.ScalarTransform4f().scale([METER_RADIUS] * 3)
        d = dict(base)
        d["meter"] = {
            "type": "disk",
            "to_world": to_world,
            "sensor": {
                "type": "irradiancemeter",
                "film": {"type": "hdrfilm", "width": 1, "height": 1, "pixel_format": "rgb",
                         "rfilter": {"type": "box"}},
            },
        }
        scene = mi.load_dict(d)
        batches = []
        for b in range(args.batches):
            img = mi.render(scene, spp=args.spp, seed=1000 * k + b)
            batches.append(np.array(img).reshape(-1)[:3])
        batches = np.array(batches)
        h = batches.mean(axis=0)
        h_se = batches.std(axis=0, ddof=1) / math.sqrt(args.batches)
        rho = np.array(p["reflectance"])
        b_mi = rho * h + np.array(p["emission"])
        se_mi = rho * h_se
        b_ref = np.array(r["radiosity"])
        se_ref = np.array(r["std_error"])
        z = np.abs(b_mi - b_ref) / np.sqrt(se_mi ** 2 + se_ref ** 2)
        rows.append({"patch": s["patch"], "name": p["name"], "point": s["point"], "mitsuba": b_mi.tolist(),
                     "mitsuba_se": se_mi.tolist(), "radlab": b_ref.tolist(), "radlab_se": se_ref.tolist(),
                     "z": z.tolist()})
        print(f"{k:3d} {p['name']:<24} mitsuba {b_mi.round(4)} ± {se_mi.round(4)}  radlab {b_ref.round(4)} ± "
              f"{se_ref.round(4)}  z {z.round(2)}", flush=True)

    agree = sum(1 for r in rows if max(r["z"]) <= 3.0)
    frac = agree / len(rows)
    zs = np.array([r["z"] for r in rows]).ravel()
    rel = np.array([abs(np.mean(r["mitsuba"]) - np.mean(r["radlab"])) / np.mean(r["radlab"]) for r in rows])
    if args.json_out:
        json.dump({"rows": rows, "agree": agree, "points": len(rows)}, open(args.json_out, "w"), indent=1)
    with open(args.out, "w") as f:
        f.write("# Reference cross-check against Mitsuba 3\n\n")
        f.write("radlab's independent Monte Carlo reference (`radlab reference --point-file`, "
                "`radlab::eval::reference::estimate_points`) against Mitsuba 3 "
                f"({mi.__version__}, variant `scalar_rgb`, `path` integrator, unbounded depth) at "
                f"{len(rows)} points of `{args.scene}`: two fixed points on every patch but the light. "
                "Mitsuba measures the irradiance H with an `irradiancemeter` on a disk of radius "
                f"{METER_RADIUS} mm lifted {METER_LIFT} mm off the surface; B = ρ·H + E. "
                f"Mitsuba: {args.batches} independent renders × {args.spp} paths per point, standard error of "
                f"their mean; radlab: {args.radlab_samples} paths per point.\n\n")
        f.write(f"Made by `scripts/mitsuba_crosscheck.py` (command in its docstring).\n\n")
        f.write(f"**Result: {agree} of {len(rows)} points ({100 * frac:.1f} %) agree within 3 combined standard "
                f"errors in all three channels** (target ≥ 95 %). Over all {len(zs)} channel values: "
                f"mean z² = {np.mean(zs ** 2):.2f} (1 expected for agreement with honest errors), largest "
                f"z = {zs.max():.2f}; mean relative difference of the channel means "
                f"{100 * rel.mean():.3f} %, largest {100 * rel.max():.3f} %.\n\n")
        f.write("z = |B_mitsuba − B_radlab| / √(σ_mitsuba² + σ_radlab²), per channel.\n\n")
        f.write("| # | patch | point (mm) | Mitsuba B (r, g, b) | radlab B (r, g, b) | rel. σ (M / r) | z (r, g, b) |\n")
        f.write("|---|---|---|---|---|---|---|\n")
        for k, r in enumerate(rows):
            fmt = lambda v: ", ".join(f"{c:.4f}" for c in v)
            m = np.mean(r["mitsuba"])
            f.write(f"| {k} | {r['name']} | ({', '.join(f'{c:.1f}' for c in r['point'])}) | {fmt(r['mitsuba'])} | "
                    f"{fmt(r['radlab'])} | {100 * np.mean(r['mitsuba_se']) / m:.2f} % / "
                    f"{100 * np.mean(r['radlab_se']) / np.mean(r['radlab']):.2f} % | "
                    f"{', '.join(f'{z:.2f}' for z in r['z'])} |\n")
    print(f"{agree}/{len(rows)} points agree within 3 sigma ({100 * frac:.1f} %); wrote {args.out}")
    return 0 if frac >= 0.95 else 1


if __name__ == "__main__":
    sys.exit(main())
