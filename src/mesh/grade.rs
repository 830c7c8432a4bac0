//! A graded discontinuity mesh: the pieces of a discontinuity mesh (and the patches it left
//! whole) split further, small where the direct light varies — inside the penumbrae, between the
//! D1/D2 lines that bound them — and large elsewhere, within one element budget for the whole
//! scene.
//!
//! A constant element K of area A_K that approximates B by its mean has the squared L2 error
//! A_K · Var_K(B). The mesher estimates it from the **direct** light each piece reflects, which
//! it can evaluate before any solve (the penumbra module's fixed shadow-ray grid,
//! [`crate::geometry::lit::lit_fraction`]):
//!
//! ```text
//! D(x)   = ρ̄ Σ_e Ē_e F_e(x) v_e(x)                 direct radiosity at x (v_e: visible fraction)
//! err_K  = A_K · ( w_K Var_K(D) + G² A_K / 12 )       Var_K(D) over a few points of K
//! G      = smooth · D̄_scene / diagonal                an assumed smooth (indirect) gradient
//! ```
//!
//! w_K is `penumbra_weight` on a piece with a sample in a penumbra (0 < lit < 1 by the band's
//! margins), else 1: the L2 error of a few shadow strips is a small part of the scene's, but the
//! shadows are what the lecture's artifacts (A, D, E) are about, so they are weighted up.
//! The second term stands for what the direct light does not show (indirect light, on the
//! ceiling and in the umbrae: a linear function of gradient G varies by G² A / 12 over a square
//! of area A), so every reflecting patch gets elements by its area too. Greedy refinement then
//! splits the piece of largest `err_K` in two until the budget is spent [the greedy allocation
//! of an L2 error; cf. Lischinski, Tampieri & Greenberg 1992, sec. 5, who refine a discontinuity
//! mesh by the variation of the illumination]:
//!
//! ```text
//!      in a penumbra: cut along the isolines              elsewhere: bisect the longest edge
//!      (perpendicular to D's fitted gradient)             (elements stay round)
//!   ┌──────────────┐ D1        ┌────┬────┐                 ┌──────┬──────┐
//!   │ ░░░░░░░░░░░░ │           │    │    │                 │      │      │
//!   ├──────────────┤ (cut)  →  penumbra strips get thin,   │      │      │
//!   │ ▒▒▒▒▒▒▒▒▒▒▒▒ │           long slabs along the shadow └──────┴──────┘
//!   └──────────────┘ D1
//! ```
//!
//! Before grading, [`shadow_segments`] keeps only the critical segments with a penumbra beside
//! them (and every D0), so the discontinuity mesh does not spend the budget on lines inside an
//! umbra or in full light ([`super::remesh`] calls it when grading).
//!
//! **The automatic budget** ([`Budget::Auto`], [`auto_budget`]; the default when the graded mesh
//! is the hierarchical solver's top level): the patches the kept segments' mesh already has, plus
//! one piece per square of side d/17 of reflecting area (d the scene's diagonal). The first part
//! draws the shadows' edges; the second is what the top level needs for the smooth light, since
//! the hierarchy's oracle, started from a wall left as two or three pieces, stops early on it.
//! The constant is where table-room and cornell reach their lowest error (docs/meshing.md, "A
//! graded discontinuity mesh").
//!
//! Pieces stay convex (a convex polygon cut by a line); pieces of more than 4 vertices count as
//! the triangles of their fan, which is how [`super::remesh`] turns them into patches. The cuts
//! are straight lines through the piece's centroid, so the result is not conforming (a cut ends
//! on a neighbour's edge: a T-vertex): fine for constant elements, not for a continuous p = 1
//! basis. Deterministic: the queue orders by (error, creation index).

use crate::geometry::accel::Accel;
use crate::geometry::lit::{FULLY_LIT_ABOVE, MIN_DIRECT_SHARE, UMBRA_BELOW, lit_fraction};
use crate::math::{DVec3, polygon_area, polygon_normal};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

