//! Ray-cast acceleration: an obvhs CWBVH over the scene's input polygons, answering
//! "is the segment a→b blocked?" (any-hit) and "what is the first patch hit?" (obvhs's
//! `ray_traverse`).
//!
//! Shadow rays (any-hit, nearly all the rays the solvers cast) traverse the same tree decoded
//! once into unquantised 8-wide nodes, four slab tests per SIMD instruction: a third of the
//! box-test work of obvhs's traversal, which dequantises each node per ray, and conservative
//! where that one is not (rays starting a hair from another polygon's box were missed).
//!
//! ## How it works
//! - The BVH is `f32`. To keep precision for scenes far from the origin (translated by 1e6) or at
//!   extreme scales (1e-4, 1e4), every point is first mapped into a **local frame**: centred on the
//!   scene's bounds and scaled so the bounds' diagonal is 1. Results do not depend on the frame.
//! - Primitives are whole convex polygons (not triangle pairs), tested by plane intersection and
//!   inside-all-edges with a small outward tolerance: a ray through the shared edge of two patches
//!   hits one of them (no leaks through shared edges).
//! - The caller names up to two patches to ignore (the sender and receiver of a form factor), so an
//!   element never shadows itself.
//! - Built once with `BvhBuildParams::very_slow_build()`: on closed rooms `medium_build` trees
//!   traverse several times more nodes per ray, and the build is cheap next to the rays.
//!
//! `primitive_indices` is hidden: the polygon list is reordered into BVH order once at build.

use crate::math::DVec3;
use crate::scene::Scene;
use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::{Boundable, BvhBuildParams};
use std::time::Duration;

/// Relative tolerance (in local units, scene diagonal = 1) by which polygon edges are widened.
const EDGE_EPS: f32 = 1e-6;
/// Segment ends are pulled in by this much (local units) so the endpoints' own surfaces never count.
const END_EPS: f32 = 2e-6;

#[derive(Clone, Copy, Debug)]
struct Poly {
    /// Patch index in the scene.
    patch: u32,
    n_edges: u32,
    normal: Vec3A,
    d: f32,
    /// Inward edge normals (in the polygon plane) and offsets: inside if `e·p >= o` for all edges.
    edge_n: [Vec3A; 4],
    edge_o: [f32; 4],
    aabb: Aabb,
}

