#!/usr/bin/env python3
"""Cross-check radlab's pointwise reference against Mitsuba 3 at the reference's own points.

radlab scores a solution at the points of its path-traced reference (`radlab reference`, the
cached adaptive point set, docs/accuracy.md). This script estimates B with Mitsuba 3 at the same
points and compares (docs/reference_crosscheck.md):

1. the reference against Mitsuba: the debiased pointwise rel L2 (radlab's formula, below), an upper
   bound on it, the fraction of points whose three channels agree within 3 combined standard
   errors, and each reference batch alone against Mitsuba (is its standard error honest?);
2. with --presets, radlab's solutions (their reconstruction at the points, `radlab reference
   --compare --preset P --point-errors`) against both rulers: radlab's reference and Mitsuba.

Mitsuba is a tool to check with, not a dependency of radlab (not in CI, not in Cargo):

    python3 -m venv --system-site-packages /tmp/mi && /tmp/mi/bin/pip install mitsuba numpy
    cargo build --release --no-default-features
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so
    nice -n 10 /tmp/mi/bin/python scripts/mitsuba_crosscheck.py builtin:cornell \
        --radlab target/release/radlab --cache-dir /work/radlab-cache --batches 2 --paths 4096 \
        --threads 2 --presets draft,interactive,quality,fine --work /tmp/mi-work \
        --json /tmp/mi-work/cornell.json

(--sample N checks N random points instead of all; --runs K merges K independent Mitsuba runs.)
Intermediate files (the reference's points, Mitsuba's estimates per run, each preset's values at
the points) are kept in --work and reused. The `llvm_ad_rgb` variant needs libLLVM 16 or newer
(with LLVM 15 it stops with "LLVM ERROR: Cannot select: ... fminimum"); DRJIT_LIBLLVM_PATH
names it.

How it works:
- the patches (vertices, normal, ρ, E) come from `radlab solve SCENE --json` with one element per
  patch (instant; only the geometry and materials are read): the scene exactly as radlab loads it,
  decals already cut out of the patches under them (src/scene/decal.rs);
- every patch becomes a Mitsuba mesh (fan triangles wound as radlab winds them, face normals, so
  the front is radlab's), a one-sided `diffuse` BSDF of reflectance ρ and, where E > 0, an `area`
  emitter of radiance E/π;
- the points, their patch, area, reference value and standard error come from `radlab reference
  SCENE --batches B --cache-dir DIR --json` (the cached points-v2 entries, B batches merged); each
  batch's own estimates are read from its cache file (a header line, then JSON);
- at each point x on a patch of normal n, P paths from x + δn (δ = DELTA_REL × the scene's
  diagonal): H = H_direct + π · mean(L_indirect), B = ρ H + E, where, per path,
    H_direct = L_e cos θ / pdf from Mitsuba's emitter sampling (`Scene.sample_emitter_direction`
      from x + δn, visibility tested), the next-event estimate of the direct irradiance, and
    L_indirect = L − L_e(first hit): L is Mitsuba's `path` integrator (unbounded depth, Russian
      roulette, its own next-event estimation and MIS) along a cosine-distributed ray from x + δn
      (`Integrator.sample` on a wavefront of rays), L_e(first hit) the emission that the ray itself
      sees, which the integrator adds with weight 1 at its first vertex;
  --estimator cosine drops the split (H = π · mean(L), the plain cosine estimate: unbiased, but
  the direct light of a small lamp is found only by chance, about 9× the noise on cornell);
- a point's standard error is the sample standard deviation of its P path values / √P;
- left out of every figure: points on a patch under a coplanar, same-facing patch (a decal's
  base; radlab cuts the covered part away, so none should exist), and contact points, closer than
  CONTACT_LIFTS · δ to another surface that is not in their own plane, where the lift can carry
  the origin across that surface; points inside a solid (B = 0 exactly on both sides, no noise)
  stay in the sums, where they add nothing, and out of the agreement fraction.

The figures, per RGB channel c, each point i weighted by the area a_i of its cell (as
src/eval/metrics.rs):

    debiased rel L2 = √( max(0, Σ_i a_i Σ_c (Δ_ic² − σ_ic²)) / Σ_i a_i Σ_c (B̂_ic − E_ic)² )

relative to the reflected radiosity B̂ − E of the ruler. Reference against Mitsuba: Δ = B_radlab −
B_mitsuba, σ² = σ_radlab² + σ_mitsuba², B̂ = radlab's reference; a solution against a ruler: Δ =
B_solution − B_ruler, σ² = σ_ruler². Noise: √(Σ a Σ_c σ² / Σ a Σ_c (B̂ − E)²); resolution (the
smallest debiased error that can be told from zero, radlab's rule): 2 · noise · (2/N)^¼ for N
points; upper bound: the debiased sum plus twice its spread √(2 Σ_i w_i²), w_i = a_i Σ_c σ_ic²,
for honest Gaussian errors (the channels counted as one, which is conservative).
"""

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

