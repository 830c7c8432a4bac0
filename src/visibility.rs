//! Visible fraction V_ij ∈ [0, 1] between two surface regions, estimated with N stratified,
//! jittered sample pairs and the BVH's any-hit query.
//!
//! ```text
//! V_ij ≈ (1/N) Σ_k [segment x_k → y_k unblocked],   x_k on the receiver, y_k on the source
//! ```
//!
//! Deterministic: ray k's jitter is one SplitMix64 hash of (seed, the caller's key — a link's
//! element ids —, k), split into four 16-bit offsets, so the estimate does not depend on thread
//! scheduling and the rays' samples are independent of each other. The strata of each ray count
//! are computed once; points are made from each region's bilinear form mapped once into the
//! BVH's local frame, where the rays are cast. Only sample pairs that face each other
//! (x in front of the source's plane and y in front of the receiver's) are counted: the form
//! factor already clips the parts behind either plane, and counting rays through them would
//! darken a receiver that sees only part of a large source (a box face standing on a floor).
//! The receiver and source patches are ignored by the ray cast, so an element never shadows
//! itself; sample points sit strictly inside the regions (5 % to 95 % across their stratum), so
//! rays never graze a shared edge.

use crate::accel::Accel;
use crate::math::{DVec3, Pcg32, splitmix64};
use glam::Vec3A;

/// Point on a triangle or quad from (u, v) ∈ [0,1)²: bilinear on quads, the square-root map
/// (uniform in area) on triangles.
#[must_use]
pub fn point_on_polygon(verts: &[DVec3], u: f64, v: f64) -> DVec3 {
    if verts.len() == 3 {
        let su = u.sqrt();
        verts[0] * (1.0 - su) + verts[1] * (su * (1.0 - v)) + verts[2] * (su * v)
    } else {
        let a = verts[0].lerp(verts[1], u);
        let b = verts[3].lerp(verts[2], u);
        a.lerp(b, v)
    }
}

/// Offset within a stratum from 16 bits: 5 % to 95 % of the stratum, so points never reach
/// its edges (and sample points never touch a region's boundary).
#[inline]
fn jitter(bits: u64) -> f64 {
    const UNIT: f64 = 0.9 / 65536.0;
    0.05 + UNIT * f64::from(bits as u16)
}

/// The strata of `n` sample pairs: sample k's receiver and source strata (lower corners in
/// [0,1)², `corners[k] = [u_r, v_r, u_s, v_s]`) and the strata's size. Receiver strata in
/// order, source strata in a co-prime stride so pairs decorrelate.
#[derive(Clone, Debug)]
struct SamplePattern {
    corners: Vec<[f64; 4]>,
    du: f64,
    dv: f64,
}

impl SamplePattern {
    fn new(n: u32) -> SamplePattern {
        let strata = Strata::new(n);
        let (mut walk_r, mut walk_s) = (strata.walk(0), strata.walk(strata.coprime_stride(n)));
        let corners = (0..n)
            .map(|_| {
                let (ri, rj) = strata.step(&mut walk_r);
                let (si, sj) = strata.step(&mut walk_s);
                let (du, dv) = (strata.inv_cols, strata.inv_rows);
                [f64::from(ri) * du, f64::from(rj) * dv, f64::from(si) * du, f64::from(sj) * dv]
            })
            .collect();
        SamplePattern { corners, du: strata.inv_cols, dv: strata.inv_rows }
    }
}

/// Patterns for 1 to `CACHED_PATTERNS` rays, built once (they depend on nothing else).
const CACHED_PATTERNS: u32 = 64;
static PATTERNS: std::sync::OnceLock<Vec<SamplePattern>> = std::sync::OnceLock::new();

fn build_patterns() -> Vec<SamplePattern> {
    (1..=CACHED_PATTERNS).map(SamplePattern::new).collect()
}

/// A region as P(u, v) = a + f·e1 + g·e2 + h·e3 in the BVH's local frame: on a quad (f, g, h)
/// = (u, v, uv), the bilinear map of [`point_on_polygon`]; on a triangle (√u, 0, √u·v), its
/// square-root map.
struct Bilinear {
    a: DVec3,
    e1: DVec3,
    e2: DVec3,
    e3: DVec3,
    triangle: bool,
}

