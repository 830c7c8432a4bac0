//! Decals: a patch lying on another one, in the same plane, facing the same way and overlapping
//! it (a poster on a wall, a rug on a floor). Both would receive the same light: a ray that
//! reaches the wall behind the poster ends in the poster's plane, so nothing blocks it, and the
//! light that lands on the poster is counted a second time on the wall under it. The solver then
//! creates light (the SPLASH-2 room's poster, patch 6 on wall 1: its lamps' rows of F·V sum
//! above 1; docs/solver.md#decals-and-what-is-not-normalised), and a path tracer picks one of
//! the two surfaces by chance.
//!
//! What an author means is that the decal covers what lies under it: no light reaches the
//! covered part and none leaves it. [`cut_under_decals`] cuts each covered patch around its
//! decals (the convex pieces of the patch outside each decal, split along the decal's edge
//! lines as Campbell & Fussell's BSP splits a receiver, 1990) and drops the covered part, so
//! every ray meets one surface and no unseen area is left to solve or to score. The loader
//! reports what it cut.
//!
//! Candidates share a plane bucket (normal to 1e-6, plane offset to [`PLANE_REL`] × diagonal;
//! pairs split across a bucket boundary are missed) and a grid cell in the plane; a pair is a
//! decal pair when the convex intersection of the two polygons covers more than
//! [`OVERLAP_REL`] of the smaller one (edge-sharing neighbours of a tessellated floor do not).
//! Work is about linear in the patch count.

use super::{Patch, Scene};
use crate::math::DVec3;
use std::collections::HashMap;

/// Plane offsets closer than this (relative to the diagonal) count as the same plane.
pub const PLANE_REL: f64 = 1e-7;
/// Two coplanar patches overlap when their intersection covers more than this fraction of the
/// smaller one; cut pieces smaller than this fraction of their patch are dropped.
pub const OVERLAP_REL: f64 = 1e-6;
/// Work bounds (hostile files): a plane with more candidate pairs than this is not searched,
/// and a patch under more decals than [`MAX_DECALS_PER_PATCH`] is not cut; the warning says so.
pub const MAX_PAIRS_PER_PLANE: usize = 4_000_000;
pub const MAX_DECALS_PER_PATCH: usize = 64;

/// One decal pair: the decal and the patch it lies on. Of two overlapping patches the decal is
/// the one whose mesh has less area in their plane (a rug over a tiled floor), then the smaller
/// patch (a poster on a wall of the same mesh), then the later one.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Decal {
    pub decal: usize,
    pub on: usize,
}

/// What [`cut_under_decals`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CutReport {
    /// Decal pairs found.
    pub decals: usize,
    /// Patches cut around their decals.
    pub cut: usize,
    /// Patches that replaced them.
    pub pieces: usize,
    /// Area dropped (covered).
    pub covered_area: f64,
    /// Planes not searched and patches not cut, for the work bounds.
    pub skipped: usize,
}

/// Cut every patch that a decal covers around it (see the module docs); the first piece of a
/// cut patch takes its place and the others go to the end, so no other patch changes index
/// (unless one is covered wholly: it is removed). Adds one warning when anything was cut.
pub fn cut_under_decals(scene: &mut Scene) -> CutReport {
    let diag = scene.bounds().diagonal();
    if !(diag > 0.0) || scene.patches.len() < 2 {
        return CutReport::default();
    }
    let (decals, skipped_planes) = find_decals(&scene.patches, diag);
    let mut report = CutReport { decals: decals.len(), skipped: skipped_planes, ..CutReport::default() };
    if decals.is_empty() {
        warn_skipped(scene, &report);
        return report;
    }
    let mut by_base: Vec<(usize, Vec<usize>)> = Vec::new();
    for d in &decals {
        match by_base.last_mut() {
            Some((b, tops)) if *b == d.on => tops.push(d.decal),
            _ => by_base.push((d.on, vec![d.decal])),
        }
    }
    let mut first_cut: Option<(String, String)> = None;
    let mut appended = Vec::new();
    for (base, tops) in by_base {
        if tops.len() > MAX_DECALS_PER_PATCH {
            report.skipped += 1;
            continue;
        }
        let p = &scene.patches[base];
        let frame = Frame::of(p);
        let mut pieces = vec![frame.project(&p.vertices)];
        for &t in &tops {
            let top = frame.project(&scene.patches[t].vertices);
            pieces =
                pieces.into_iter().flat_map(|piece| subtract(piece, &top, OVERLAP_REL * p.area)).collect();
        }
        let mut patches: Vec<Patch> = Vec::new();
        for (k, piece) in pieces.iter().enumerate() {
            for (j, poly) in split_to_quads(&clean(piece, 1e-12 * diag)).into_iter().enumerate() {
                let verts = poly.iter().map(|&q| frame.lift(q)).collect();
                let name = format!("{}#cut{k}.{j}", p.name);
                if let Ok(np) = p.piece(verts, name) {
                    patches.push(np);
                }
            }
        }
        let kept: f64 = patches.iter().map(|q| q.area).sum();
        report.cut += 1;
        report.pieces += patches.len();
        report.covered_area += (p.area - kept).max(0.0);
        if first_cut.is_none() {
            first_cut = Some((p.name.clone(), scene.patches[tops[0]].name.clone()));
        }
        let mut it = patches.into_iter();
        match it.next() {
            Some(first) => scene.patches[base] = first,
            // Wholly covered: removed below.
            None => scene.patches[base].area = 0.0,
        }
        appended.extend(it);
    }
    scene.patches.retain(|p| p.area > 0.0);
    scene.patches.extend(appended);
    if let Some((a, b)) = first_cut {
        scene.warnings.push(format!(
            "{} patch(es) cut around {} coplanar decal(s) lying on them (first: {a} under {b}) into {} \
             piece(s); the covered area ({:.4e}) is dropped: no light reaches it and none leaves it",
            report.cut, report.decals, report.pieces, report.covered_area
        ));
    }
    warn_skipped(scene, &report);
    report
}