impl Boundable for Poly {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// "No polygon" for [`Accel::occluded_cached`]'s shadow cache.
pub const NO_HIT: u32 = u32::MAX;

/// One CWBVH node decoded for shadow rays: its eight child boxes as f32 planes (structure of
/// arrays, so the slab test of all eight runs as a few 8-wide vector instructions) and what each
/// child holds.
#[derive(Clone, Copy, Debug)]
struct WideNode {
    /// Child c's box: `lo[axis][c / 4][c % 4]`, `hi` likewise.
    lo: [[Vec4; 2]; 3],
    hi: [[Vec4; 2]; 3],
    /// Bit c set when slot c holds a child.
    used: u32,
    /// Per child: a node index, or [`LEAF`] | first polygon << 3 | polygon count (1 to 3).
    child: [u32; 8],
}

/// Marks a leaf child in [`WideNode::child`].
const LEAF: u32 = 1 << 31;
/// Entries of the shadow-ray traversal stack: a node pushes at most 7 children (it visits the
/// eighth), so trees up to `(WIDE_STACK - 1) / 7` levels deep fit; deeper ones use obvhs's own
/// traversal.
const WIDE_STACK: usize = 64;

/// The BVH over a scene's patches.
pub struct Accel {
    bvh: CwBvh,
    /// The same tree decoded for shadow rays (empty if it is too deep for [`WIDE_STACK`]).
    wide: Vec<WideNode>,
    /// Polygons in BVH primitive order.
    polys: Vec<Poly>,
    origin: DVec3,
    inv_scale: f64,
}

impl Accel {
    /// Build the BVH over every patch of the scene.
    #[must_use]
    pub fn build(scene: &Scene) -> Accel {
        let b = scene.bounds();
        let origin = b.center();
        let diag = b.diagonal();
        let inv_scale = if diag > 0.0 && diag.is_finite() { 1.0 / diag } else { 1.0 };
        let to_local = |p: DVec3| -> Vec3A {
            let q = (p - origin) * inv_scale;
            Vec3A::new(q.x as f32, q.y as f32, q.z as f32)
        };
        let polys: Vec<Poly> = scene
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let v: Vec<Vec3A> = p.vertices.iter().map(|&v| to_local(v)).collect();
                let n64 = p.normal;
                let normal = Vec3A::new(n64.x as f32, n64.y as f32, n64.z as f32);
                let c = to_local(p.centroid);
                let d = normal.dot(c);
                let mut edge_n = [Vec3A::ZERO; 4];
                let mut edge_o = [0.0f32; 4];
                for k in 0..v.len() {
                    let a = v[k];
                    let e = v[(k + 1) % v.len()] - a;
                    let en = normal.cross(e).normalize_or_zero(); // points inward for CCW
                    edge_n[k] = en;
                    edge_o[k] = en.dot(a) - EDGE_EPS;
                }
                let mut mn = v[0];
                let mut mx = v[0];
                for &q in &v[1..] {
                    mn = mn.min(q);
                    mx = mx.max(q);
                }
                let pad = Vec3A::splat(EDGE_EPS * 4.0);
                Poly {
                    patch: i as u32,
                    n_edges: v.len() as u32,
                    normal,
                    d,
                    edge_n,
                    edge_o,
                    aabb: Aabb::new(mn - pad, mx + pad),
                }
            })
            .collect();
        let mut t = Duration::ZERO;
        let bvh = obvhs::cwbvh::builder::build_cwbvh(&polys, BvhBuildParams::very_slow_build(), &mut t);
        let ordered = bvh.primitive_indices.iter().map(|&i| polys[i as usize]).collect();
        let wide = decode_wide(&bvh);
        Accel { bvh, wide, polys: ordered, origin, inv_scale }
    }

    /// Does the ray hit any polygon for which `hit(index)` (BVH order) says so? The CWBVH's own
    /// tree, traversed with unquantised 8-wide slab tests: the same polygons reach `hit` as with
    /// obvhs's traversal of that tree whenever the ray can hit them (both tests are
    /// conservative), so the answer is the same, for about a third of the box-test instructions.
    fn any_hit(&self, ray: &Ray, mut hit: impl FnMut(usize) -> bool) -> bool {
        if self.wide.is_empty() {
            return !self.bvh.ray_traverse_miss(*ray, |_, id| {
                if hit(id) { 0.5 * (ray.tmin + ray.tmax) } else { f32::INFINITY }
            });
        }
        let o = [Vec4::splat(ray.origin.x), Vec4::splat(ray.origin.y), Vec4::splat(ray.origin.z)];
        let inv = [
            Vec4::splat(ray.inv_direction.x),
            Vec4::splat(ray.inv_direction.y),
            Vec4::splat(ray.inv_direction.z),
        ];
        let (tmin, tmax) = (Vec4::splat(ray.tmin), Vec4::splat(ray.tmax));
        let mut stack = [0u32; WIDE_STACK];
        let mut sp = 0;
        let mut node = 0u32;
        loop {
            let n = &self.wide[node as usize];
            let mut mask = slab8(n, o, inv, tmin, tmax);
            while mask != 0 {
                let c = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let ch = n.child[c];
                if ch & LEAF == 0 {
                    stack[sp] = ch;
                    sp += 1;
                } else {
                    let first = ((ch & !LEAF) >> 3) as usize;
                    for i in first..first + (ch & 7) as usize {
                        if hit(i) {
                            return true;
                        }
                    }
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack[sp];
        }
    }

    fn to_local(&self, p: DVec3) -> Vec3A {
        let q = self.local_f64(p);
        Vec3A::new(q.x as f32, q.y as f32, q.z as f32)
    }

    /// A point in the BVH's local frame (centred on the scene's bounds, diagonal 1), in `f64`.
    /// The map is a translation and a uniform positive scale: directions and the signs of dot
    /// products with normals carry over.
    #[must_use]
    pub fn local_f64(&self, p: DVec3) -> DVec3 {
        (p - self.origin) * self.inv_scale
    }

    /// Number of polygons in the BVH.
    #[must_use]
    pub fn len(&self) -> usize {
        self.polys.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.polys.is_empty()
    }

    /// Is the open segment a→b blocked by any patch other than `ignore[0]`, `ignore[1]`?
    #[must_use]
    pub fn occluded(&self, a: DVec3, b: DVec3, ignore: [u32; 2]) -> bool {
        let mut last = NO_HIT;
        self.occluded_cached(a, b, ignore, &mut last)
    }

    /// [`Accel::occluded`] with a shadow cache (Haines & Greenberg, "The Light Buffer", 1986):
    /// `last` names the polygon that blocked a previous, nearby segment (or [`NO_HIT`]); it is
    /// tested first, and on a traversal hit `last` becomes the blocker. Segments between the
    /// same two regions are usually blocked by the same polygon, so a blocked segment mostly
    /// costs one polygon test instead of a traversal. The answer is the same as without it.
    #[must_use]
    pub fn occluded_cached(&self, a: DVec3, b: DVec3, ignore: [u32; 2], last: &mut u32) -> bool {
        self.occluded_local_cached(self.to_local(a), self.to_local(b), ignore, last)
    }

    /// [`Accel::occluded_cached`] for end points already in the BVH's local frame
    /// ([`Accel::local_f64`], rounded to `f32`).
    #[must_use]
    pub fn occluded_local_cached(&self, la: Vec3A, lb: Vec3A, ignore: [u32; 2], last: &mut u32) -> bool {
        let delta = lb - la;
        let len = delta.length();
        if !(len > 2.0 * END_EPS) {
            return false;
        }
        let dir = delta / len;
        let ray = Ray::new(la, dir, END_EPS, len - END_EPS);
        let usable = |p: &Poly| p.patch != ignore[0] && p.patch != ignore[1];
        if let Some(p) = self.polys.get(*last as usize)
            && usable(p)
            && intersect(p, &ray).is_finite()
        {
            return true;
        }
        let mut blocker = NO_HIT;
        let blocked = self.any_hit(&ray, |id| {
            let p = &self.polys[id];
            if usable(p) && intersect(p, &ray).is_finite() {
                blocker = id as u32;
                true
            } else {
                false
            }
        });
        if blocked {
            *last = blocker;
        }
        blocked
    }

    /// First patch hit along the ray from `origin` in direction `dir` (any length), ignoring
    /// `ignore`. Returns `(patch, distance)` in scene units.
    #[must_use]
    pub fn first_hit(&self, origin: DVec3, dir: DVec3, ignore: u32) -> Option<(u32, f64)> {
        let lo = self.to_local(origin);
        let d = dir.normalize();
        let ld = Vec3A::new(d.x as f32, d.y as f32, d.z as f32);
        let ray = Ray::new(lo, ld, END_EPS, f32::INFINITY);
        let mut hit = obvhs::ray::RayHit::none();
        if self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            let p = &self.polys[id];
            if p.patch == ignore { f32::INFINITY } else { intersect(p, r) }
        }) {
            let p = self.polys[hit.primitive_id as usize].patch;
            Some((p, f64::from(hit.t) / self.inv_scale))
        } else {
            None
        }
    }
}