impl Bilinear {
    fn new(accel: &Accel, verts: &[DVec3]) -> Bilinear {
        let l = |i: usize| accel.local_f64(verts[i]);
        if verts.len() == 3 {
            let (v0, v1, v2) = (l(0), l(1), l(2));
            Bilinear { a: v0, e1: v1 - v0, e2: DVec3::ZERO, e3: v2 - v1, triangle: true }
        } else {
            let (v0, v1, v2, v3) = (l(0), l(1), l(2), l(3));
            Bilinear { a: v0, e1: v1 - v0, e2: v3 - v0, e3: (v2 - v3) - (v1 - v0), triangle: false }
        }
    }

    #[inline]
    fn point(&self, u: f64, v: f64) -> DVec3 {
        if self.triangle {
            let su = u.sqrt();
            self.a + self.e1 * su + self.e3 * (su * v)
        } else {
            self.a + self.e1 * u + self.e2 * v + self.e3 * (u * v)
        }
    }
}

/// The k-th of `n` stratified, jittered points in [0,1)², with strata on a near-square grid.
/// `perm` shifts which stratum sample k lands in, so receiver and source strata pair differently.
#[must_use]
pub fn stratified(k: u32, n: u32, perm: u32, rng: &mut Pcg32) -> (f64, f64) {
    Strata::new(n).point(k, perm, rng)
}

/// The near-square grid of `n` strata (computed once per estimate).
#[derive(Copy, Clone, Debug)]
struct Strata {
    cols: u32,
    rows: u32,
    inv_cols: f64,
    inv_rows: f64,
}

impl Strata {
    fn new(n: u32) -> Strata {
        let cols = (f64::from(n).sqrt().ceil() as u32).max(1);
        let rows = n.div_ceil(cols);
        Strata { cols, rows, inv_cols: 1.0 / f64::from(cols), inv_rows: 1.0 / f64::from(rows) }
    }

    fn point(&self, k: u32, perm: u32, rng: &mut Pcg32) -> (f64, f64) {
        let (i, j) = self.stratum(k, perm);
        let ju = 0.05 + 0.9 * rng.next_f64();
        let jv = 0.05 + 0.9 * rng.next_f64();
        self.at(i, j, ju, jv)
    }

    /// A stride for the source's strata: about 2n/3, co-prime with the number of strata so the
    /// walk visits each once (2n/3 + 1 itself is not always: 27 and 42 strata for n = 40).
    fn coprime_stride(&self, n: u32) -> u32 {
        let m = self.cols * self.rows;
        let gcd = |mut a: u32, mut b: u32| {
            while b != 0 {
                (a, b) = (b, a % b);
            }
            a
        };
        let mut s = 2 * n / 3 + 1;
        while gcd(s | 1, m) != 1 {
            s += 1;
        }
        s
    }

    /// (column, row) of sample k's stratum: k·(perm|1) + perm mod cols·rows.
    fn stratum(&self, k: u32, perm: u32) -> (u32, u32) {
        let s = (u64::from(k) * u64::from(perm | 1) + u64::from(perm)) % u64::from(self.cols * self.rows);
        let s = s as u32;
        (s % self.cols, s / self.cols)
    }

    /// Stratum (i, j) at offsets (ju, jv) ∈ [0, 1) within it.
    fn at(&self, i: u32, j: u32, ju: f64, jv: f64) -> (f64, f64) {
        ((f64::from(i) + ju) * self.inv_cols, (f64::from(j) + jv) * self.inv_rows)
    }

    /// The strata of samples k = 0, 1, … in order: the same as `point(k, perm, ·)` without a
    /// division per sample (stratum k·(perm|1) + perm mod cols·rows, advanced by adding).
    fn walk(&self, perm: u32) -> Walk {
        let m = self.cols * self.rows;
        let (s0, step) = (perm % m, (perm | 1) % m);
        Walk { i: s0 % self.cols, j: s0 / self.cols, di: step % self.cols, dj: step / self.cols }
    }

    /// The walk's current stratum (column, row), then a step.
    fn step(&self, w: &mut Walk) -> (u32, u32) {
        let p = (w.i, w.j);
        w.i += w.di;
        w.j += w.dj;
        if w.i >= self.cols {
            w.i -= self.cols;
            w.j += 1;
        }
        if w.j >= self.rows {
            w.j -= self.rows;
        }
        p
    }
}

/// Position of a [`Strata::walk`]: the current stratum (column, row) and the step.
struct Walk {
    i: u32,
    j: u32,
    di: u32,
    dj: u32,
}