fn warn_skipped(scene: &mut Scene, report: &CutReport) {
    if report.skipped > 0 {
        scene.warnings.push(format!(
            "{} plane(s) or patch(es) with too many coplanar overlaps (more than {MAX_PAIRS_PER_PLANE} \
             candidate pairs, or {MAX_DECALS_PER_PATCH} decals on one patch) left uncut: their overlapping \
             parts receive the same light twice",
            report.skipped
        ));
    }
}

/// The decal pairs of `patches` (scene diagonal `diag`), sorted by (covered patch, decal), and
/// the number of planes not searched (over [`MAX_PAIRS_PER_PLANE`]).
#[must_use]
pub fn find_decals(patches: &[Patch], diag: f64) -> (Vec<Decal>, usize) {
    let plane_tol = PLANE_REL * diag;
    let mut buckets: HashMap<(i64, i64, i64, i64), Vec<usize>> = HashMap::new();
    for (i, p) in patches.iter().enumerate() {
        let n = p.normal;
        let q = |x: f64| (x * 1e6).round() as i64;
        let key = (q(n.x), q(n.y), q(n.z), (p.plane_d() / plane_tol).round() as i64);
        buckets.entry(key).or_default().push(i);
    }
    let mut out = Vec::new();
    let mut skipped = 0;
    for g in buckets.into_values().filter(|g| g.len() > 1) {
        if !decals_in_plane(patches, &g, diag, &mut out) {
            skipped += 1;
        }
    }
    out.sort_unstable_by_key(|d| (d.on, d.decal));
    (out, skipped)
}