# The origin of each point's paths is lifted this fraction of the scene's diagonal off its surface:
# far above f32 rounding of the coordinates (~6e-8 relative), far below any feature (radlab's
# smallest cells are ~1e-3 of the diagonal).
DELTA_REL = 1e-5
# Points closer than this many lifts δ to another surface (not in their own plane) are left out:
# there the lift can carry the origin across that surface (a panel that cuts through the patch, a
# block's foot on the floor), so the value depends on the estimator's offset, not on the light.
CONTACT_LIFTS = 2.0
# Rays per Mitsuba wavefront (points × paths per chunk).
WAVEFRONT = 1 << 20
# Points within this many combined standard errors (each channel) "agree".
AGREE_SIGMAS = 3.0


def run(cmd, what):
    t = time.time()
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{res.stderr}")
    print(f"  [{time.time() - t:6.1f} s] {what}", file=sys.stderr, flush=True)
    return res.stdout + res.stderr


def slug(scene):
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", scene)


# --------------------------------------------------------------------------------------------
# radlab's side


def load_patches(args, work):
    out = os.path.join(work, f"{slug(args.scene)}.patches.json")
    if not os.path.exists(out):
        run([args.radlab, "solve", args.scene, "--method", "uniform", "--element-size", "1e9", "--rays", "0",
             "--json", out, "--quiet"], "radlab solve (the patches)")
    patches = json.load(open(out))["patches"]
    for i, p in enumerate(patches):
        assert p["index"] == i, "patches out of order"
    return patches


def reference_args(args):
    return ["--cache-dir", args.cache_dir, "--batches", str(args.batches), "--samples", str(args.samples),
            "--points", str(args.points)]


def load_reference(args, work):
    """The reference's points: patch, position, area, B and its standard error (merged batches)."""
    out = os.path.join(work, f"{slug(args.scene)}.reference-b{args.batches}.json")
    if not (os.path.exists(out) and os.path.exists(out + ".log")):
        log = run([args.radlab, "reference", args.scene, *reference_args(args), "--json", out],
                  "radlab reference (the cached points)")
        if "computed" in log:
            print("  note: radlab computed (part of) the reference: it was not in the cache", file=sys.stderr)
        open(out + ".log", "w").write(log)
    doc = json.load(open(out))
    pts = doc["points"]
    # The cache file of each batch, in batch order (batch 1 placed the points).
    files = re.findall(r"(\S+points-v2-[0-9a-f]+\.json)", open(out + ".log").read())
    return {
        "batch_files": list(dict.fromkeys(files)),
        "cache_file": doc["cache_file"],
        "params": doc["params"],
        "patch": np.array([p["patch"] for p in pts], dtype=np.int64),
        "position": np.array([p["position"] for p in pts], dtype=np.float64),
        "area": np.array([p["area"] for p in pts], dtype=np.float64),
        "level": np.array([p["level"] for p in pts], dtype=np.int64),
        "b": np.array([p["radiosity"] for p in pts], dtype=np.float64),
        "se": np.array([p["std_error"] for p in pts], dtype=np.float64),
    }