/// How many patches [`grade`] leaves the scene with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Budget {
    /// Exactly this many (emitters and pieces fanned into triangles included).
    Patches(usize),
    /// Chosen from the scene by [`auto_budget`]: the pieces of the shadow segments, plus about
    /// one piece per (diagonal / 17)² of reflecting area.
    Auto,
}

/// Pieces the automatic budget adds per d² of reflecting area (d the scene's diagonal): one per
/// square of side d / 17 (module docs, "The automatic budget").
pub const AUTO_PIECES_PER_DIAGONAL_SQUARED: f64 = 289.0;

/// The automatic budget ([`Budget::Auto`]): the `before` patches the shadow segments' mesh
/// already has, plus [`AUTO_PIECES_PER_DIAGONAL_SQUARED`] · A_r / d² for the smooth light, A_r
/// the reflecting area and d the scene's diagonal, capped at `cap`. The segments' pieces resolve
/// the shadows' edges; the rest gives every reflecting surface pieces about d / 17 across before
/// any hierarchical refinement (docs/meshing.md).
#[must_use]
pub fn auto_budget(scene: &Scene, before: usize, cap: usize) -> usize {
    let reflecting: f64 = scene.patches.iter().filter(|p| p.reflectance.mean() > 0.0).map(|p| p.area).sum();
    let d = scene.bounds().diagonal().max(f64::MIN_POSITIVE);
    let smooth = (AUTO_PIECES_PER_DIAGONAL_SQUARED * reflecting / (d * d)).ceil();
    // A degenerate scene's ratio is huge or not finite: the cap bounds it.
    let smooth = if smooth.is_finite() && smooth < cap as f64 { smooth as usize } else { cap };
    before.saturating_add(smooth).min(cap)
}

/// Settings of [`grade`].
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct GradeParams {
    /// Patches of the whole graded scene, or [`Budget::Auto`].
    pub budget: Budget,
    /// Side of the shadow-ray grid on each emitter at each sample point (side² rays).
    pub side: u32,
    /// The assumed smooth gradient, in units of the scene's mean direct radiosity per scene
    /// diagonal (module docs); 0: split only where the direct light varies.
    pub smooth: f64,
    /// Weight of Var(D) on a piece with a sample in a penumbra (lit fraction strictly between
    /// 2 % and 98 %, [`crate::geometry::lit::UMBRA_BELOW`], [`crate::geometry::lit::FULLY_LIT_ABOVE`]): the shadows get more
    /// of the budget than their share of the L2 error (1: plain L2 allocation).
    pub penumbra_weight: f64,
}

impl GradeParams {
    /// `budget` patches, an 8 × 8 shadow grid, smooth = 4, penumbra weight 100 (tuned on
    /// table-room: docs/meshing.md).
    #[must_use]
    pub const fn with_budget(budget: usize) -> GradeParams {
        GradeParams { budget: Budget::Patches(budget), side: 8, smooth: 4.0, penumbra_weight: 100.0 }
    }

    /// [`GradeParams::with_budget`] with the budget chosen from the scene ([`auto_budget`]).
    #[must_use]
    pub const fn auto() -> GradeParams {
        GradeParams { budget: Budget::Auto, ..GradeParams::with_budget(1) }
    }

    /// Reject budgets of 0, a zero grid, a negative or non-finite smooth term.
    pub fn validate(&self) -> Result<(), super::MeshError> {
        let finite_nonneg = |x: f64| x.is_finite() && x >= 0.0;
        if self.budget == Budget::Patches(0)
            || self.side == 0
            || !finite_nonneg(self.smooth)
            || !(finite_nonneg(self.penumbra_weight) && self.penumbra_weight > 0.0)
        {
            return Err(super::MeshError::Parameter(format!(
                "grading needs budget ≥ 1, side ≥ 1, smooth ≥ 0 and penumbra weight > 0 (got {}, {}, {}, {})",
                match self.budget {
                    Budget::Patches(n) => n.to_string(),
                    Budget::Auto => "auto".into(),
                },
                self.side,
                self.smooth,
                self.penumbra_weight
            )));
        }
        Ok(())
    }
}