/// The decal pairs among the patches `ids` of one plane; false (nothing added) when the plane
/// has more than [`MAX_PAIRS_PER_PLANE`] candidate pairs.
fn decals_in_plane(patches: &[Patch], ids: &[usize], diag: f64, out: &mut Vec<Decal>) -> bool {
    let frame = Frame::of(&patches[ids[0]]);
    let poly: Vec<Vec<[f64; 2]>> = ids.iter().map(|&i| frame.project(&patches[i].vertices)).collect();
    let boxes: Vec<[f64; 4]> = poly.iter().map(|v| bbox(v)).collect();
    // A grid of about one cell per patch's mean box size.
    let mean = boxes.iter().map(|b| (b[2] - b[0]).max(b[3] - b[1])).sum::<f64>() / boxes.len() as f64;
    let cell = mean.max(1e-12 * diag);
    let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    let mut big: Vec<u32> = Vec::new();
    let range = |lo: f64, hi: f64| (lo / cell).floor() as i64..=(hi / cell).floor() as i64;
    for (k, b) in boxes.iter().enumerate() {
        let (xs, ys) = (range(b[0], b[2]), range(b[1], b[3]));
        // A patch far larger than the mean (a wall among tiles) would fill many cells.
        if (xs.end() - xs.start() + 1) * (ys.end() - ys.start() + 1) > 4096 {
            big.push(k as u32);
            continue;
        }
        for x in xs {
            for y in ys.clone() {
                grid.entry((x, y)).or_default().push(k as u32);
            }
        }
    }
    let cell_pairs: usize = grid.values().map(|m| m.len() * m.len().saturating_sub(1) / 2).sum();
    if cell_pairs.saturating_add(big.len().saturating_mul(boxes.len())) > MAX_PAIRS_PER_PLANE {
        return false;
    }
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for members in grid.values() {
        for (a, &i) in members.iter().enumerate() {
            pairs.extend(members[a + 1..].iter().map(|&j| (i.min(j), i.max(j))));
        }
    }
    // A big patch is a candidate with every other one (pairs of two big ones dedup below).
    for &i in &big {
        pairs.extend((0..boxes.len() as u32).filter(|&j| j != i).map(|j| (i.min(j), i.max(j))));
    }
    pairs.sort_unstable();
    pairs.dedup();
    // Which of two overlapping patches is on top: the one whose mesh has less area in this
    // plane (a rug over a tiled floor, a poster on a wall), then the smaller, then the later.
    let mut mesh_area: HashMap<&str, f64> = HashMap::new();
    for (k, &i) in ids.iter().enumerate() {
        *mesh_area.entry(patches[i].mesh.as_str()).or_default() += signed_area(&poly[k]);
    }
    let rank = |k: usize| {
        (mesh_area[patches[ids[k]].mesh.as_str()], signed_area(&poly[k]), std::cmp::Reverse(ids[k]))
    };
    for (i, j) in pairs {
        let (i, j) = (i as usize, j as usize);
        let (bi, bj) = (boxes[i], boxes[j]);
        if bi[0] >= bj[2] || bj[0] >= bi[2] || bi[1] >= bj[3] || bj[1] >= bi[3] {
            continue;
        }
        let (ai, aj) = (signed_area(&poly[i]), signed_area(&poly[j]));
        let common = signed_area(&clip(&poly[i], &poly[j]));
        if common > OVERLAP_REL * ai.min(aj) {
            let (ri, rj) = (rank(i), rank(j));
            let i_on_top = ri.0 < rj.0 || (ri.0 == rj.0 && (ri.1 < rj.1 || (ri.1 == rj.1 && ri.2 < rj.2)));
            let (top, bottom) = if i_on_top { (i, j) } else { (j, i) };
            out.push(Decal { decal: ids[top], on: ids[bottom] });
        }
    }
    true
}

/// A patch's plane: 2D coordinates (u, v) along t1, t2 and the offset along the normal.
struct Frame {
    t1: DVec3,
    t2: DVec3,
    n: DVec3,
    d: f64,
}

impl Frame {
    fn of(p: &Patch) -> Frame {
        let n = p.normal;
        let t1 = n.any_orthonormal_vector();
        Frame { t1, t2: n.cross(t1), n, d: p.plane_d() }
    }
    /// The polygon in the plane's coordinates, counter-clockwise.
    fn project(&self, verts: &[DVec3]) -> Vec<[f64; 2]> {
        let mut v: Vec<[f64; 2]> = verts.iter().map(|p| [p.dot(self.t1), p.dot(self.t2)]).collect();
        if signed_area(&v) < 0.0 {
            v.reverse();
        }
        v
    }
    fn lift(&self, q: [f64; 2]) -> DVec3 {
        self.t1 * q[0] + self.t2 * q[1] + self.n * self.d
    }
}

fn bbox(v: &[[f64; 2]]) -> [f64; 4] {
    let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for p in v {
        b[0] = b[0].min(p[0]);
        b[1] = b[1].min(p[1]);
        b[2] = b[2].max(p[0]);
        b[3] = b[3].max(p[1]);
    }
    b
}

fn signed_area(v: &[[f64; 2]]) -> f64 {
    let n = v.len();
    (0..n).map(|i| v[i][0] * v[(i + 1) % n][1] - v[(i + 1) % n][0] * v[i][1]).sum::<f64>() * 0.5
}

/// `poly` split by the line through a → b: (the part on its left, the part on its right).
fn split(poly: &[[f64; 2]], a: [f64; 2], b: [f64; 2]) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    let (mut left, mut right) = (Vec::new(), Vec::new());
    let Some(&last) = poly.last() else { return (left, right) };
    let mut s = last;
    for &e in poly {
        let (ss, se) = (side(s), side(e));
        if (ss < 0.0) != (se < 0.0) {
            let t = ss / (ss - se);
            let x = [s[0] + t * (e[0] - s[0]), s[1] + t * (e[1] - s[1])];
            left.push(x);
            right.push(x);
        }
        if se >= 0.0 {
            left.push(e);
        } else {
            right.push(e);
        }
        s = e;
    }
    (left, right)
}

