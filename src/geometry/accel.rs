//! Ray-cast acceleration: an obvhs CWBVH over the scene's input polygons, answering
//! "is the segment a→b blocked?" (any-hit) and "what is the first patch hit?" (obvhs's
//! `ray_traverse`).
//!
//! Shadow rays (any-hit, nearly all the rays the solvers cast) traverse the same tree decoded
//! once into unquantised 8-wide nodes, four slab tests per SIMD instruction: a small part of the
//! box-test work of obvhs's traversal, which dequantises each node per ray, and conservative
//! where that one is not (rays starting a hair from another polygon's box were missed).
//!
//! ## Shadow-ray traversal
//! ```text
//!  segment a→b ─▶ local frame ─▶ shadow cache: last blocker hit? ──yes──▶ blocked
//!                                      │ no
//!                                      ▼
//!  node: slab test of its 8 child boxes (near plane per axis from the ray's signs)
//!    ├─ leaf children, slot order: 4-wide plane test of the leaf's polygons,
//!    │     edges of those whose plane the segment crosses ──inside──▶ blocked
//!    └─ node children, slot order: pushed (popped last-pushed first) ──▶ node …
//! ```
//! Every step does the arithmetic of the plain scalar tests lane by lane (the slab test's
//! `min`/`max` replaced by the plane the ray meets first, which rounding cannot reorder), so
//! the polygons tested, their order, and every answer are those of a scalar traversal.
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
use std::sync::OnceLock;
use std::time::Duration;

/// Relative tolerance (in local units, scene diagonal = 1) by which polygon edges are widened.
const EDGE_EPS: f32 = 1e-6;
/// How far (local units) a polygon may reach into a shaft and still count as outside it
/// ([`Accel::shaft_clear`]): polygons that touch the hull's boundary (the floor under a box,
/// a wall both polygons meet) only graze it.
pub const SHAFT_TOL: f32 = 1e-5;
/// Segment ends are pulled in by this much (local units) so the endpoints' own surfaces never count.
const END_EPS: f32 = 2e-6;

#[derive(Clone, Copy, Debug)]
struct Poly {
    /// Patch index in the scene.
    patch: u32,
    normal: Vec3A,
    d: f32,
    /// Inward edge normals (in the polygon plane) and offsets, edge k in lane k: inside if
    /// `e·p >= o` for all edges.
    edge_x: Vec4,
    edge_y: Vec4,
    edge_z: Vec4,
    edge_o: Vec4,
    /// Bit k set for each edge k the polygon has.
    edges: u32,
    aabb: Aabb,
}

impl Boundable for Poly {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// "No polygon" for [`Accel::occluded_cached`]'s shadow cache.
pub const NO_HIT: u32 = u32::MAX;

/// Eight `f32` lanes as two glam `Vec4`s: each operation is one SSE/AVX instruction per half
/// (`minps`/`maxps`/`cmpleps`, as the min/max slab test always used). Safe code cannot name
/// 256-bit intrinsics without `#[target_feature]` on every caller, and per-lane loops over
/// `[f32; 8]` vectorise badly (they compile to more instructions than two `Vec4`s).
mod lanes {
    use glam::Vec4;

    #[derive(Clone, Copy, Debug)]
    pub struct F8([Vec4; 2]);

    impl F8 {
        #[inline(always)]
        pub fn splat(x: f32) -> F8 {
            F8([Vec4::splat(x); 2])
        }

        pub fn from_array(a: [f32; 8]) -> F8 {
            F8([Vec4::new(a[0], a[1], a[2], a[3]), Vec4::new(a[4], a[5], a[6], a[7])])
        }

        #[inline(always)]
        pub fn sub(self, rhs: F8) -> F8 {
            F8([self.0[0] - rhs.0[0], self.0[1] - rhs.0[1]])
        }

        #[inline(always)]
        pub fn add(self, rhs: F8) -> F8 {
            F8([self.0[0] + rhs.0[0], self.0[1] + rhs.0[1]])
        }

        #[inline(always)]
        pub fn mul(self, rhs: F8) -> F8 {
            F8([self.0[0] * rhs.0[0], self.0[1] * rhs.0[1]])
        }

        #[inline(always)]
        pub fn min(self, rhs: F8) -> F8 {
            F8([self.0[0].min(rhs.0[0]), self.0[1].min(rhs.0[1])])
        }

        #[inline(always)]
        pub fn max(self, rhs: F8) -> F8 {
            F8([self.0[0].max(rhs.0[0]), self.0[1].max(rhs.0[1])])
        }