def batch_estimates(path):
    """One batch's estimates (B, standard error) from its cache file: a header line, then JSON."""
    with open(path) as f:
        f.readline()
        est = json.load(f)["estimates"]
    return (np.array([e["radiosity"] for e in est], dtype=np.float64),
            np.array([e["std_error"] for e in est], dtype=np.float64))


def solution_at_points(args, preset, work, ref):
    """radlab's solution at the reference's points (`--point-errors`) and radlab's own figure."""
    csv_path = os.path.join(work, f"{slug(args.scene)}.{preset}-b{args.batches}.points.csv")
    log_path = csv_path + ".log"
    if not (os.path.exists(csv_path) and os.path.exists(log_path)):
        log = run([args.radlab, "reference", args.scene, *reference_args(args), "--compare", "--preset", preset,
                   "--point-errors", csv_path], f"radlab reference --compare --preset {preset}")
        open(log_path, "w").write(log)
    log = open(log_path).read()
    rows = list(csv.reader(open(csv_path)))
    head, rows = rows[0], rows[1:]
    col = {name: k for k, name in enumerate(head)}
    a = np.array(rows, dtype=np.float64)
    assert len(a) == len(ref["patch"]), "--point-errors wrote other points than the reference's"
    assert np.array_equal(a[:, col["patch"]].astype(np.int64), ref["patch"])
    assert np.allclose(a[:, [col["x"], col["y"], col["z"]]], ref["position"], rtol=0, atol=1e-9)
    sol = a[:, [col["sol_r"], col["sol_g"], col["sol_b"]]]
    # radlab's own figure, printed as "pointwise rel L2 X % (N points, noise Y %):".
    m = re.search(r"pointwise rel L2 ([0-9.<]+) %", log)
    printed = m.group(1) + " %" if m else None
    return sol, printed, log


# --------------------------------------------------------------------------------------------
# Hidden points: on a patch under a coplanar, same-facing patch (a decal's base).


def covered_points(patches, pos, patch_of, diag):
    normals = [np.array(p["normal"]) for p in patches]
    offsets = [float(np.dot(normals[i], np.array(p["vertices"][0]))) for i, p in enumerate(patches)]
    hidden = np.zeros(len(pos), dtype=bool)
    for i in range(len(patches)):
        for j in range(len(patches)):
            if i == j or np.dot(normals[i], normals[j]) < 1 - 1e-6 or abs(offsets[i] - offsets[j]) > 1e-6 * diag:
                continue
            on = np.nonzero(patch_of == i)[0]
            if len(on) == 0:
                continue
            inside = inside_polygon(pos[on], np.array(patches[j]["vertices"]), normals[j])
            hidden[on[inside]] = True
    return hidden


def contact_points(patches, pos, patch_of, tol, diag):
    """Points closer than tol to a patch that does not lie in their own patch's plane."""
    normals = [np.array(p["normal"]) for p in patches]
    offsets = np.array([float(np.dot(normals[i], np.array(p["vertices"][0]))) for i, p in enumerate(patches)])
    near = np.zeros(len(pos), dtype=bool)
    for j, q in enumerate(patches):
        v = np.array(q["vertices"])
        same_plane = np.array([abs(abs(np.dot(normals[i], normals[j])) - 1) < 1e-6
                               and abs(abs(offsets[i]) - abs(offsets[j])) < 1e-6 * diag for i in range(len(patches))])
        cand = (patch_of != j) & ~same_plane[patch_of] & (np.abs((pos - v[0]) @ normals[j]) < tol)
        if cand.any():
            idx = np.nonzero(cand)[0]
            near[idx[distance_to_polygon(pos[idx], v, normals[j]) < tol]] = True
    return near