/// `subject` clipped by the convex, counter-clockwise `clipper` (their intersection).
fn clip(subject: &[[f64; 2]], clipper: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out = subject.to_vec();
    for k in 0..clipper.len() {
        out = split(&out, clipper[k], clipper[(k + 1) % clipper.len()]).0;
        if out.is_empty() {
            break;
        }
    }
    out
}

/// The convex pieces of `poly` outside the convex `hole` (pieces of area below `tiny` dropped);
/// `poly` itself, unsplit, when the two do not overlap by more than `tiny`.
fn subtract(poly: Vec<[f64; 2]>, hole: &[[f64; 2]], tiny: f64) -> Vec<Vec<[f64; 2]>> {
    if signed_area(&clip(&poly, hole)) <= tiny {
        return vec![poly];
    }
    let mut out = Vec::new();
    let mut rest = poly;
    for k in 0..hole.len() {
        let (inside, outside) = split(&rest, hole[k], hole[(k + 1) % hole.len()]);
        if signed_area(&outside) > tiny {
            out.push(outside);
        }
        rest = inside;
        if rest.is_empty() {
            break;
        }
    }
    out
}

/// `poly` without repeated or collinear vertices (`eps` a length).
fn clean(poly: &[[f64; 2]], eps: f64) -> Vec<[f64; 2]> {
    let mut v: Vec<[f64; 2]> = Vec::with_capacity(poly.len());
    for &p in poly {
        if v.last().is_none_or(|q| (q[0] - p[0]).hypot(q[1] - p[1]) > eps) {
            v.push(p);
        }
    }
    while v.len() > 1 && (v[0][0] - v[v.len() - 1][0]).hypot(v[0][1] - v[v.len() - 1][1]) <= eps {
        v.pop();
    }
    let mut changed = true;
    while changed && v.len() > 3 {
        changed = false;
        for i in 0..v.len() {
            let (a, b, c) = (v[(i + v.len() - 1) % v.len()], v[i], v[(i + 1) % v.len()]);
            let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
            let scale = (b[0] - a[0]).hypot(b[1] - a[1]) * (c[0] - b[0]).hypot(c[1] - b[1]);
            if cross.abs() <= 1e-12 * scale {
                v.remove(i);
                changed = true;
                break;
            }
        }
    }
    v
}