        /// Bit c set where lane c of `self` <= lane c of `rhs`.
        #[inline(always)]
        pub fn le_mask(self, rhs: F8) -> u32 {
            self.0[0].cmple(rhs.0[0]).bitmask() | self.0[1].cmple(rhs.0[1]).bitmask() << 4
        }
    }
}

use lanes::F8;

/// One CWBVH node decoded for shadow rays: its eight child boxes as f32 planes (structure of
/// arrays, so the slab test of all eight is a few 8-wide vector instructions) and what each
/// child holds.
#[derive(Clone, Copy, Debug)]
struct WideNode {
    /// `planes[axis][0]`: the children's lower bounds along `axis`, lane c for child c;
    /// `planes[axis][1]`: their upper bounds. An empty slot holds the inverted box
    /// (+∞, −∞), which no ray meets.
    planes: [[F8; 2]; 3],
    /// Per child slot: the child's node index when it is a node.
    child: [u32; 8],
    /// Bit c set when child c is a leaf.
    leaves: u32,
    /// Per child slot: the leaf's polygons (no lanes when the child is not a leaf).
    packs: [LeafPack; 8],
}

/// Entries of the shadow-ray traversal stack. While a node at depth k is processed, at most 7
/// siblings wait per level above it and it pushes at most 8 children; only nodes above the
/// deepest push, so a tree whose deepest node is at depth D needs `7 D + 1` entries: D <= 9
/// fits; deeper trees use obvhs's own traversal.
const WIDE_STACK: usize = 64;
/// The stack used when it suffices (D <= 4, the built-in rooms): half the entries to clear per
/// ray.
const SMALL_STACK: usize = 32;
/// Polygons per [`LeafPack`]; a CWBVH leaf holds at most 3.
const PACK: usize = 4;

/// The polygons of one leaf as structure of arrays: their planes, for a 4-wide plane test.
#[derive(Clone, Copy, Debug, Default)]
struct LeafPack {
    nx: Vec4,
    ny: Vec4,
    nz: Vec4,
    d: Vec4,
    /// Lane k is polygon `first + k` (BVH order).
    first: u32,
    /// Bit k set when lane k holds a polygon.
    lanes: u32,
}

/// The BVH over a scene's patches.
pub struct Accel {
    bvh: CwBvh,
    /// The same tree decoded for shadow rays (empty if it is too deep for [`WIDE_STACK`]).
    wide: Vec<WideNode>,
    /// Entries the traversal stack needs (at most [`WIDE_STACK`]).
    stack_needs: usize,
    /// Polygons in BVH primitive order.
    polys: Vec<Poly>,
    /// Their vertices in the local frame (BVH order) and how many there are (3 or 4), for
    /// [`Accel::shaft_clear`]: made at its first call, so the solves that never test a shaft
    /// (the BF oracle's) do not hold them (80 bytes a polygon, 80 MB for furnished-1m).
    poly_verts: OnceLock<Vec<([Vec3A; 4], u8)>>,
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
                    normal,
                    d,
                    edge_x: Vec4::from_array(edge_n.map(|e| e.x)),
                    edge_y: Vec4::from_array(edge_n.map(|e| e.y)),
                    edge_z: Vec4::from_array(edge_n.map(|e| e.z)),
                    edge_o: Vec4::from_array(edge_o),
                    edges: (1 << v.len()) - 1,
                    aabb: Aabb::new(mn - pad, mx + pad),
                }
            })
            .collect();
        let mut t = Duration::ZERO;
        let bvh = obvhs::cwbvh::builder::build_cwbvh(&polys, BvhBuildParams::very_slow_build(), &mut t);
        let ordered: Vec<Poly> = bvh.primitive_indices.iter().map(|&i| polys[i as usize]).collect();
        let (wide, stack_needs) = decode_wide(&bvh, &ordered);
        Accel { bvh, wide, stack_needs, polys: ordered, poly_verts: OnceLock::new(), origin, inv_scale }
    }

    /// The first polygon (in traversal order) that blocks the shadow ray, or `None`. The
    /// CWBVH's own tree, traversed with unquantised 8-wide slab tests: the same polygons are
    /// tested as with obvhs's traversal of that tree whenever the ray can hit them (both tests
    /// are conservative), so the answer is the same, for a fraction of the box-test instructions.
    fn shadow_blocker(&self, ray: &Ray, ignore: [u32; 2]) -> Option<u32> {
        if self.stack_needs <= SMALL_STACK {
            self.shadow_blocker_in::<SMALL_STACK>(ray, ignore)
        } else {
            self.shadow_blocker_in::<WIDE_STACK>(ray, ignore)
        }
    }

    /// [`Accel::shadow_blocker`] with a traversal stack of `N` entries.
    #[inline(always)]
    fn shadow_blocker_in<const N: usize>(&self, ray: &Ray, ignore: [u32; 2]) -> Option<u32> {
        let usable = |p: &Poly| p.patch != ignore[0] && p.patch != ignore[1];
        if self.wide.is_empty() {
            let mut blocker = None;
            self.bvh.ray_traverse_miss(*ray, |_, id| {
                let p = &self.polys[id];
                if usable(p) && intersect(p, ray).is_finite() {
                    blocker = Some(id as u32);
                    0.5 * (ray.tmin + ray.tmax)
                } else {
                    f32::INFINITY
                }
            });
            return blocker;
        }
        let boxes = SlabRay::new(ray);
        let planes = PlaneRay::new(ray);
        // Leaves first, then the nodes: the same polygons in the same order as visiting the
        // children in slot order, since pushing a node tests nothing.
        self.find_in_leaves::<N, u32>(|n| boxes.hits(n), |pack| self.pack_blocker(pack, ray, &planes, ignore))
    }

    /// Walk the wide tree from its root down the children `reach` selects (bit c for child c),
    /// a node's leaves before its nodes, each in slot order, with a stack of `N` entries: the
    /// first `Some` that `leaf` gives a leaf pack, or `None` when none does.
    #[inline(always)]
    fn find_in_leaves<const N: usize, R>(
        &self,
        reach: impl Fn(&WideNode) -> u32,
        mut leaf: impl FnMut(&LeafPack) -> Option<R>,
    ) -> Option<R> {
        let mut stack = [0u32; N];
        let mut sp = 0;
        let mut node = 0u32;
        loop {
            let n = &self.wide[node as usize];
            let mask = reach(n);
            let mut leaves = mask & n.leaves;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                if let Some(found) = leaf(&n.packs[c]) {
                    return Some(found);
                }
            }
            let mut nodes = mask & !n.leaves;
            while nodes != 0 {
                let c = nodes.trailing_zeros() as usize;
                nodes &= nodes - 1;
                stack[sp] = n.child[c];
                sp += 1;
            }
            if sp == 0 {
                return None;
            }
            sp -= 1;
            node = stack[sp];
        }
    }

    /// The first polygon of the leaf, in lane order, that blocks the ray: the planes of all its
    /// polygons at once, then the edges of those whose plane the segment crosses. Exactly
    /// [`intersect`]'s arithmetic, lane by lane.
    #[inline]
    fn pack_blocker(&self, pack: &LeafPack, ray: &Ray, r: &PlaneRay, ignore: [u32; 2]) -> Option<u32> {
        let denom = pack.nx * r.d[0] + pack.ny * r.d[1] + pack.nz * r.d[2];
        let dist = pack.nx * r.o[0] + pack.ny * r.o[1] + pack.nz * r.o[2];
        let t = (pack.d - dist) / denom;
        let crosses = denom.abs().cmpge(Vec4::splat(PARALLEL)) & t.cmpgt(r.tmin) & t.cmplt(r.tmax);
        let mut m = crosses.bitmask() & pack.lanes;
        if m == 0 {
            return None;
        }
        let t = t.to_array();
        while m != 0 {
            let k = m.trailing_zeros() as usize;
            m &= m - 1;
            let id = pack.first as usize + k;
            let p = &self.polys[id];
            if p.patch != ignore[0]
                && p.patch != ignore[1]
                && inside_edges(p, ray.origin + ray.direction * t[k])
            {
                return Some(id as u32);
            }
        }
        None
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
        let ray = shadow_ray(la, delta / len, END_EPS, len - END_EPS);
        if let Some(p) = self.polys.get(*last as usize)
            && p.patch != ignore[0]
            && p.patch != ignore[1]
            && intersect(p, &ray).is_finite()
        {
            return true;
        }
        match self.shadow_blocker(&ray, ignore) {
            Some(id) => {
                *last = id;
                true
            }
            None => false,
        }
    }

    /// Is the shaft between two convex polygons (scene coordinates) empty: does no polygon of
    /// the scene but the patches `ignore` meet the interior of the convex hull of their
    /// vertices? Every segment between a point of `a` and a point of `b` lies in that hull, so
    /// an empty shaft means the two see each other whole, V = 1 exactly, with no ray cast
    /// [Haines & Wallace 1994, "Shaft culling for efficient ray-cast radiosity": the shaft
    /// test; here the shaft is the exact hull, its face planes found by brute force over the
    /// vertex triples, at most 16 vertices].
    ///
    /// Conservative: `false` whenever it cannot tell (a polygon neither outside one of the
    /// hull's face planes nor with the whole hull on one side of its own plane, a degenerate
    /// hull, too many vertices, a tree too deep for the wide traversal). Polygons that touch
    /// the hull's boundary within [`SHAFT_TOL`] (the floor a box stands on, a wall the two
    /// polygons both meet) do not count: a segment can only graze them.
    ///
    /// `scene` is the scene the tree was built from (its polygons' vertices are read from it
    /// once); another scene, of a different patch count, answers `false`.
    #[must_use]
    pub fn shaft_clear(&self, scene: &Scene, a: &[DVec3], b: &[DVec3], ignore: [u32; 2]) -> bool {
        if self.wide.is_empty()
            || a.len() + b.len() > SHAFT_MAX_VERTICES
            || scene.patches.len() != self.polys.len()
        {
            return false;
        }
        let poly_verts = self.poly_verts(scene);
        let mut pts = [DVec3::ZERO; SHAFT_MAX_VERTICES];
        let n = a.len() + b.len();
        for (o, &p) in pts.iter_mut().zip(a.iter().chain(b)) {
            *o = self.local_f64(p);
        }
        let pts = &pts[..n];
        if pts.iter().any(|p| !p.is_finite()) {
            return false;
        }
        let tol = f64::from(SHAFT_TOL);
        let Some(planes) = hull_planes(pts, tol) else { return false };
        let planes32: Vec<([f32; 3], f32)> = planes
            .iter()
            .map(|(nrm, d)| ([nrm.x as f32, nrm.y as f32, nrm.z as f32], (*d + tol) as f32))
            .collect();
        let pts32: Vec<Vec3A> = pts.iter().map(|p| Vec3A::new(p.x as f32, p.y as f32, p.z as f32)).collect();
        // Is polygon `id` (BVH order) outside the shaft?
        let separated = |id: usize| {
            let (v, m) = &poly_verts[id];
            let v = &v[..usize::from(*m)];
            let outside = planes32.iter().any(|(nrm, d)| {
                let nrm = Vec3A::from_array(*nrm);
                v.iter().all(|q| nrm.dot(*q) >= *d - 2.0 * SHAFT_TOL)
            });
            if outside {
                return true;
            }
            let p = &self.polys[id];
            let (lo, hi) = pts32.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), q| {
                let s = p.normal.dot(*q) - p.d;
                (lo.min(s), hi.max(s))
            });
            lo >= -SHAFT_TOL || hi <= SHAFT_TOL
        };
        self.none_in_shaft(&planes32, |id| {
            let patch = self.polys[id].patch;
            patch == ignore[0] || patch == ignore[1] || separated(id)
        })
    }

    /// Each polygon's vertices in the tree's local frame (BVH order), read from `scene` once.
    fn poly_verts(&self, scene: &Scene) -> &[([Vec3A; 4], u8)] {
        self.poly_verts.get_or_init(|| {
            self.polys
                .iter()
                .map(|p| {
                    let v = &scene.patches[p.patch as usize].vertices;
                    let mut out = [Vec3A::ZERO; 4];
                    for (o, &q) in out.iter_mut().zip(v) {
                        *o = self.to_local(q);
                    }
                    (out, v.len().min(4) as u8)
                })
                .collect()
        })
    }

    /// Walk the wide tree down the child boxes not wholly outside one of `planes` (n·x <= d
    /// inside): true when every polygon in a box that reaches the shaft passes `outside`.
    fn none_in_shaft(&self, planes: &[([f32; 3], f32)], outside: impl Fn(usize) -> bool) -> bool {
        // Child boxes not wholly outside one of the planes: min over the box of n·x <= d.
        let reach = |w: &WideNode| {
            let mut mask = 0xFF;
            for (nrm, d) in planes {
                let mut m = F8::splat(0.0);
                for (axis, &n) in w.planes.iter().zip(nrm) {
                    let side = usize::from(n < 0.0);
                    m = m.add(axis[side].mul(F8::splat(n)));
                }
                mask &= m.le_mask(F8::splat(*d));
                if mask == 0 {
                    break;
                }
            }
            mask
        };
        let inside = |pack: &LeafPack| {
            let mut lanes = pack.lanes;
            while lanes != 0 {
                let k = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                if !outside(pack.first as usize + k) {
                    return Some(());
                }
            }
            None
        };
        self.find_in_leaves::<WIDE_STACK, ()>(reach, inside).is_none()
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

/// `Ray::new(origin, dir, tmin, tmax)` with the three reciprocals in one vector division:
/// obvhs's `safe_inverse` lane by lane (`1/x`, or `signum(x)/ε` where `|x| <= ε`), the same
/// values.
#[inline]
fn shadow_ray(origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32) -> Ray {
    let tiny = dir.abs().cmple(Vec3A::splat(f32::EPSILON));
    let inv = Vec3A::select(tiny, Vec3A::ONE.copysign(dir) / f32::EPSILON, Vec3A::ONE / dir);
    Ray { origin, direction: dir, inv_direction: inv, tmin, tmax }
}

/// A ray set up for [`WideNode`] slab tests: origin, reciprocal direction and interval in all
/// eight lanes, and per axis which plane the ray meets first.
struct SlabRay {
    o: [F8; 3],
    inv: [F8; 3],
    /// 1 where the ray runs towards −axis (it enters a box through its upper plane), else 0.
    near: [usize; 3],
    tmin: F8,
    tmax: F8,
}

impl SlabRay {
    #[inline(always)]
    fn new(ray: &Ray) -> SlabRay {
        let (o, inv) = (ray.origin, ray.inv_direction);
        SlabRay {
            o: [F8::splat(o.x), F8::splat(o.y), F8::splat(o.z)],
            inv: [F8::splat(inv.x), F8::splat(inv.y), F8::splat(inv.z)],
            near: [usize::from(inv.x < 0.0), usize::from(inv.y < 0.0), usize::from(inv.z < 0.0)],
            tmin: F8::splat(ray.tmin),
            tmax: F8::splat(ray.tmax),
        }
    }

    /// Which of the node's eight child boxes the ray's [tmin, tmax] interval meets (bit c for
    /// child c). The textbook slab test `max(tmin, min(x0, x1)) <= min(tmax, max(x0, x1))`
    /// with `x = (plane - o) / dir` per axis, where the near plane's `x` is the min of the two
    /// without computing it: `(lo - o) * inv <= (hi - o) * inv` when `inv > 0` because rounded
    /// subtraction and multiplication are monotonic (and the other way round when `inv < 0`),
    /// so the masks are bit for bit those of the min/max form. No NaN arises (`inv` is finite
    /// and non-zero; the empty slots' infinities give ±∞).
    #[inline(always)]
    fn hits(&self, n: &WideNode) -> u32 {
        let mut t0 = self.tmin;
        let mut t1 = self.tmax;
        for a in 0..3 {
            let near = n.planes[a][self.near[a]].sub(self.o[a]).mul(self.inv[a]);
            let far = n.planes[a][1 - self.near[a]].sub(self.o[a]).mul(self.inv[a]);
            t0 = t0.max(near);
            t1 = t1.min(far);
        }
        t0.le_mask(t1)
    }
}

/// A ray set up for [`LeafPack`] plane tests: origin, direction and interval in four lanes.
struct PlaneRay {
    o: [Vec4; 3],
    d: [Vec4; 3],
    tmin: Vec4,
    tmax: Vec4,
}

impl PlaneRay {
    #[inline(always)]
    fn new(ray: &Ray) -> PlaneRay {
        let (o, d) = (ray.origin, ray.direction);
        PlaneRay {
            o: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            d: [Vec4::splat(d.x), Vec4::splat(d.y), Vec4::splat(d.z)],
            tmin: Vec4::splat(ray.tmin),
            tmax: Vec4::splat(ray.tmax),
        }
    }
}

/// The CWBVH's nodes decoded into [`WideNode`]s (node i is the CWBVH's node i, its leaves
/// into [`LeafPack`]s) and the traversal stack entries they need; no nodes when the tree is
/// deeper than [`WIDE_STACK`] allows. `polys` is in BVH order.
fn decode_wide(bvh: &CwBvh, polys: &[Poly]) -> (Vec<WideNode>, usize) {
    let mut out = Vec::with_capacity(bvh.nodes.len());
    for n in &bvh.nodes {
        let mut lo = [[f32::INFINITY; 8]; 3];
        let mut hi = [[f32::NEG_INFINITY; 8]; 3];
        let mut child = [0; 8];
        let mut leaves = 0;
        let mut packs = [LeafPack::default(); 8];
        for c in 0..8 {
            if n.is_child_empty(c) {
                continue;
            }
            let b = n.child_aabb(c);
            for a in 0..3 {
                // min/max keeps an inverted box (never built) tested as the min/max form would.
                lo[a][c] = b.min[a].min(b.max[a]);
                hi[a][c] = b.min[a].max(b.max[a]);
            }
            if n.is_leaf(c) {
                let (first, count) = n.child_primitives(c);
                let Some(members) = polys.get(first as usize..(first + count) as usize) else {
                    return (Vec::new(), 0);
                };
                if members.is_empty() || members.len() > PACK {
                    return (Vec::new(), 0);
                }
                let lane = |f: &dyn Fn(&Poly) -> f32| {
                    Vec4::from_array(std::array::from_fn(|k| members.get(k).map_or(0.0, f)))
                };
                leaves |= 1 << c;
                packs[c] = LeafPack {
                    nx: lane(&|p| p.normal.x),
                    ny: lane(&|p| p.normal.y),
                    nz: lane(&|p| p.normal.z),
                    d: lane(&|p| p.d),
                    first,
                    lanes: (1 << members.len()) - 1,
                };
            } else {
                child[c] = n.child_node_index(c);
            }
        }
        let planes = std::array::from_fn(|a| [F8::from_array(lo[a]), F8::from_array(hi[a])]);
        out.push(WideNode { planes, child, leaves, packs });
    }
    // Depth from the root, whatever order the builder laid the nodes out in.
    let mut deepest = 0;
    let mut todo = vec![(0u32, 0usize)];
    while let Some((node, d)) = todo.pop() {
        deepest = deepest.max(d);
        let (Some(w), Some(n)) = (out.get(node as usize), bvh.nodes.get(node as usize)) else {
            return (Vec::new(), 0);
        };
        for c in 0..8 {
            if !n.is_child_empty(c) && w.leaves & (1 << c) == 0 {
                todo.push((w.child[c], d + 1));
            }
        }
    }
    let needs = 7 * deepest + 1;
    if out.is_empty() || needs > WIDE_STACK { (Vec::new(), 0) } else { (out, needs) }
}

/// `|n · dir|` below this: the ray runs parallel to the polygon's plane and misses it.
const PARALLEL: f32 = 1e-12;

#[inline]
fn intersect(p: &Poly, r: &Ray) -> f32 {
    let denom = p.normal.dot(r.direction);
    if denom.abs() < PARALLEL {
        return f32::INFINITY;
    }
    let t = (p.d - p.normal.dot(r.origin)) / denom;
    if !(t > r.tmin && t < r.tmax) {
        return f32::INFINITY;
    }
    if inside_edges(p, r.origin + r.direction * t) { t } else { f32::INFINITY }
}

/// Is the point `q` of the polygon's plane inside all its (widened) edges? All edges at once:
/// `(x·qx + y·qy) + z·qz`, glam's `dot` order, lane by lane.
#[inline]
fn inside_edges(p: &Poly, q: Vec3A) -> bool {
    let dot = p.edge_x * q.x + p.edge_y * q.y + p.edge_z * q.z;
    dot.cmplt(p.edge_o).bitmask() & p.edges == 0
}

/// Most vertices of the two polygons [`Accel::shaft_clear`] takes (its hull's face planes are
/// found over every triple of them).
const SHAFT_MAX_VERTICES: usize = 16;

/// The outward face planes (n·x <= d inside, within `tol`) of the convex hull of `pts`, found
/// by brute force over the vertex triples, then its bounding box's six; `None` when the hull
/// is flat (fewer than four faces: coplanar polygons, no shaft).
fn hull_planes(pts: &[DVec3], tol: f64) -> Option<Vec<(DVec3, f64)>> {
    let n = pts.len();
    let mut planes: Vec<(DVec3, f64)> = Vec::with_capacity(32);
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let nrm = (pts[j] - pts[i]).cross(pts[k] - pts[i]);
                let len = nrm.length();
                if !(len > 1e-12) {
                    continue;
                }
                let nrm = nrm / len;
                let d = nrm.dot(pts[i]);
                let (lo, hi) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    let s = nrm.dot(*p) - d;
                    (lo.min(s), hi.max(s))
                });
                let plane = if hi <= tol {
                    (nrm, d)
                } else if lo >= -tol {
                    (-nrm, -d)
                } else {
                    continue;
                };
                if !planes.iter().any(|q| q.0.dot(plane.0) > 1.0 - 1e-9 && (q.1 - plane.1).abs() <= tol) {
                    planes.push(plane);
                }
            }
        }
    }
    // A closed hull has four faces at least; fewer: flat (coplanar polygons), no shaft.
    if planes.len() < 4 {
        return None;
    }
    let (bmin, bmax) =
        pts.iter().fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    for (axis, unit) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
        planes.push((unit, bmax[axis]));
        planes.push((-unit, -bmin[axis]));
    }
    Some(planes)
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

    /// Rectangle [x0, x1] × [0, 1] at height z, facing up or down.
    fn strip(x0: f64, x1: f64, z: f64, up: bool) -> Vec<DVec3> {
        let v = vec![
            DVec3::new(x0, 0.0, z),
            DVec3::new(x1, 0.0, z),
            DVec3::new(x1, 1.0, z),
            DVec3::new(x0, 1.0, z),
        ];
        if up { v } else { v.into_iter().rev().collect() }
    }

    /// The shaft test says clear exactly where nothing stands between the two polygons: beside
    /// the blocker yes, across it or over it no, and a wall that both polygons touch (it meets
    /// the shaft's boundary only) does not count. At any offset and scale.
    #[test]
    fn shaft_is_clear_only_where_nothing_stands_between() {
        for (off, s) in
            [(DVec3::ZERO, 1.0), (DVec3::splat(1e6), 1.0), (DVec3::ZERO, 1e-4), (DVec3::splat(-3.0), 1e4)]
        {
            let mut sc = two_squares_and_blocker(off, s);
            let t = |p: [f64; 3]| (DVec3::from_array(p) * s + off).to_array();
            // A wall at x = 1 that the floor's and the ceiling's right edges touch.
            sc.patches
                .push(quad([t([1., 0., 0.]), t([1., 0., 2.]), t([1., 1., 2.]), t([1., 1., 0.])], "wall"));
            let sc = Scene::new("t", "t", sc.patches);
            let acc = Accel::build(&sc);
            let m = |v: Vec<DVec3>| v.into_iter().map(|p| p * s + off).collect::<Vec<_>>();
            // The strips lie in the floor (patch 0) and the ceiling (patch 1).
            let clear = |a: Vec<DVec3>, b: Vec<DVec3>| acc.shaft_clear(&sc, &m(a), &m(b), [0, 1]);
            assert!(
                clear(strip(0.6, 1.0, 0.0, true), strip(0.6, 1.0, 2.0, false)),
                "beside the blocker, {off} {s}"
            );
            assert!(
                !clear(strip(0.0, 0.4, 0.0, true), strip(0.0, 0.4, 2.0, false)),
                "across the blocker, {off} {s}"
            );
            // The hull passes over x = 0.5 at z = 1, where the blocker ends.
            assert!(
                !clear(strip(0.6, 1.0, 0.0, true), strip(0.0, 0.4, 2.0, false)),
                "over its edge, {off} {s}"
            );
            // Ignoring the blocker's two halves instead: nothing else stands there, and the
            // floor and ceiling the strips lie in count as outside (their own planes bound it).
            assert!(
                acc.shaft_clear(&sc, &m(strip(0.0, 0.4, 0.0, true)), &m(strip(0.0, 0.4, 2.0, false)), [2, 3]),
                "blocker ignored, {off} {s}"
            );
        }
    }

    /// Wherever the shaft test says clear, no segment between the two polygons is blocked
    /// (random sub-rectangles of the floor and ceiling, 64 segments each).
    #[test]
    fn a_clear_shaft_blocks_no_segment() {
        let sc = two_squares_and_blocker(DVec3::ZERO, 1.0);
        let acc = Accel::build(&sc);
        let mut rng = crate::math::Pcg32::keyed(3, 4);
        let (mut clear, mut blocked) = (0, 0);
        for _ in 0..300 {
            let span = |rng: &mut crate::math::Pcg32| {
                let (a, b) = (rng.next_f64(), rng.next_f64());
                (a.min(b), a.max(b).max(a.min(b) + 1e-3))
            };
            let (a0, a1) = span(&mut rng);
            let (b0, b1) = span(&mut rng);
            let (lo, hi) = (strip(a0, a1, 0.0, true), strip(b0, b1, 2.0, false));
            if !acc.shaft_clear(&sc, &lo, &hi, [0, 1]) {
                blocked += 1;
                continue;
            }
            clear += 1;
            for _ in 0..64 {
                let x = DVec3::new(a0 + (a1 - a0) * rng.next_f64(), rng.next_f64(), 0.0);
                let y = DVec3::new(b0 + (b1 - b0) * rng.next_f64(), rng.next_f64(), 2.0);
                assert!(!acc.occluded(x, y, [0, 1]), "[{a0}, {a1}] → [{b0}, {b1}]: {x} → {y} blocked");
            }
        }
        assert!(clear > 20 && blocked > 20, "both cases drawn: {clear} clear, {blocked} not");
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
            let (mut blocked, mut total) = (0, 0);
            for _ in 0..20_000 {
                let Some(seg) = random_segment(&sc, &acc, &mut rng) else { continue };
                let (a, b, ignore) = (seg.a, seg.b, seg.patches);
                let ray = Ray::new(seg.local_a, seg.dir, END_EPS, seg.len - END_EPS);
                let brute =
                    acc.polys.iter().any(|p| !ignore.contains(&p.patch) && intersect(p, &ray).is_finite());
                assert_eq!(acc.occluded(a, b, ignore), brute, "{name}: {a} → {b} (patches {ignore:?})");
                blocked += usize::from(brute);
                total += 1;
            }
            assert!(blocked > total / 20 && blocked < total, "{name}: {blocked} of {total} blocked");
        }
    }

    /// A segment between random points of two random patches.
    struct Segment {
        patches: [u32; 2],
        a: DVec3,
        b: DVec3,
        /// `a` in the accelerator's frame, the unit direction to `b` and the length there.
        local_a: Vec3A,
        dir: Vec3A,
        len: f32,
    }

    /// The next random segment, `None` where it is too short to test (under 2 `END_EPS`).
    fn random_segment(sc: &Scene, acc: &Accel, rng: &mut crate::math::Pcg32) -> Option<Segment> {
        let n = sc.patches.len();
        let i = (rng.next_u32() as usize) % n;
        let j = (rng.next_u32() as usize) % n;
        let point = |k: usize, rng: &mut crate::math::Pcg32| {
            let (s, t) = (rng.next_f64(), rng.next_f64());
            crate::geometry::visibility::point_on_polygon(&sc.patches[k].vertices, s, t)
        };
        let a = point(i, rng);
        let b = point(j, rng);
        let (la, lb) = (acc.to_local(a), acc.to_local(b));
        let len = (lb - la).length();
        if !(len > 2.0 * END_EPS) {
            return None;
        }
        Some(Segment { patches: [i as u32, j as u32], a, b, local_a: la, dir: (lb - la) / len, len })
    }

    /// Random unit directions, with some components forced to ±0, ±ε and a hair above ε (where
    /// `safe_inverse` switches branch).
    fn directions(rng: &mut crate::math::Pcg32, n: usize) -> Vec<Vec3A> {
        let special = [0.0, -0.0, f32::EPSILON, -f32::EPSILON, 1.5 * f32::EPSILON, -1e-30];
        (0..n)
            .map(|k| {
                let mut d = Vec3A::new(
                    rng.next_f64() as f32 - 0.5,
                    rng.next_f64() as f32 - 0.5,
                    rng.next_f64() as f32 - 0.5,
                )
                .normalize();
                if k % 3 == 0 {
                    d[k % 2] = special[(k / 3) % special.len()];
                }
                d
            })
            .collect()
    }

    /// The vectorised reciprocal is obvhs's `Ray::new` bit for bit.
    #[test]
    fn shadow_ray_is_ray_new() {
        let mut rng = crate::math::Pcg32::keyed(3, 5);
        for d in directions(&mut rng, 3000) {
            let o = Vec3A::new(0.1, -0.2, 0.3);
            let (a, b) = (shadow_ray(o, d, END_EPS, 0.5), Ray::new(o, d, END_EPS, 0.5));
            for k in 0..3 {
                assert_eq!(a.inv_direction[k].to_bits(), b.inv_direction[k].to_bits(), "{d} lane {k}");
            }
        }
    }

    /// The near/far-plane slab test gives, for every decoded node, the masks of the textbook
    /// min/max test on the CWBVH's own child boxes, rays running both ways along every axis.
    #[test]
    fn slab_masks_are_those_of_the_min_max_test() {
        let sc = Scene::load("builtin:splash_room").unwrap();
        let acc = Accel::build(&sc);
        let mut rng = crate::math::Pcg32::keyed(9, 4);
        let dirs = directions(&mut rng, 2000);
        let mut hits = 0;
        for (i, d) in dirs.into_iter().enumerate() {
            let o = Vec3A::new(
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
            );
            let ray = shadow_ray(o, d, END_EPS, 0.2 + (i % 4) as f32 * 0.3);
            let slab = SlabRay::new(&ray);
            for (w, n) in acc.wide.iter().zip(&acc.bvh.nodes) {
                let mut want = 0;
                for c in 0..8 {
                    if n.is_child_empty(c) {
                        continue;
                    }
                    let b = n.child_aabb(c);
                    let (mut t0, mut t1) = (ray.tmin, ray.tmax);
                    for a in 0..3 {
                        let x0 = (b.min[a] - ray.origin[a]) * ray.inv_direction[a];
                        let x1 = (b.max[a] - ray.origin[a]) * ray.inv_direction[a];
                        t0 = t0.max(x0.min(x1));
                        t1 = t1.min(x0.max(x1));
                    }
                    want |= u32::from(t0 <= t1) << c;
                }
                assert_eq!(slab.hits(w), want, "ray {i}: {o} + t {d}");
                hits += want.count_ones();
            }
        }
        assert!(hits > 1000, "the rays must meet boxes ({hits} child boxes met)");
    }

    /// A leaf's 4-wide test finds the first polygon, in BVH order, that the scalar test says
    /// blocks the ray.
    #[test]
    fn leaf_packs_agree_with_the_scalar_polygon_test() {
        let sc = Scene::load("builtin:splash_room").unwrap();
        let acc = Accel::build(&sc);
        let mut rng = crate::math::Pcg32::keyed(2, 8);
        let mut found = 0;
        for _ in 0..3000 {
            let Some(seg) = random_segment(&sc, &acc, &mut rng) else { continue };
            let (a, b, ignore) = (seg.a, seg.b, seg.patches);
            let ray = shadow_ray(seg.local_a, seg.dir, END_EPS, seg.len - END_EPS);
            let planes = PlaneRay::new(&ray);
            for w in &acc.wide {
                for c in 0..8 {
                    if w.leaves & (1 << c) == 0 {
                        continue;
                    }
                    let pack = &w.packs[c];
                    let first = pack.first as usize;
                    let want = (first..first + pack.lanes.count_ones() as usize)
                        .find(|&id| {
                            let p = &acc.polys[id];
                            !ignore.contains(&p.patch) && intersect(p, &ray).is_finite()
                        })
                        .map(|id| id as u32);
                    assert_eq!(acc.pack_blocker(pack, &ray, &planes, ignore), want, "{a} → {b}");
                    found += usize::from(want.is_some());
                }
            }
        }
        assert!(found > 100, "some leaves must block ({found})");
    }

    /// The built-in rooms' trees are shallow enough for the small stack.
    #[test]
    fn built_in_rooms_use_the_small_stack() {
        for name in ["builtin:splash_room", "builtin:splash_largeroom", "builtin:cornell"] {
            let acc = Accel::build(&Scene::load(name).unwrap());
            assert!(!acc.wide.is_empty() && acc.stack_needs <= SMALL_STACK, "{name}: {}", acc.stack_needs);
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