/// What [`grade`] did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct GradeStats {
    /// The budget graded to (the automatic one's value when `auto`).
    pub budget: usize,
    /// The budget was chosen by [`auto_budget`].
    pub auto: bool,
    /// Patches before and after (fanned pieces counted as their triangles).
    pub patches_before: usize,
    pub patches_after: usize,
    pub splits: usize,
    /// Points where the direct light was evaluated (each `side²` shadow rays per emitter).
    pub direct_samples: usize,
    /// The smooth gradient G used (B per scene unit).
    pub smooth_gradient: f64,
    pub grade_s: f64,
}

/// One convex piece of an input patch.
#[derive(Clone, Debug, PartialEq)]
pub struct Piece {
    /// The input patch it lies on.
    pub patch: usize,
    /// Convex polygon, the patch's orientation.
    pub vertices: Vec<DVec3>,
}

/// Patches a piece becomes: itself up to 4 vertices, else the triangles of its fan.
#[must_use]
pub fn patch_cost(vertices: usize) -> usize {
    if vertices <= 4 { 1 } else { vertices - 2 }
}

/// The critical segments of `receiver` that bound a shadow the direct light shows: every D0
/// (contact: a jump in value, lit or not), and each D1/D2 with a penumbra beside it — lit
/// strictly between the band's margins, or lit differing across it, at one of 5 points along
/// it, read a small step (10⁻³ of the receiver's size) to either side. With several emitters,
/// "lit" is the segment's own emitter's visible fraction, and that emitter must bring at least
/// the band's `min_direct` (10 %) of the unoccluded direct light there: the summed lit fraction
/// of many lamps is partial almost everywhere (splash_room: 548 137 pieces, now 46 014). The segments of
/// [`super::discontinuity`] are a superset (a wedge hidden by another occluder is not clipped):
/// inside an umbra or in full light they bound nothing, and only cost elements.
#[must_use]
pub fn shadow_segments(
    scene: &Scene,
    accel: &Accel,
    receiver: usize,
    set: &super::discontinuity::CriticalSet,
    side: u32,
) -> Vec<[DVec3; 2]> {
    use super::discontinuity::Discontinuity;
    let p = &scene.patches[receiver];
    let size = p.area.sqrt();
    let lit = |x: DVec3| lit_fraction(scene, accel, receiver, x, side).map_or(0.0, |(l, _)| l);
    let emitters = scene.patches.iter().filter(|q| q.emission.mean() > 0.0).count();
    set.segments
        .iter()
        .filter(|s| {
            if s.order == Discontinuity::D0 {
                return true;
            }
            let across = p.normal.cross(s.b - s.a).normalize_or_zero() * (1e-3 * size);
            if let (Some(e), true) = (s.emitter, emitters > 1) {
                // Several lamps: the summed lit fraction is partial almost everywhere; ask
                // whether this segment's own emitter is partly hidden beside it, and whether
                // its light is at least the band's share of the direct light there.
                return [0.1, 0.3, 0.5, 0.7, 0.9].iter().any(|t| {
                    let x = s.a.lerp(s.b, *t);
                    let (l0, s0) = emitter_lit(scene, accel, receiver, e, x - across, side);
                    let (l1, s1) = emitter_lit(scene, accel, receiver, e, x + across, side);
                    let partial = |l: f64| l > UMBRA_BELOW && l < FULLY_LIT_ABOVE;
                    s0.max(s1) >= MIN_DIRECT_SHARE
                        && (partial(l0) || partial(l1) || (l0 - l1).abs() > UMBRA_BELOW)
                });
            }
            [0.1, 0.3, 0.5, 0.7, 0.9].iter().any(|t| {
                let x = s.a.lerp(s.b, *t);
                let (l0, l1) = (lit(x - across), lit(x + across));
                let partial = |l: f64| l > UMBRA_BELOW && l < FULLY_LIT_ABOVE;
                partial(l0) || partial(l1) || (l0 - l1).abs() > UMBRA_BELOW
            })
        })
        .map(|s| [s.a, s.b])
        .collect()
}