/// Estimate the visible fraction between a receiver region and a source region.
///
/// `key` seeds the jitter (use something that identifies the pair, e.g. both element ids);
/// `seed` is the run's global seed. Returns the fraction of unblocked sample pairs.
#[must_use]
pub fn visible_fraction(
    accel: &Accel,
    receiver: &[DVec3],
    receiver_patch: u32,
    source: &[DVec3],
    source_patch: u32,
    rays: u32,
    seed: u64,
    key: u64,
) -> f64 {
    let n_r = crate::math::newell_normal(receiver);
    let n_s = crate::math::newell_normal(source);
    visible_fraction_oriented(
        accel,
        (receiver, receiver_patch, n_r),
        (source, source_patch, n_s),
        rays,
        seed,
        key,
    )
}

/// [`visible_fraction`] with the regions' normals given (any positive scale): `(vertices, patch,
/// normal)` of the receiver and of the source.
#[must_use]
pub fn visible_fraction_oriented(
    accel: &Accel,
    receiver: (&[DVec3], u32, DVec3),
    source: (&[DVec3], u32, DVec3),
    rays: u32,
    seed: u64,
    key: u64,
) -> f64 {
    let mut last = crate::accel::NO_HIT;
    visibility_sample(accel, receiver, source, rays, seed, key, &mut last, Stop::Never, false).0
}

/// When [`visibility_sample`] may stop before casting every ray.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Stop {
    /// Cast every ray: the estimate itself.
    Never,
    /// Stop at the first unblocked ray and return 1: only whether the fraction is positive
    /// (otherwise it is exactly 0).
    AtVisible,
    /// Stop as soon as one ray passed and one was blocked, returning the fraction so far (in
    /// (0, 1)): only whether the fraction is 0, 1 or in between (0 and 1 are exact).
    AtMixed,
}