/// The CWBVH's nodes decoded into [`WideNode`]s (node i is the CWBVH's node i), or nothing when
/// the tree is deeper than the shadow-ray stack allows.
fn decode_wide(bvh: &CwBvh) -> Vec<WideNode> {
    let mut out = Vec::with_capacity(bvh.nodes.len());
    for n in &bvh.nodes {
        let mut w =
            WideNode { lo: [[Vec4::ZERO; 2]; 3], hi: [[Vec4::ZERO; 2]; 3], used: 0, child: [LEAF; 8] };
        for c in 0..8 {
            if n.is_child_empty(c) {
                continue;
            }
            let b = n.child_aabb(c);
            w.used |= 1 << c;
            for a in 0..3 {
                w.lo[a][c / 4][c % 4] = b.min[a];
                w.hi[a][c / 4][c % 4] = b.max[a];
            }
            if n.is_leaf(c) {
                let (first, count) = n.child_primitives(c);
                debug_assert!((1..=7).contains(&count) && first < 1 << 27);
                w.child[c] = LEAF | first << 3 | count;
            } else {
                w.child[c] = n.child_node_index(c);
            }
        }
        out.push(w);
    }
    // Depth from the root, whatever order the builder laid the nodes out in.
    let mut deepest = 0;
    let mut todo = vec![(0u32, 0usize)];
    while let Some((node, d)) = todo.pop() {
        deepest = deepest.max(d);
        let Some(w) = out.get(node as usize) else { return Vec::new() };
        for c in 0..8 {
            if w.used & (1 << c) != 0 && w.child[c] & LEAF == 0 {
                todo.push((w.child[c], d + 1));
            }
        }
    }
    if out.is_empty() || 7 * deepest + 8 > WIDE_STACK { Vec::new() } else { out }
}