/// Emitter `e` seen from `x` on `receiver`: the fraction of a `side` × `side` grid of its points
/// that no patch hides, and its share of the unoccluded direct light E·F summed over every
/// emitter (0 when none faces x).
fn emitter_lit(scene: &Scene, accel: &Accel, receiver: usize, e: usize, x: DVec3, side: u32) -> (f64, f64) {
    let p = &scene.patches[receiver];
    let direct = |q: &crate::scene::Patch| {
        let power = q.emission.mean();
        if power > 0.0 {
            power * crate::geometry::form_factor::point_to_polygon(x, p.normal, &q.vertices).max(0.0)
        } else {
            0.0
        }
    };
    let total: f64 =
        scene.patches.iter().enumerate().filter(|(i, _)| *i != receiver).map(|(_, q)| direct(q)).sum();
    let emitter = &scene.patches[e];
    let own = direct(emitter);
    if !(total > 0.0 && own > 0.0) {
        return (0.0, 0.0);
    }
    let n = f64::from(side);
    let mut last = crate::geometry::accel::NO_HIT;
    let grid = (0..side * side).map(|k| ((f64::from(k % side) + 0.5) / n, (f64::from(k / side) + 0.5) / n));
    let seen = grid
        .filter(|&(u, v)| {
            let y = crate::geometry::visibility::point_on_polygon(&emitter.vertices, u, v);
            !accel.occluded_cached(x, y, [receiver as u32, e as u32], &mut last)
        })
        .count();
    (seen as f64 / (n * n), own / total)
}

/// A piece with its estimate.
struct Scored {
    piece: Piece,
    area: f64,
    /// Mean and variance of D over the sample points; D's fitted gradient (in the plane).
    mean: f64,
    variance: f64,
    gradient: DVec3,
    /// A sample lies in a penumbra.
    penumbra: bool,
}

fn centre(v: &[DVec3]) -> DVec3 {
    v.iter().copied().sum::<DVec3>() / v.len() as f64
}

/// The sample points of a convex polygon: its vertex average, and each vertex and edge midpoint
/// pulled 20 % toward it (off the edges, which lie on shadow lines).
fn sample_points(v: &[DVec3]) -> Vec<DVec3> {
    let c = centre(v);
    let n = v.len();
    let mut out = vec![c];
    for k in 0..n {
        out.push(c.lerp(v[k], 0.8));
        out.push(c.lerp((v[k] + v[(k + 1) % n]) * 0.5, 0.8));
    }
    out
}

fn score(scene: &Scene, accel: &Accel, piece: Piece, side: u32) -> Scored {
    let area = polygon_area(&piece.vertices);
    let p = &scene.patches[piece.patch];
    let points = sample_points(&piece.vertices);
    if p.reflectance.mean() <= 0.0 {
        return Scored { piece, area, mean: 0.0, variance: 0.0, gradient: DVec3::ZERO, penumbra: false };
    }
    let mut penumbra = false;
    let values: Vec<f64> = points
        .iter()
        .map(|x| {
            lit_fraction(scene, accel, piece.patch, *x, side).map_or(0.0, |(lit, direct)| {
                penumbra |= lit > UMBRA_BELOW && lit < FULLY_LIT_ABOVE;
                lit * direct
            })
        })
        .collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n;
    // Least-squares plane D ≈ a + g_s s + g_t t in a frame of the patch plane.
    let c = points[0];
    let e1 = (piece.vertices[1] - piece.vertices[0]).normalize_or_zero();
    let e2 = p.normal.cross(e1);
    let (mut m, mut r) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for (x, d) in points.iter().zip(&values) {
        let q = [1.0, (*x - c).dot(e1), (*x - c).dot(e2)];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += q[i] * q[j];
            }
            r[i] += q[i] * d;
        }
    }
    let gradient = solve3(m, r).map_or(DVec3::ZERO, |g| e1 * g[1] + e2 * g[2]);
    Scored { piece, area, mean, variance, gradient, penumbra }
}