/// [`visible_fraction_oriented`] with a shadow cache shared with the caller (see
/// [`Accel::occluded_cached`]: pass the same `last` for nearby region pairs, the children of one
/// split link; the estimate does not depend on it), returning the rays cast as well.
///
/// With a [`Stop`] other than `Never`, the same rays in the same order, stopping as soon as the
/// answer the caller needs is known (see [`Stop`]).
///
/// `weighted`: each ray counts with the point-to-point kernel cos θ_x cos θ_y / r² of its pair,
/// so the estimate is the transfer-weighted visible fraction ∫∫ K V / ∫∫ K that a link's
/// coefficient wants (a ratio estimator: consistent, biased by O(1/n)), rather than the plain
/// fraction of pairs, which is off where the kernel varies across the pair (a large lamp over a
/// penumbra: shadow-wide's element averages 15 % off with 16 plain rays). Symmetric in the two
/// regions, as the kernel is.
#[allow(clippy::too_many_arguments)]
pub fn visibility_sample(
    accel: &Accel,
    (receiver, receiver_patch, n_r): (&[DVec3], u32, DVec3),
    (source, source_patch, n_s): (&[DVec3], u32, DVec3),
    rays: u32,
    seed: u64,
    key: u64,
    last: &mut u32,
    stop: Stop,
    weighted: bool,
) -> (f64, u32) {
    if rays == 0 {
        return (1.0, 0);
    }
    let base = splitmix64(seed ^ splitmix64(key));
    let owned;
    let pattern = match PATTERNS.get_or_init(build_patterns).get(rays as usize - 1) {
        Some(p) => p,
        None => {
            owned = SamplePattern::new(rays);
            &owned
        }
    };
    // Points are made directly in the BVH's local frame, where the rays are cast, from each
    // region's bilinear form (mapped there once per estimate).
    let (rf, sf) = (Bilinear::new(accel, receiver), Bilinear::new(accel, source));
    let mut visible = 0u32;
    let mut counted = 0u32;
    // Kernel weights of the visible and of all counted pairs (`weighted`).
    let (mut w_visible, mut w_all) = (0.0f64, 0.0f64);
    let fraction = |visible: u32, counted: u32, w_visible: f64, w_all: f64| {
        if weighted && w_all > 0.0 { w_visible / w_all } else { f64::from(visible) / f64::from(counted) }
    };
    for (k, c) in pattern.corners.iter().enumerate() {
        // One hash per ray gives the four 16-bit jitters of its two points: independent of the
        // other rays (no serial generator state), so they are computed side by side.
        let h = splitmix64(base.wrapping_add((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)));
        let x = rf.point(c[0] + pattern.du * jitter(h), c[1] + pattern.dv * jitter(h >> 16));
        let y = sf.point(c[2] + pattern.du * jitter(h >> 32), c[3] + pattern.dv * jitter(h >> 48));
        // Only pairs that face each other carry energy (both cosines positive); a pair behind
        // either plane says nothing about the visibility that the form factor counts.
        let d = y - x;
        if n_r.dot(d) <= 0.0 || n_s.dot(d) >= 0.0 {
            continue;
        }
        let w = if weighted {
            let r2 = d.length_squared();
            n_r.dot(d) * -n_s.dot(d) / (r2 * r2)
        } else {
            1.0
        };
        w_all += w;
        let (x, y) =
            (Vec3A::new(x.x as f32, x.y as f32, x.z as f32), Vec3A::new(y.x as f32, y.y as f32, y.z as f32));
        counted += 1;
        if accel.occluded_local_cached(x, y, [receiver_patch, source_patch], last) {
            if stop == Stop::AtMixed && visible > 0 {
                return (fraction(visible, counted, w_visible, w_all), counted);
            }
        } else {
            visible += 1;
            w_visible += w;
            match stop {
                Stop::AtVisible => return (1.0, counted),
                Stop::AtMixed if visible < counted => {
                    return (fraction(visible, counted, w_visible, w_all), counted);
                }
                _ => {}
            }
        }
    }
    if counted == 0 {
        // No facing pair among the samples: the regions barely see each other; the form factor
        // (which clips exactly) decides, so do not also attenuate.
        return (1.0, 0);
    }
    (fraction(visible, counted, w_visible, w_all), counted)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stratified_covers_every_stratum_once() {
        for n in [1u32, 4, 9, 10, 16] {
            let mut rng = Pcg32::new(1, 1);
            let cols = (f64::from(n).sqrt().ceil() as u32).max(1);
            let rows = n.div_ceil(cols);
            let mut seen = vec![0; (cols * rows) as usize];
            for k in 0..n {
                let (u, v) = stratified(k, n, 0, &mut rng);
                assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
                seen[((v * f64::from(rows)) as u32 * cols + (u * f64::from(cols)) as u32) as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c <= 1), "n={n}: {seen:?}");
        }
    }

    #[test]
    fn strata_walk_matches_the_closed_form() {
        for n in [1u32, 2, 3, 4, 7, 10, 16, 40, 64, 4096] {
            let strata = Strata::new(n);
            for perm in [0, 1, 2 * n / 3 + 1, 5, 97] {
                let mut w = strata.walk(perm);
                for k in 0..n {
                    assert_eq!(strata.step(&mut w), strata.stratum(k, perm), "n {n} perm {perm} k {k}");
                }
            }
        }
    }

    #[test]
    fn sample_patterns_cover_every_stratum_once_and_stay_inside() {
        for n in [1u32, 2, 3, 4, 7, 10, 16, 40, 64, 65, 100] {
            let p = SamplePattern::new(n);
            assert_eq!(p.corners.len(), n as usize);
            for side in [0, 2] {
                let mut seen: Vec<(u64, u64)> = p
                    .corners
                    .iter()
                    .map(|c| ((c[side] / p.du).round() as u64, (c[side + 1] / p.dv).round() as u64))
                    .collect();
                seen.sort_unstable();
                seen.dedup();
                assert_eq!(seen.len(), n as usize, "n {n}: a stratum used twice");
            }
            for c in &p.corners {
                for (x, d) in [(c[0], p.du), (c[1], p.dv), (c[2], p.du), (c[3], p.dv)] {
                    for bits in [0u64, 0xFFFF, 0x8000] {
                        let u = x + d * jitter(bits);
                        assert!(u > x && u < x + d && u < 1.0, "n {n}: {u} outside [{x}, {})", x + d);
                    }
                }
            }
        }
    }

    #[test]
    fn triangle_map_stays_inside() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        for i in 0..10 {
            for j in 0..10 {
                let p = point_on_polygon(&t, f64::from(i) / 10.0, f64::from(j) / 10.0);
                assert!(p.x >= -1e-15 && p.y >= -1e-15 && p.x + p.y <= 1.0 + 1e-15);
            }
        }
    }
}