/// Which of the node's eight child boxes the ray's [tmin, tmax] interval meets (bit c for child
/// c), four at a time with glam's SIMD `Vec4`. No NaN can arise (`Ray` keeps `inv_direction`
/// finite).
#[inline(always)]
fn slab8(n: &WideNode, o: [Vec4; 3], inv: [Vec4; 3], tmin: Vec4, tmax: Vec4) -> u32 {
    let mut mask = 0;
    for h in 0..2 {
        let mut t0 = tmin;
        let mut t1 = tmax;
        for a in 0..3 {
            let x0 = (n.lo[a][h] - o[a]) * inv[a];
            let x1 = (n.hi[a][h] - o[a]) * inv[a];
            t0 = t0.max(x0.min(x1));
            t1 = t1.min(x0.max(x1));
        }
        mask |= t0.cmple(t1).bitmask() << (4 * h);
    }
    mask & n.used
}

#[inline]
fn intersect(p: &Poly, r: &Ray) -> f32 {
    let denom = p.normal.dot(r.direction);
    if denom.abs() < 1e-12 {
        return f32::INFINITY;
    }
    let t = (p.d - p.normal.dot(r.origin)) / denom;
    if !(t > r.tmin && t < r.tmax) {
        return f32::INFINITY;
    }
    let q = r.origin + r.direction * t;
    for k in 0..p.n_edges as usize {
        if p.edge_n[k].dot(q) < p.edge_o[k] {
            return f32::INFINITY;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;
    use crate::scene::Patch;

    fn quad(v: [[f64; 3]; 4], name: &str) -> Patch {
        Patch::new(
            v.iter().map(|a| DVec3::from_array(*a)).collect(),
            Rgb::splat(0.5),
            Rgb::ZERO,
            name,
            0,
            name,
            "m",
        )
        .unwrap()
    }

    fn two_squares_and_blocker(offset: DVec3, scale: f64) -> Scene {
        let t = |p: [f64; 3]| {
            let q = DVec3::from_array(p) * scale + offset;
            q.to_array()
        };
        Scene::new(
            "t",
            "t",
            vec![
                quad([t([0., 0., 0.]), t([1., 0., 0.]), t([1., 1., 0.]), t([0., 1., 0.])], "floor"),
                quad([t([0., 0., 2.]), t([0., 1., 2.]), t([1., 1., 2.]), t([1., 0., 2.])], "ceil"),
                // blocker covering x in [0, 0.5] at z = 1, split in two quads sharing the edge x = 0.25
                quad([t([0., 0., 1.]), t([0.25, 0., 1.]), t([0.25, 1., 1.]), t([0., 1., 1.])], "b1"),
                quad([t([0.25, 0., 1.]), t([0.5, 0., 1.]), t([0.5, 1., 1.]), t([0.25, 1., 1.])], "b2"),
            ],
        )
    }

    #[test]
    fn blocks_and_passes_at_any_offset_and_scale() {
        for (off, s) in
            [(DVec3::ZERO, 1.0), (DVec3::splat(1e6), 1.0), (DVec3::ZERO, 1e-4), (DVec3::splat(-3.0), 1e4)]
        {
            let sc = two_squares_and_blocker(off, s);
            let acc = Accel::build(&sc);
            let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * s + off;
            assert!(acc.occluded(p(0.1, 0.5, 0.0), p(0.1, 0.5, 2.0), [0, 1]), "offset {off} scale {s}");
            assert!(!acc.occluded(p(0.9, 0.5, 0.0), p(0.9, 0.5, 2.0), [0, 1]), "offset {off} scale {s}");
            // Exactly through the shared edge x = 0.25: must not leak.
            assert!(acc.occluded(p(0.25, 0.5, 0.0), p(0.25, 0.5, 2.0), [0, 1]), "edge leak at {off} {s}");
        }
    }

    #[test]
    fn endpoints_on_surfaces_do_not_self_occlude() {
        let sc = two_squares_and_blocker(DVec3::ZERO, 1.0);
        let acc = Accel::build(&sc);
        // From the blocker's top to the ceiling, ignoring nothing: the blocker itself is at t=0.
        assert!(!acc.occluded(DVec3::new(0.1, 0.5, 1.0), DVec3::new(0.1, 0.5, 2.0), [u32::MAX, u32::MAX]));
    }

    /// The shadow cache never changes the answer: a stale blocker that misses, or one that
    /// belongs to an ignored patch, falls back to the traversal; a hit records the blocker.
    #[test]
    fn shadow_cache_gives_the_same_answers() {
        let sc = two_squares_and_blocker(DVec3::ZERO, 1.0);
        let acc = Accel::build(&sc);
        let mut rng = crate::math::Pcg32::keyed(1, 2);
        let mut last = NO_HIT;
        for k in 0..400 {
            let a = DVec3::new(rng.next_f64(), rng.next_f64(), 0.0);
            let b = DVec3::new(rng.next_f64(), rng.next_f64(), 2.0);
            // Every 7th segment ignores the blocker b1 (patch 2) too, while `last` may name it.
            let ignore = if k % 7 == 0 { [0, 2] } else { [0, 1] };
            let plain = acc.occluded(a, b, ignore);
            assert_eq!(acc.occluded_cached(a, b, ignore, &mut last), plain, "segment {k}: {a} → {b}");
            if plain {
                assert_ne!(last, NO_HIT, "a hit records its blocker");
            }
        }
    }

    /// The shadow-ray traversal finds a blocker exactly when testing every polygon does, on
    /// segments between random points of the room's patches (many start on one surface and
    /// pass within a hair of another, where a box test that is not conservative fails), and on
    /// the Cornell box.
    #[test]
    fn shadow_rays_agree_with_testing_every_polygon() {
        for name in ["builtin:splash_room", "builtin:cornell"] {
            let sc = Scene::load(name).unwrap();
            let acc = Accel::build(&sc);
            assert!(!acc.wide.is_empty(), "{name}: the decoded tree must be in use");
            let mut rng = crate::math::Pcg32::keyed(7, 11);
            let n = sc.patches.len();
            let (mut blocked, mut total) = (0, 0);
            for _ in 0..20_000 {
                let i = (rng.next_u32() as usize) % n;
                let j = (rng.next_u32() as usize) % n;
                let a = crate::visibility::point_on_polygon(
                    &sc.patches[i].vertices,
                    rng.next_f64(),
                    rng.next_f64(),
                );
                let b = crate::visibility::point_on_polygon(
                    &sc.patches[j].vertices,
                    rng.next_f64(),
                    rng.next_f64(),
                );
                let ignore = [i as u32, j as u32];
                let (la, lb) = (acc.to_local(a), acc.to_local(b));
                let len = (lb - la).length();
                if !(len > 2.0 * END_EPS) {
                    continue;
                }
                let ray = Ray::new(la, (lb - la) / len, END_EPS, len - END_EPS);
                let brute =
                    acc.polys.iter().any(|p| !ignore.contains(&p.patch) && intersect(p, &ray).is_finite());
                assert_eq!(acc.occluded(a, b, ignore), brute, "{name}: {a} → {b} (patches {i}, {j})");
                blocked += usize::from(brute);
                total += 1;
            }
            assert!(blocked > total / 20 && blocked < total, "{name}: {blocked} of {total} blocked");
        }
    }

    #[test]
    fn first_hit_finds_nearest() {
        let sc = two_squares_and_blocker(DVec3::ZERO, 1.0);
        let acc = Accel::build(&sc);
        let (p, t) = acc.first_hit(DVec3::new(0.1, 0.5, 0.0), DVec3::Z, 0).unwrap();
        assert_eq!(p, 2);
        assert!((t - 1.0).abs() < 1e-5);
        assert!(acc.first_hit(DVec3::new(0.9, 0.5, 0.0), -DVec3::Z, 0).is_none());
    }
}