def distance_to_polygon(x, verts, n):
    """Distance from points x to the convex polygon verts (normal n)."""
    h = (x - verts[0]) @ n
    p = x - h[:, None] * n
    inside = np.ones(len(x), dtype=bool)
    edge = np.full(len(x), np.inf)
    for k in range(len(verts)):
        a, b = verts[k], verts[(k + 1) % len(verts)]
        ab = b - a
        inside &= np.cross(ab, p - a) @ n >= 0
        t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
        edge = np.minimum(edge, np.linalg.norm(p - (a + t[:, None] * ab), axis=1))
    return np.hypot(h, np.where(inside, 0.0, edge))


def inside_polygon(x, verts, n):
    """Points x (in the polygon's plane) strictly inside the convex polygon verts (normal n)."""
    ok = np.ones(len(x), dtype=bool)
    for k in range(len(verts)):
        a, b = verts[k], verts[(k + 1) % len(verts)]
        ok &= np.cross(b - a, x - a) @ n > 1e-9 * np.linalg.norm(b - a)
    return ok


# --------------------------------------------------------------------------------------------
# Mitsuba's side


def mitsuba_scene(mi, patches):
    d = {"type": "scene"}
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
        d[f"patch{i}"] = mesh
    return mi.load_dict(d)


def mitsuba_estimate(args, seed, patches, pos, patch_of, diag):
    """B at each point from args.paths Mitsuba paths: mean and standard error per channel."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    if args.threads:
        dr.set_thread_count(args.threads)
    scene = mitsuba_scene(mi, patches)
    integrator = mi.load_dict({"type": "path", "max_depth": -1})
    normals = np.array([p["normal"] for p in patches])[patch_of]
    rho = np.array([p["reflectance"] for p in patches])[patch_of]
    emission = np.array([p["emission"] for p in patches])[patch_of]
    origin = pos + DELTA_REL * diag * normals
    paths = args.paths
    per_chunk = max(1, WAVEFRONT // paths)
    mean_h = np.zeros((len(pos), 3))
    se_h = np.zeros((len(pos), 3))
    t0 = time.time()
    for c, start in enumerate(range(0, len(pos), per_chunk)):
        sl = slice(start, min(len(pos), start + per_chunk))
        n_pts = sl.stop - sl.start
        wave = n_pts * paths
        idx = dr.arange(mi.UInt32, wave) // paths
        o = dr.gather(mi.Point3f, mi.Point3f(*[mi.Float(origin[sl, k]) for k in range(3)]), idx)
        nn = dr.gather(mi.Vector3f, mi.Vector3f(*[mi.Float(normals[sl, k]) for k in range(3)]), idx)
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(seed * 1_000_003 + c, wave)
        frame = mi.Frame3f(nn)
        d = frame.to_world(mi.warp.square_to_cosine_hemisphere(sampler.next_2d()))
        ray = mi.Ray3f(o, d)
        h = mi.Color3f(0.0)
        if args.estimator == "nee":
            it = dr.zeros(mi.Interaction3f)
            it.p, it.n = o, nn
            ds, weight = scene.sample_emitter_direction(it, sampler.next_2d(), True)
            h += weight * dr.maximum(dr.dot(nn, ds.d), 0.0)
            si = scene.ray_intersect(ray)
            seen = si.emitter(scene).eval(si, si.is_valid())
        else:
            seen = mi.Color3f(0.0)
        radiance, _, _ = integrator.sample(scene, sampler, ray)
        h += math.pi * (mi.Color3f(radiance) - seen)
        v = np.array(h).reshape(3, n_pts, paths)  # channel, point, path
        mean_h[sl] = v.mean(axis=2).T
        se_h[sl] = (v.std(axis=2, ddof=1) / math.sqrt(paths)).T
        done = sl.stop
        el = time.time() - t0
        print(f"\r  mitsuba: {done}/{len(pos)} points, {el:.0f} s, about {el / done * (len(pos) - done):.0f} s left  ",
              end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return rho * mean_h + emission, rho * se_h, time.time() - t0


# --------------------------------------------------------------------------------------------
# Figures


def debiased(diff, var, refl, area):
    """(debiased rel L2, raw rel L2, noise, resolution) of diff against the reflected radiosity."""
    a = area[:, None]
    sq = float(np.sum(a * diff ** 2))
    noise = float(np.sum(a * var))
    ref_sq = float(np.sum(a * refl ** 2))
    n = len(area)
    if ref_sq == 0.0:  # nothing reflected here (an emitter of ρ = 0): no relative figure
        return {"l2_debiased": math.nan, "l2": math.nan, "noise": math.nan, "resolution": math.nan,
                "l2_upper": math.nan, "points": n}
    # The debiased Σ a |Δ|² − Σ a σ² fluctuates by √(2 Σ w²), w = a Σ_c σ² per point, for honest
    # Gaussian errors (the channels taken as one, which is conservative); l2_upper adds two of that.
    w = area * var.sum(axis=1)
    spread = math.sqrt(2.0 * float(np.sum(w ** 2)))
    return {
        "l2_debiased": math.sqrt(max(0.0, sq - noise) / ref_sq),
        "l2_upper": math.sqrt(max(0.0, sq - noise + 2.0 * spread) / ref_sq),
        "l2": math.sqrt(sq / ref_sq),
        "noise": math.sqrt(noise / ref_sq),
        "resolution": 2.0 * math.sqrt(noise / ref_sq) * (2.0 / n) ** 0.25,
        "points": n,
    }


def pct(x):
    return f"{100 * x:.2f} %"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene", help="builtin:cornell, builtin:table-room, builtin:splash_room, …")
    ap.add_argument("--radlab", default="target/release/radlab", help="radlab binary (headless release)")
    ap.add_argument("--cache-dir", default=os.environ.get("RADLAB_CACHE", ".radlab-cache"),
                    help="radlab's reference cache (points-v2-*.json)")
    ap.add_argument("--batches", type=int, default=2, help="reference batches to merge (radlab --batches)")
    ap.add_argument("--samples", type=int, default=1024, help="reference paths per point and batch")
    ap.add_argument("--points", type=int, default=65536, help="reference points (radlab --points)")
    ap.add_argument("--sample", type=int, default=0,
                    help="check N of the reference's points, drawn at random with --sample-seed (0: all)")
    ap.add_argument("--sample-seed", type=int, default=0)
    ap.add_argument("--paths", type=int, default=4096, help="Mitsuba paths per point")
    ap.add_argument("--seed", type=int, default=0, help="Mitsuba's sampler seed (of the first run)")
    ap.add_argument("--runs", type=int, default=1,
                    help="independent Mitsuba runs of --paths paths to merge (seeds --seed, --seed + 1, …)")
    ap.add_argument("--estimator", choices=["nee", "cosine"], default="nee",
                    help="nee: direct light by emitter sampling + the path integrator's indirect light "
                         "along cosine rays; cosine: π · mean(path integrator along cosine rays)")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, default=0, help="Dr.Jit threads (0: Dr.Jit's default)")
    ap.add_argument("--presets", default="", help="comma-separated radlab presets to score on both rulers")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "radlab-mitsuba-crosscheck"),
                    help="folder for intermediate files (reused)")
    ap.add_argument("--json", default=None, help="write the figures as JSON")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)

    print(f"{args.scene}:", file=sys.stderr)
    patches = load_patches(args, args.work)
    ref = load_reference(args, args.work)
    verts = np.array([v for p in patches for v in p["vertices"]])
    diag = float(np.linalg.norm(verts.max(axis=0) - verts.min(axis=0)))
    n_all = len(ref["patch"])

    hidden = covered_points(patches, ref["position"], ref["patch"], diag)
    contact = contact_points(patches, ref["position"], ref["patch"], CONTACT_LIFTS * DELTA_REL * diag, diag) & ~hidden
    # Mitsuba estimates every visible point drawn (contact points too, to show what they do); the
    # figures are taken over `keep`, the drawn points less the contact points.
    drawn = np.nonzero(~hidden)[0]
    if args.sample and args.sample < len(drawn):
        rng = np.random.default_rng(args.sample_seed)
        drawn = np.sort(rng.choice(drawn, size=args.sample, replace=False))
    # --runs independent runs of --paths paths (seeds --seed, --seed + 1, …), each kept in its own
    # file, merged: the mean of the means, standard error √(Σ se²) / runs.
    runs = []
    for seed in range(args.seed, args.seed + args.runs):
        mfile = os.path.join(args.work, f"{slug(args.scene)}.mitsuba-{args.estimator}-n{len(drawn)}"
                                        f"-s{args.sample_seed}-p{args.paths}-seed{seed}.npz")
        if os.path.exists(mfile):
            z = np.load(mfile)
            assert np.array_equal(z["keep"], drawn), f"{mfile}: other points"
            runs.append((z["b"], z["se"], float(z["seconds"])))
        else:
            b, se, secs = mitsuba_estimate(args, seed, patches, ref["position"][drawn], ref["patch"][drawn], diag)
            np.savez(mfile, keep=drawn, b=b, se=se, seconds=secs)
            runs.append((b, se, secs))
    b_drawn = sum(r[0] for r in runs) / len(runs)
    se_drawn = np.sqrt(sum(r[1] ** 2 for r in runs)) / len(runs)
    mi_s = sum(r[2] for r in runs)
    emission_all = np.array([p["emission"] for p in patches])[ref["patch"]]
    with_contact = debiased(ref["b"][drawn] - b_drawn, ref["se"][drawn] ** 2 + se_drawn ** 2,
                            ref["b"][drawn] - emission_all[drawn], ref["area"][drawn])
    not_contact = ~contact[drawn]
    keep = drawn[not_contact]
    b_mi, se_mi = b_drawn[not_contact], se_drawn[not_contact]
    pos, patch_of, area = ref["position"][keep], ref["patch"][keep], ref["area"][keep]
    b_ref, se_ref = ref["b"][keep], ref["se"][keep]
    emission = emission_all[keep]

    import mitsuba as mi
    refl_ref = b_ref - emission
    refl_mi = b_mi - emission
    cross = debiased(b_ref - b_mi, se_ref ** 2 + se_mi ** 2, refl_ref, area)
    noise_ref = debiased(np.zeros_like(b_ref), se_ref ** 2, refl_ref, area)["noise"]
    noise_mi = debiased(np.zeros_like(b_mi), se_mi ** 2, refl_mi, area)["noise"]
    # Sealed points (inside a solid, e.g. the floor under a block): both read exactly 0 with no
    # noise; they add nothing to the sums and are left out of the agreement fraction.
    sealed = np.all(b_ref == 0, axis=1) & np.all(se_ref == 0, axis=1) & np.all(b_mi == 0, axis=1)
    z = np.abs(b_ref - b_mi) / np.sqrt(se_ref ** 2 + se_mi ** 2 + 1e-300)
    within = float(np.mean(np.all(z[~sealed] <= AGREE_SIGMAS, axis=1)))
    within_ch = float(np.mean(z[~sealed] <= AGREE_SIGMAS))
    # Area-weighted means of B (reflected part) on each side: a global offset shows here.
    a = area[:, None]
    mean_ref = (a * refl_ref).sum(axis=0) / area.sum()
    mean_mi = (a * refl_mi).sum(axis=0) / area.sum()
    # The same debiased figure per patch, where the difference lies.
    per_patch = []
    for p in np.unique(patch_of):
        s = patch_of == p
        if s.sum() < 16 or not np.any(refl_ref[s]):
            continue
        f = debiased((b_ref - b_mi)[s], (se_ref ** 2 + se_mi ** 2)[s], refl_ref[s], area[s])
        zz = z[s]
        per_patch.append({"patch": int(p), "name": patches[p]["name"], "points": int(s.sum()),
                          "l2_debiased": f["l2_debiased"], "noise": f["noise"],
                          "within": float(np.mean(np.all(zz <= AGREE_SIGMAS, axis=1))),
                          "mean_ratio": float(np.sum(a[s] * refl_mi[s]) / np.sum(a[s] * refl_ref[s]))})
    # Each batch alone against Mitsuba: Σ a |B_batch − B_mitsuba|² over the noise both claim, by
    # refinement level (1 for honest standard errors). Batch 1's own estimates placed the points.
    batches = []
    if len(ref["batch_files"]) == args.batches:
        for b, f in enumerate(ref["batch_files"]):
            bb, sb = batch_estimates(f)
            bb, sb = bb[keep], sb[keep]
            row = {"batch": b + 1, "file": f,
                   "vs_mitsuba": debiased(bb - b_mi, sb ** 2 + se_mi ** 2, refl_ref, area)}
            for lev in [None, *sorted(set(ref["level"][keep].tolist()))]:
                m = (np.ones(len(keep), dtype=bool) if lev is None else ref["level"][keep] == lev)[:, None]
                w = np.sum(a * m * (sb ** 2 + se_mi ** 2), axis=1)
                ratio = float(np.sum(a * m * (bb - b_mi) ** 2) / w.sum())
                # Its standard deviation for honest Gaussian errors, channels taken as one.
                sd = float(math.sqrt(2.0 * np.sum(w ** 2)) / w.sum())
                key = "ratio" if lev is None else f"ratio_level{lev}"
                row[key], row[key + "_sd"] = ratio, sd
            batches.append(row)
    result = {
        "scene": args.scene,
        "batches": batches,
        "reference": {"cache_file": ref["cache_file"], "params": ref["params"], "batches": args.batches,
                      "points": n_all, "hidden": int(hidden.sum()), "contact": int(contact.sum()),
                      "noise": noise_ref},
        "mitsuba": {"version": mi.__version__, "variant": args.variant, "estimator": args.estimator,
                    "paths": args.paths, "runs": args.runs, "seed": args.seed, "delta": DELTA_REL * diag, "seconds": mi_s,
                    "noise": noise_mi},
        "checked": {"points": int(len(keep)), "sample_seed": args.sample_seed if args.sample else None,
                    "sealed": int(sealed.sum()), "sealed_area": float(area[sealed].sum() / area.sum())},
        "reference_vs_mitsuba_with_contact_points": with_contact,
        "reference_vs_mitsuba": {**cross, "within_3_sigma": within, "within_3_sigma_channels": within_ch,
                                 "mean_reflected_radlab": mean_ref.tolist(),
                                 "mean_reflected_mitsuba": mean_mi.tolist()},
        "per_patch": per_patch,
        "ladder": [],
    }
    print(f"{args.scene}: {len(keep)} of {n_all} points ({int(hidden.sum())} hidden, {int(contact.sum())} within "
          f"{CONTACT_LIFTS:g} δ of another surface; {int(sealed.sum())} checked "
          f"points sealed, B = 0 on both sides), Mitsuba {args.runs} × {args.paths} paths each ({args.estimator}, "
          f"{mi_s:.0f} s)")
    print(f"  noise: radlab {pct(noise_ref)}, Mitsuba {pct(noise_mi)}; combined {pct(cross['noise'])}, "
          f"resolution {pct(cross['resolution'])}")
    print(f"  radlab reference vs Mitsuba: debiased rel L2 {pct(cross['l2_debiased'])} (raw {pct(cross['l2'])}, "
          f"upper bound {pct(cross['l2_upper'])}); "
          f"within 3σ: {100 * within:.2f} % of points, {100 * within_ch:.2f} % of channel values")
    print(f"  (with the {int(contact[drawn].sum())} contact points: debiased {pct(with_contact['l2_debiased'])}, "
          f"raw {pct(with_contact['l2'])})")
    print(f"  mean reflected B: radlab {np.round(mean_ref, 5).tolist()}, Mitsuba {np.round(mean_mi, 5).tolist()}")
    for r in batches:
        levels = ", ".join(f"{k[len('ratio_level'):]}: {v:.3f}" for k, v in r.items()
                           if k.startswith("ratio_level") and not k.endswith("_sd"))
        print(f"  batch {r['batch']} alone vs Mitsuba: debiased {pct(r['vs_mitsuba']['l2_debiased'])} "
              f"(upper bound {pct(r['vs_mitsuba']['l2_upper'])}), "
              f"Σa|ΔB|² / Σa(σ² + σ_M²) = {r['ratio']:.3f} ± {r['ratio_sd']:.3f} (by level {levels})")
    worst = sorted(per_patch, key=lambda r: -r["l2_debiased"])[:5]
    for r in worst:
        print(f"    patch {r['patch']:>4} {r['name']:<22} {r['points']:>6} points: debiased {pct(r['l2_debiased'])}, "
              f"noise {pct(r['noise'])}, within 3σ {100 * r['within']:.1f} %, Mitsuba/radlab mean {r['mean_ratio']:.4f}")

    for preset in [p for p in args.presets.split(",") if p]:
        sol_all, printed, _ = solution_at_points(args, preset, args.work, ref)
        sol = sol_all[keep]
        all_ref = debiased(sol_all - ref["b"], ref["se"] ** 2,
                           ref["b"] - np.array([p["emission"] for p in patches])[ref["patch"]], ref["area"])
        sub_ref = debiased(sol - b_ref, se_ref ** 2, refl_ref, area)
        sub_mi = debiased(sol - b_mi, se_mi ** 2, refl_mi, area)
        row = {"preset": preset, "radlab_all_points": all_ref, "radlab": sub_ref, "mitsuba": sub_mi,
               "radlab_printed": printed}
        if len(ref["batch_files"]) > 1:
            # The first batch alone (it placed the points; `--batches 1`, radlab's default) and the
            # last alone (its estimates played no part in placing them).
            for name, f in [("radlab_first_batch", ref["batch_files"][0]), ("radlab_last_batch", ref["batch_files"][-1])]:
                bb, sb = batch_estimates(f)
                row[name] = debiased(sol - bb[keep], sb[keep] ** 2, bb[keep] - emission, area)
        result["ladder"].append(row)
        last = (f", vs radlab's first batch alone {pct(row['radlab_first_batch']['l2_debiased'])}"
                f", last batch alone {pct(row['radlab_last_batch']['l2_debiased'])}"
                if "radlab_last_batch" in row else "")
        print(f"  {preset:<12} vs radlab (all {n_all} points) {pct(all_ref['l2_debiased'])}, "
              f"vs radlab (checked points) {pct(sub_ref['l2_debiased'])}, vs Mitsuba {pct(sub_mi['l2_debiased'])}"
              f"{last}   [radlab printed: {printed}]")
    if result["ladder"]:
        for ruler in [r for r in ["radlab_all_points", "radlab", "mitsuba", "radlab_first_batch", "radlab_last_batch"]
                      if r in result["ladder"][0]]:
            e = [r[ruler]["l2_debiased"] for r in result["ladder"]]
            falls = all(x > y for x, y in zip(e, e[1:]))
            result[f"ladder_falls_{ruler}"] = falls
            print(f"  ladder on {ruler}: {' > '.join(pct(x) for x in e)}: {'falls' if falls else 'does NOT fall'} "
                  "at every step")
    if args.json:
        json.dump(result, open(args.json, "w"), indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
