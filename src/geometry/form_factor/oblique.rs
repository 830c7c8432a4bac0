//! The oblique edge pairs of the double contour integral ([`super::contour`]): segments at an
//! angle other than 0 or 90°, the inner integral of ln r in closed form, the outer by
//! Gauss–Legendre rules graded towards where the integrand is singular, on a ladder of rules
//! whose successive values give each pair's error estimate.

use super::gauss::gauss_legendre;
use crate::math::DVec3;
use std::sync::OnceLock;

/// An oblique edge pair of the double contour integral ([`super::contour`]) on its rung of the
/// ladder: its ∫∫ ln r ds dt by that rule (`value`, the caller multiplies by `cos`) and the
/// estimate of its error (times |cos|).
pub(super) struct Rung {
    pub(super) pair: ObliquePair,
    pub(super) cos: f64,
    pub(super) rung: usize,
    pub(super) value: f64,
    pub(super) error: f64,
}

/// The error of an edge pair's value by rung `k` of the ladder, from its value by rung `k − 1`:
/// twice their difference. The difference bounds the coarser rule's error, and the finer rule's
/// is smaller; the factor 2 guards against two rules that agree by chance, which a single edge
/// pair can, where a sum over all of a polygon's edges on the same rule rarely does. (Measured on
/// splash_room's contour couplings against 96-node rules, `splash2` and `quality`: the n⁻⁸
/// model's |difference| / ((n_k / n_{k−1})⁸ − 1), the estimate while every edge pair climbed
/// together, let 21 of 552 and 44 of 14 690 couplings exceed their tolerance, up to 14 times,
/// once the edge pairs stop on different rungs; the plain difference 1 of each; twice it none.)
pub(super) fn rung_error(below: f64, value: f64) -> f64 {
    2.0 * (value - below).abs()
}

/// The Gauss–Legendre rules of [`OBLIQUE_LADDER`], computed once.
pub(super) fn oblique_ladder() -> &'static [Vec<(f64, f64)>] {
    static RULES: OnceLock<Vec<Vec<(f64, f64)>>> = OnceLock::new();
    RULES.get_or_init(|| OBLIQUE_LADDER.iter().map(|&n| gauss_legendre(n)).collect())
}

/// The node counts of the Gauss–Legendre rules [`super::polygon_to_polygon_contour`] climbs, edge pair
/// by edge pair: a rule gives the value, its difference from the rule below the error estimate.
pub(super) const OBLIQUE_LADDER: [usize; 7] = [4, 6, 8, 12, 16, 24, 32];

/// [`super::polygon_to_polygon_contour`] starts each edge pair on the first rule whose n⁻⁸ is below
/// this times the tolerance: on the test's touching pairs the error is ~5 n⁻⁸ of the oblique
/// terms' sum, which is 0.4–12 times the result.
pub(super) const OBLIQUE_APRIORI: f64 = 0.1;

/// An edge pair at an oblique angle: segments x = a + s·u, s ∈ [0, la] and y = c + t·v,
/// t ∈ [0, lc], u and v unit and not parallel, with the cuts of the outer interval.
///
/// The inner integral is closed: with p = x(s), τ = (p − c)·v and h the distance from p to y's
/// line, ∫₀^lc ln |p − y(t)| dt = G(lc − τ) − G(−τ), G(w) = ½ w ln(w² + h²) − w + h atan(w / h).
/// It is analytic in s except near the points of x closest to y's ends and to y's line, where
/// r can vanish (a shared vertex, a T-junction, lines that cross): the outer interval is cut
/// there and each piece integrated by a Gauss–Legendre rule in u with
/// s = s₀ + (s₁ − s₀)(3u² − 2u³), which grades the nodes towards both ends and turns an s ln s
/// singularity there into u³ ln u, where an n-point rule errs by O(n⁻⁸).
pub(super) struct ObliquePair {
    a: DVec3,
    u: DVec3,
    c: DVec3,
    v: DVec3,
    lc: f64,
    /// The outer interval's ends and cuts, sorted (unused cuts at 0).
    cuts: [f64; 5],
    /// Pieces shorter than this are skipped.
    tiny: f64,
}

impl ObliquePair {
    pub(super) fn new(a: DVec3, u: DVec3, la: f64, c: DVec3, v: DVec3, lc: f64) -> ObliquePair {
        // Where x passes closest to y's ends and to y's line.
        let (w0, b) = (a - c, u.dot(v));
        let cross = (b * w0.dot(v) - w0.dot(u)) / u.cross(v).length_squared();
        let mut cuts = [0.0, (c - a).dot(u), (c + v * lc - a).dot(u), cross, la];
        let tiny = 1e-9 * la;
        for x in &mut cuts[1..4] {
            if !(x.is_finite() && *x > tiny && *x < la - tiny) {
                *x = 0.0;
            }
        }
        cuts.sort_unstable_by(f64::total_cmp);
        ObliquePair { a, u, c, v, lc, cuts, tiny }
    }

    /// ∫∫ ln r ds dt over the pair (the caller multiplies by u·v) by the graded `rule`.
    pub(super) fn integrate(&self, rule: &[(f64, f64)]) -> f64 {
        let g = |w: f64, h: f64, h2: f64| {
            let r2 = w * w + h2;
            let log = if r2 > 0.0 { 0.5 * w * r2.ln() } else { 0.0 };
            let at = if h > 0.0 { h * (w / h).atan() } else { 0.0 };
            log - w + at
        };
        let inner = |s: f64| {
            let d = self.a + self.u * s - self.c;
            // (The distance to the line by the cross product: |d|² − τ² cancels where it is
            // small.)
            let h = d.cross(self.v).length();
            let tau = d.dot(self.v);
            g(self.lc - tau, h, h * h) - g(-tau, h, h * h)
        };
        let mut sum = 0.0;
        for w in self.cuts.windows(2) {
            let (s0, s1) = (w[0], w[1]);
            let len = s1 - s0;
            if !(len > self.tiny) {
                continue;
            }
            for &(t, wt) in rule {
                let s = s0 + len * t * t * (3.0 - 2.0 * t);
                sum += wt * len * 6.0 * t * (1.0 - t) * inner(s);
            }
        }
        sum
    }
}