/// A convex polygon as quads and at most one triangle sharing its first vertex.
fn split_to_quads(poly: &[[f64; 2]]) -> Vec<Vec<[f64; 2]>> {
    if poly.len() < 3 {
        return Vec::new();
    }
    if poly.len() <= 4 {
        return vec![poly.to_vec()];
    }
    let mut out = Vec::new();
    let mut i = 1;
    while i + 1 < poly.len() {
        if i + 2 < poly.len() {
            out.push(vec![poly[0], poly[i], poly[i + 1], poly[i + 2]]);
            i += 2;
        } else {
            out.push(vec![poly[0], poly[i], poly[i + 1]]);
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;

    fn quad(x0: f64, y0: f64, x1: f64, y1: f64, z: f64) -> Patch {
        quad_of("m", x0, y0, x1, y1, z)
    }

    fn quad_of(mesh: &str, x0: f64, y0: f64, x1: f64, y1: f64, z: f64) -> Patch {
        let v =
            vec![DVec3::new(x0, y0, z), DVec3::new(x1, y0, z), DVec3::new(x1, y1, z), DVec3::new(x0, y1, z)];
        Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, mesh, 0, "p", "m").unwrap()
    }

    #[test]
    fn a_rug_on_a_tiled_floor_is_found_and_the_tiles_are_not() {
        let mut tiles = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                tiles.push(quad_of(
                    "floor",
                    f64::from(i),
                    f64::from(j),
                    f64::from(i + 1),
                    f64::from(j + 1),
                    0.0,
                ));
            }
        }
        assert!(find_decals(&tiles, 20.0).0.is_empty(), "tiles sharing edges are no decals");
        // A rug larger than a tile: its mesh has less area in the plane, so it is on top.
        tiles.push(quad_of("rug", 2.5, 2.5, 4.5, 4.5, 0.0));
        let (found, skipped) = find_decals(&tiles, 20.0);
        assert_eq!(skipped, 0);
        // The rug covers parts of 9 tiles (columns and rows 2, 3, 4).
        assert_eq!(found.len(), 9, "{found:?}");
        assert!(found.iter().all(|d| d.decal == 100));
        let mut scene = Scene::new("t", "t", tiles);
        let r = cut_under_decals(&mut scene);
        assert_eq!(r.cut, 9);
        assert!((r.covered_area - 4.0).abs() < 1e-12, "{r:?}");
        assert!((scene.total_area() - 100.0).abs() < 1e-9, "the rug replaces the floor under it");
    }

    #[test]
    fn facing_away_or_apart_is_no_decal() {
        let floor = quad(0.0, 0.0, 4.0, 4.0, 0.0);
        let mut v = quad(1.0, 1.0, 2.0, 2.0, 0.0).vertices;
        v.reverse();
        let flipped = Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "m", 0, "p", "m").unwrap();
        let above = quad(1.0, 1.0, 2.0, 2.0, 0.01);
        let beside = quad(4.0, 0.0, 5.0, 1.0, 0.0);
        assert!(find_decals(&[floor, flipped, above, beside], 10.0).0.is_empty());
    }

    #[test]
    fn a_wall_is_cut_around_its_poster_and_keeps_the_rest() {
        let wall = quad(0.0, 0.0, 4.0, 3.0, 0.0);
        let poster = quad(1.0, 1.0, 2.0, 2.5, 0.0);
        let other = quad(0.0, 0.0, 1.0, 1.0, 2.0);
        let mut scene = Scene::new("t", "t", vec![wall, poster, other]);
        let r = cut_under_decals(&mut scene);
        assert_eq!((r.decals, r.cut), (1, 1));
        assert!((r.covered_area - 1.5).abs() < 1e-12, "{r:?}");
        // The poster and the other patch keep their index; the wall's pieces tile the wall
        // minus the poster, none of them overlapping the poster.
        assert_eq!(scene.patches[1].area, 1.5);
        assert_eq!(scene.patches[2].centroid.z, 2.0);
        let pieces: Vec<&Patch> =
            std::iter::once(&scene.patches[0]).chain(scene.patches[3..].iter()).collect();
        assert_eq!(pieces.len(), r.pieces);
        let area: f64 = pieces.iter().map(|p| p.area).sum();
        assert!((area - 10.5).abs() < 1e-12, "{area}");
        assert!(pieces.iter().all(|p| p.normal.z > 0.999 && p.vertices.iter().all(|v| v.z.abs() < 1e-12)));
        assert!(find_decals(&scene.patches, 10.0).0.is_empty(), "nothing left under the poster");
        assert!(scene.warnings.iter().any(|w| w.contains("1 patch(es) cut around 1 coplanar decal(s)")));
        assert!(scene.validate().is_empty(), "{:?}", scene.validate());
    }

    #[test]
    fn a_decal_over_the_edge_and_a_duplicate() {
        // A rug hanging over the floor's edge: only the overlap is cut away.
        let mut s = Scene::new("t", "t", vec![quad(0.0, 0.0, 2.0, 2.0, 0.0), quad(1.5, 0.5, 2.5, 1.0, 0.0)]);
        let r = cut_under_decals(&mut s);
        assert!((r.covered_area - 0.25).abs() < 1e-12, "{r:?}");
        // A duplicate covers its twin wholly: the twin goes.
        let mut d = Scene::new("t", "t", vec![quad(0.0, 0.0, 1.0, 1.0, 0.0), quad(0.0, 0.0, 1.0, 1.0, 0.0)]);
        let r = cut_under_decals(&mut d);
        assert_eq!((r.decals, r.cut, r.pieces), (1, 1, 0));
        assert_eq!(d.patches.len(), 1);
    }

    #[test]
    fn a_pile_of_overlapping_copies_is_bounded() {
        // 70 copies of one quad: every copy lies on the earlier ones, so the first is under 69
        // decals (over the per-patch bound): left uncut, with a warning, and no blow-up.
        let quads: Vec<Patch> = (0..70).map(|_| quad(0.0, 0.0, 1.0, 1.0, 0.0)).collect();
        let mut scene = Scene::new("t", "t", quads);
        let r = cut_under_decals(&mut scene);
        assert!(r.skipped >= 1, "{r:?}");
        assert!(scene.warnings.iter().any(|w| w.contains("left uncut")), "{:?}", scene.warnings);
    }

    #[test]
    fn a_patch_far_larger_than_the_others_is_still_paired() {
        // 10 000 tiles of side 0.01 on a floor of side 10: the floor spans far more grid cells
        // than the cap, so it is paired with every tile directly; each tile lies on it.
        let mut p = vec![quad_of("floor", 0.0, 0.0, 10.0, 10.0, 0.0)];
        for i in 0..100 {
            for j in 0..100 {
                let (x, y) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
                p.push(quad_of("tiles", x, y, x + 0.01, y + 0.01, 0.0));
            }
        }
        let (found, skipped) = find_decals(&p, 15.0);
        assert_eq!(skipped, 0);
        assert_eq!(found.len(), 10_000);
        assert!(found.iter().all(|d| d.on == 0 && d.decal > 0));
    }
}