/// Cramer's rule; `None` when the system is (nearly) singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if !(d.abs() > 1e-12 * scale.abs()) || !d.is_finite() {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut a = m;
        for i in 0..3 {
            a[i][k] = r[i];
        }
        *o = det(a) / d;
    }
    Some(out)
}

/// Split a convex polygon by the plane through `c` with normal `n`: the parts on the negative
/// and the positive side, each `None` if it is empty or degenerate.
#[must_use]
pub fn cut(v: &[DVec3], c: DVec3, n: DVec3) -> (Option<Vec<DVec3>>, Option<Vec<DVec3>>) {
    let diameter = v.iter().flat_map(|a| v.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max);
    let tol = 1e-12 * diameter;
    let (mut neg, mut pos) = (Vec::new(), Vec::new());
    let k = v.len();
    for i in 0..k {
        let (a, b) = (v[i], v[(i + 1) % k]);
        let (da, db) = ((a - c).dot(n), (b - c).dot(n));
        if da <= 0.0 {
            neg.push(a);
        }
        if da >= 0.0 {
            pos.push(a);
        }
        if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
            let x = a + (b - a) * (da / (da - db));
            neg.push(x);
            pos.push(x);
        }
    }
    let clean = |mut p: Vec<DVec3>| {
        p.dedup_by(|a, b| a.distance(*b) <= tol);
        while p.len() > 1 && p[0].distance(p[p.len() - 1]) <= tol {
            p.pop();
        }
        (p.len() >= 3 && polygon_area(&p) > 1e-9 * diameter * diameter).then_some(p)
    };
    (clean(neg), clean(pos))
}

/// The cut of a piece away from the shadows, keeping elements round: a triangle bisected from
/// its longest edge's midpoint to the opposite vertex; a quad through the midpoints of its
/// longest edge and the opposite one; a larger polygon across its longest edge's midpoint.
fn round_cut(v: &[DVec3]) -> (Option<Vec<DVec3>>, Option<Vec<DVec3>>) {
    let n = v.len();
    let k = (0..n)
        .max_by(|&a, &b| v[a].distance(v[(a + 1) % n]).total_cmp(&v[b].distance(v[(b + 1) % n])))
        .unwrap_or(0);
    let (a, b) = (v[k], v[(k + 1) % n]);
    let m = (a + b) * 0.5;
    let normal = polygon_normal(v);
    let other = match n {
        3 => v[(k + 2) % 3],
        4 => (v[(k + 2) % 4] + v[(k + 3) % 4]) * 0.5,
        _ => m + normal.cross(b - a),
    };
    cut(v, m, (other - m).cross(normal).normalize_or_zero())
}

/// The queue's key: the error (non-negative, so its bits sort as the number; NaN as 0), then
/// the earlier piece first.
fn key(error: f64, index: usize) -> (u64, Reverse<usize>) {
    let e = if error.is_finite() && error > 0.0 { error } else { 0.0 };
    (e.to_bits(), Reverse(index))
}

/// Grade `pieces` (module docs): split the piece of largest estimated error until the scene
/// has `params.budget` patches ([`Budget::Auto`]: [`auto_budget`] of the pieces' count, at most
/// `cap`). `accel` is the input scene's. Returns the pieces in input-patch order (pieces of one
/// patch in creation order).
pub fn grade(
    scene: &Scene,
    accel: &Accel,
    pieces: Vec<Piece>,
    params: &GradeParams,
    cap: usize,
) -> (Vec<Piece>, GradeStats) {
    let t0 = Instant::now();
    let mut scored: Vec<Option<Scored>> =
        pieces.into_par_iter().map(|p| Some(score(scene, accel, p, params.side))).collect();
    let mut samples: usize = scored.iter().flatten().map(|s| 1 + 2 * s.piece.vertices.len()).sum();
    // The scene's mean direct radiosity over the reflecting area, and the smooth gradient.
    let (mut sum, mut area) = (0.0, 0.0);
    for s in scored.iter().flatten() {
        if scene.patches[s.piece.patch].reflectance.mean() > 0.0 {
            sum += s.mean * s.area;
            area += s.area;
        }
    }
    let diagonal = scene.bounds().diagonal().max(f64::MIN_POSITIVE);
    let gradient = if area > 0.0 { params.smooth * sum / area / diagonal } else { 0.0 };
    let smooth_var = |s: &Scored| {
        if scene.patches[s.piece.patch].reflectance.mean() > 0.0 {
            gradient * gradient * s.area / 12.0
        } else {
            0.0
        }
    };
    let weight = |s: &Scored| if s.penumbra { params.penumbra_weight } else { 1.0 };
    let error = |s: &Scored| s.area * (weight(s) * s.variance + smooth_var(s));
    let mut count: usize = scored.iter().flatten().map(|s| patch_cost(s.piece.vertices.len())).sum();
    let before = count;
    let budget = match params.budget {
        Budget::Patches(n) => n,
        Budget::Auto => auto_budget(scene, before, cap),
    };
    let min_area = 1e-9 * scene.patches.iter().map(|p| p.area).sum::<f64>();
    let mut heap: BinaryHeap<(u64, Reverse<usize>)> =
        scored.iter().enumerate().map(|(i, s)| key(s.as_ref().map_or(0.0, error), i)).collect();
    let mut splits = 0;
    while count < budget {
        let Some((err, Reverse(i))) = heap.pop() else { break };
        if err == 0 {
            break;
        }
        let Some(s) = scored[i].take() else { continue };
        let v = &s.piece.vertices;
        let (a, b) = if s.penumbra && s.gradient.length_squared() > 0.0 {
            cut(v, centre(v), s.gradient.normalize())
        } else {
            round_cut(v)
        };
        let (Some(a), Some(b)) = (a, b) else {
            scored[i] = Some(s); // cannot be cut: keep it, never again
            continue;
        };
        let grown = count - patch_cost(v.len()) + patch_cost(a.len()) + patch_cost(b.len());
        if grown > budget || s.area < min_area {
            scored[i] = Some(s);
            continue;
        }
        count = grown;
        splits += 1;
        let patch = s.piece.patch;
        let children: Vec<Scored> = [a, b]
            .into_par_iter()
            .map(|vertices| score(scene, accel, Piece { patch, vertices }, params.side))
            .collect();
        for c in children {
            samples += 1 + 2 * c.piece.vertices.len();
            heap.push(key(error(&c), scored.len()));
            scored.push(Some(c));
        }
    }
    let mut out: Vec<(usize, Piece)> =
        scored.into_iter().enumerate().filter_map(|(i, s)| s.map(|s| (i, s.piece))).collect();
    out.sort_by_key(|(i, p)| (p.patch, *i));
    let stats = GradeStats {
        budget,
        auto: params.budget == Budget::Auto,
        patches_before: before,
        patches_after: count,
        splits,
        direct_samples: samples,
        smooth_gradient: gradient,
        grade_s: t0.elapsed().as_secs_f64(),
    };
    (out.into_iter().map(|(_, p)| p).collect(), stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// table-room: on the floor the D1/D2 segments inside the table's umbra are dropped and
    /// every D0 (the legs' footprints) kept; on the table top's underside, which no direct light
    /// reaches, only the D0 remain. shadow-narrow: every segment bounds the penumbra, all kept.
    #[test]
    fn shadow_segments_keep_what_bounds_a_penumbra() {
        use crate::mesh::DEFAULT_SNAP;
        use crate::mesh::discontinuity::{Discontinuity, scene_segments};
        let scene = Scene::load("builtin:table-room").unwrap();
        let accel = Accel::build(&scene);
        let index = |name: &str| scene.patches.iter().position(|p| p.name == name).unwrap();
        for (name, lit) in [("floor/0/0", true), ("table_top/0/4", false)] {
            let patch = index(name);
            let set = scene_segments(&scene.patches, patch, DEFAULT_SNAP).unwrap();
            let d0 = set.segments.iter().filter(|s| s.order == Discontinuity::D0).count();
            let kept = shadow_segments(&scene, &accel, patch, &set, 8);
            assert!(d0 > 0, "{name}: the legs touch it");
            if lit {
                assert!(
                    kept.len() > d0 && kept.len() < set.segments.len(),
                    "{name}: {} of {}",
                    kept.len(),
                    set.segments.len()
                );
            } else {
                assert_eq!(kept.len(), d0, "{name}: only the contacts");
            }
        }
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let accel = Accel::build(&scene);
        let receiver = (0..scene.patches.len())
            .max_by(|&a, &b| scene.patches[a].area.total_cmp(&scene.patches[b].area))
            .unwrap();
        let set = scene_segments(&scene.patches, receiver, DEFAULT_SNAP).unwrap();
        assert!(!set.segments.is_empty());
        assert_eq!(shadow_segments(&scene, &accel, receiver, &set, 8).len(), set.segments.len());
    }

    /// The automatic budget: the segments' pieces plus 289 · A_r / d², never below what the
    /// segments' mesh already has (unless capped), never above the cap, the same every call;
    /// graded to it, table-room gets exactly that many patches and its walls ~30 pieces each.
    #[test]
    fn auto_budget_is_the_segments_pieces_plus_the_reflecting_area() {
        let scene = Scene::load("builtin:table-room").unwrap();
        let reflecting: f64 =
            scene.patches.iter().filter(|p| p.reflectance.mean() > 0.0).map(|p| p.area).sum();
        let d = scene.bounds().diagonal();
        let smooth = (289.0 * reflecting / (d * d)).ceil() as usize;
        assert!((500..700).contains(&smooth), "table-room: A_r/d² ≈ 2, so ≈ 580 ({smooth})");
        assert_eq!(auto_budget(&scene, 592, 10_000), 592 + smooth);
        assert_eq!(auto_budget(&scene, 592, 10_000), auto_budget(&scene, 592, 10_000));
        assert_eq!(auto_budget(&scene, 592, 800), 800, "capped");
        assert_eq!(auto_budget(&scene, 20_000, 10_000), 10_000, "capped below the pieces");
        let params = crate::mesh::remesh::RemeshParams {
            cdt: crate::mesh::cdt::CdtParams { min_angle_deg: 0.0, ..crate::mesh::cdt::CdtParams::quality() },
            grade: Some(GradeParams::auto()),
            ..crate::mesh::remesh::RemeshParams::cdt()
        };
        let meshed = crate::mesh::remesh::discontinuity_scene(&scene, &params).unwrap();
        let g = meshed.stats.graded.clone().unwrap();
        assert!(g.auto);
        assert_eq!(g.budget, g.patches_before + smooth, "{g:?}");
        assert_eq!(g.patches_after, g.budget);
        assert_eq!(meshed.scene.patches.len(), g.budget);
        let wall = scene.patches.iter().position(|p| p.name.starts_with("walls")).unwrap();
        let on_wall = meshed.origin.iter().filter(|&&o| o == wall).count();
        assert!(on_wall >= 16, "a wall cut into {on_wall} pieces");
        let again = crate::mesh::remesh::discontinuity_scene(&scene, &params).unwrap();
        assert_eq!(again.scene.patches.len(), meshed.scene.patches.len());
        assert!(meshed.scene.patches.iter().zip(&again.scene.patches).all(|(a, b)| a.vertices == b.vertices));
    }

    /// With several lamps (splash_room) a D1/D2 segment is kept by its own emitter's penumbra
    /// and share of the light: on the room's most segmented receiver fewer than a third of the
    /// segments survive (the summed lit fraction is partial nearly everywhere and kept
    /// them nearly all), and at least one D1/D2 besides the contacts. Its share: one emitter
    /// alone gives 1.
    #[test]
    fn with_several_lamps_a_segment_answers_to_its_own_emitter() {
        use crate::mesh::DEFAULT_SNAP;
        use crate::mesh::discontinuity::{Discontinuity, scene_segments};
        let scene = Scene::load("builtin:splash_room").unwrap();
        let accel = Accel::build(&scene);
        let sets: Vec<_> = (0..scene.patches.len())
            .map(|i| (i, scene_segments(&scene.patches, i, DEFAULT_SNAP).unwrap()))
            .collect();
        let (receiver, set) = sets.into_iter().max_by_key(|(_, s)| s.segments.len()).unwrap();
        let d0 = set.segments.iter().filter(|s| s.order == Discontinuity::D0).count();
        let kept = shadow_segments(&scene, &accel, receiver, &set, 8);
        assert!(
            kept.len() > d0 && 3 * kept.len() < set.segments.len(),
            "{} kept of {} ({d0} D0)",
            kept.len(),
            set.segments.len()
        );
        let narrow = Scene::load("builtin:shadow-narrow").unwrap();
        let accel = Accel::build(&narrow);
        let lamp = narrow.patches.iter().position(|p| p.emission.mean() > 0.0).unwrap();
        let floor = (0..narrow.patches.len())
            .max_by(|&a, &b| narrow.patches[a].area.total_cmp(&narrow.patches[b].area))
            .unwrap();
        let (lit, share) =
            emitter_lit(&narrow, &accel, floor, lamp, centre(&narrow.patches[floor].vertices), 8);
        assert!((share - 1.0).abs() < 1e-12 && (0.0..=1.0).contains(&lit), "{lit} {share}");
    }

    #[test]
    fn cut_halves_a_square_and_keeps_the_area() {
        let v = |x, z| DVec3::new(x, 0.0, z);
        let sq = [v(0.0, 0.0), v(0.0, 1.0), v(1.0, 1.0), v(1.0, 0.0)];
        let (a, b) = cut(&sq, v(0.5, 0.5), DVec3::new(1.0, 0.0, 1.0).normalize());
        let (a, b) = (a.unwrap(), b.unwrap());
        assert_eq!((a.len(), b.len()), (3, 3), "{a:?} {b:?}");
        assert!((polygon_area(&a) + polygon_area(&b) - 1.0).abs() < 1e-12);
        // A line missing the polygon leaves one part.
        let (a, b) = cut(&sq, v(2.0, 0.5), DVec3::X);
        assert!(a.is_some() && b.is_none());
    }

    /// The budget is met exactly on shadow-narrow, the penumbra gets smaller elements than the
    /// rest, and the pieces cover every patch.
    #[test]
    fn grading_spends_the_budget_in_the_penumbra() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let accel = Accel::build(&scene);
        let pieces: Vec<Piece> = scene
            .patches
            .iter()
            .enumerate()
            .map(|(patch, p)| Piece { patch, vertices: p.vertices.clone() })
            .collect();
        let params = GradeParams { smooth: 0.5, ..GradeParams::with_budget(200) };
        let (out, stats) = grade(&scene, &accel, pieces, &params, usize::MAX);
        assert_eq!(stats.patches_after, 200);
        assert_eq!(out.iter().map(|p| patch_cost(p.vertices.len())).sum::<usize>(), 200);
        for (i, p) in scene.patches.iter().enumerate() {
            let a: f64 = out.iter().filter(|q| q.patch == i).map(|q| polygon_area(&q.vertices)).sum();
            assert!((a - p.area).abs() < 1e-9 * p.area, "patch {i}: {a} vs {}", p.area);
        }
        // Elements inside the penumbra (lit strictly between 5 % and 95 % at the centre) are
        // smaller on average than the fully lit ones.
        let mut by_class = [(0.0, 0usize); 2];
        for q in &out {
            if let Some((lit, _)) = lit_fraction(&scene, &accel, q.patch, centre(&q.vertices), 16) {
                let k = usize::from(lit > 0.05 && lit < 0.95);
                by_class[k].0 += polygon_area(&q.vertices);
                by_class[k].1 += 1;
            }
        }
        let mean = |(a, n): (f64, usize)| a / n.max(1) as f64;
        assert!(by_class[1].1 > 20, "{by_class:?}");
        assert!(mean(by_class[1]) * 10.0 < mean(by_class[0]), "{by_class:?}");
    }
}
