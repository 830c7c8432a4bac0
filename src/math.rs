//! Small math shared by every module: RGB triples, polygon area / normal / centroid, a seeded RNG.
//!
//! Geometry is `f64` everywhere in the core (`glam::DVec3`): form factors of near-touching
//! elements and scenes translated by 1e6 lose too much in `f32`. The GPU gets `f32` copies.

use serde::{Deserialize, Serialize};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Sub};

pub use glam::DVec3;

/// An RGB triple: reflectance (dimensionless), or exitance / radiosity (W/m², any consistent unit).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Rgb(pub [f64; 3]);

impl Rgb {
    pub const ZERO: Rgb = Rgb([0.0; 3]);
    pub const ONE: Rgb = Rgb([1.0; 3]);

    #[must_use]
    pub const fn new(r: f64, g: f64, b: f64) -> Self {
        Rgb([r, g, b])
    }
    #[must_use]
    pub const fn splat(v: f64) -> Self {
        Rgb([v, v, v])
    }
    #[must_use]
    pub fn r(self) -> f64 {
        self.0[0]
    }
    #[must_use]
    pub fn g(self) -> f64 {
        self.0[1]
    }
    #[must_use]
    pub fn b(self) -> f64 {
        self.0[2]
    }
    /// Mean of the three channels (used for scalar oracles and error metrics).
    #[must_use]
    pub fn mean(self) -> f64 {
        (self.0[0] + self.0[1] + self.0[2]) / 3.0
    }
    #[must_use]
    pub fn max_channel(self) -> f64 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }
    #[must_use]
    pub fn min_channel(self) -> f64 {
        self.0[0].min(self.0[1]).min(self.0[2])
    }
    /// Luminance-like weight (Rec. 709), for display and the BF oracle.
    #[must_use]
    pub fn luminance(self) -> f64 {
        0.2126 * self.0[0] + 0.7152 * self.0[1] + 0.0722 * self.0[2]
    }
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }
    #[must_use]
    pub fn is_zero(self) -> bool {
        self.0.iter().all(|&c| c == 0.0)
    }
    /// Component-wise product (reflectance × irradiance).
    #[must_use]
    pub fn mul_rgb(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] * o.0[0], self.0[1] * o.0[1], self.0[2] * o.0[2]])
    }
    #[must_use]
    pub fn abs_diff_max(self, o: Rgb) -> f64 {
        (0..3).map(|i| (self.0[i] - o.0[i]).abs()).fold(0.0, f64::max)
    }
    #[must_use]
    pub fn map(self, f: impl Fn(f64) -> f64) -> Rgb {
        Rgb([f(self.0[0]), f(self.0[1]), f(self.0[2])])
    }
}

impl Add for Rgb {
    type Output = Rgb;
    fn add(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}
impl AddAssign for Rgb {
    fn add_assign(&mut self, o: Rgb) {
        *self = *self + o;
    }
}
impl Sub for Rgb {
    type Output = Rgb;
    fn sub(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}
impl Mul<f64> for Rgb {
    type Output = Rgb;
    fn mul(self, s: f64) -> Rgb {
        Rgb([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
}
impl MulAssign<f64> for Rgb {
    fn mul_assign(&mut self, s: f64) {
        *self = *self * s;
    }
}
impl Div<f64> for Rgb {
    type Output = Rgb;
    fn div(self, s: f64) -> Rgb {
        Rgb([self.0[0] / s, self.0[1] / s, self.0[2] / s])
    }
}
impl std::iter::Sum for Rgb {
    fn sum<I: Iterator<Item = Rgb>>(iter: I) -> Rgb {
        iter.fold(Rgb::ZERO, |a, b| a + b)
    }
}

/// Newell's method: the area-weighted normal of a planar (or nearly planar) polygon.
/// Its length is twice the area. Robust for any vertex count and for slivers.
#[must_use]
pub fn newell_normal(verts: &[DVec3]) -> DVec3 {
    // Subtract the first vertex so a polygon far from the origin keeps its precision.
    let o = verts[0];
    let mut n = DVec3::ZERO;
    for i in 0..verts.len() {
        let a = verts[i] - o;
        let b = verts[(i + 1) % verts.len()] - o;
        n += a.cross(b);
    }
    n
}

/// Area of a planar polygon.
#[must_use]
pub fn polygon_area(verts: &[DVec3]) -> f64 {
    0.5 * newell_normal(verts).length()
}

/// Unit normal (right-hand rule on the vertex order); zero for a degenerate polygon.
#[must_use]
pub fn polygon_normal(verts: &[DVec3]) -> DVec3 {
    newell_normal(verts).normalize_or_zero()
}

/// Area centroid of a planar polygon (fan triangulation from vertex 0).
#[must_use]
pub fn polygon_centroid(verts: &[DVec3]) -> DVec3 {
    let o = verts[0];
    let n = newell_normal(verts);
    let mut acc = DVec3::ZERO;
    let mut w = 0.0;
    for i in 1..verts.len() - 1 {
        let a = verts[i] - o;
        let b = verts[i + 1] - o;
        let tri = a.cross(b).dot(n); // signed, proportional to area
        acc += (a + b) / 3.0 * tri;
        w += tri;
    }
    if w.abs() > 0.0 { o + acc / w } else { verts.iter().copied().sum::<DVec3>() / verts.len() as f64 }
}

/// Any unit vector perpendicular to `n` (Duff et al. 2017, "Building an orthonormal basis, revisited").
#[must_use]
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), DVec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// A small, seedable, portable RNG (PCG32, O'Neill 2014). Same stream on every platform and
/// thread count: every consumer derives its own stream from `(seed, key)` with [`Pcg32::keyed`].
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    #[must_use]
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = Pcg32 { state: 0, inc: (stream << 1) | 1 };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }
    /// A stream for one unit of work (a link, an element, a pixel), independent of scheduling.
    #[must_use]
    pub fn keyed(seed: u64, key: u64) -> Self {
        Self::new(splitmix64(seed ^ splitmix64(key)), key)
    }
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        let hi = u64::from(self.next_u32()) << 21;
        let lo = u64::from(self.next_u32()) >> 11;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }
}

/// SplitMix64 finaliser: a good 64-bit hash for seeding.
#[must_use]
pub fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The hash of maps whose keys the program makes (element ids, quantised positions): each
/// 64-bit word of the key mixed in with [`splitmix64`]. SipHash's protection against chosen keys
/// buys nothing there, and it cost a third of the refinement's pair memo and about 40 % of the
/// display build. No output may depend on such a map's order.
#[derive(Clone, Copy, Default)]
pub struct WordHasher(u64);

impl WordHasher {
    fn add(&mut self, word: u64) {
        self.0 = splitmix64(self.0 ^ word);
    }
}

impl std::hash::Hasher for WordHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.add(u64::from_le_bytes(word));
        }
    }
    fn write_u32(&mut self, n: u32) {
        self.add(u64::from(n));
    }
    fn write_u64(&mut self, n: u64) {
        self.add(n);
    }
    fn write_i64(&mut self, n: i64) {
        self.add(n as u64);
    }
    fn write_usize(&mut self, n: usize) {
        self.add(n as u64);
    }
}

/// A map hashed by [`WordHasher`].
pub type WordMap<K, V> = std::collections::HashMap<K, V, std::hash::BuildHasherDefault<WordHasher>>;

/// A set hashed by [`WordHasher`].
pub type WordSet<K> = std::collections::HashSet<K, std::hash::BuildHasherDefault<WordHasher>>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_area_normal_centroid() {
        let v = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        assert!((polygon_area(&v) - 1.0).abs() < 1e-15);
        assert!((polygon_normal(&v) - DVec3::Z).length() < 1e-15);
        assert!((polygon_centroid(&v) - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
    }

    #[test]
    fn far_from_origin_keeps_precision() {
        let o = DVec3::splat(1e6);
        let v = [o, o + DVec3::new(1e-3, 0.0, 0.0), o + DVec3::new(0.0, 1e-3, 0.0)];
        // Coordinates near 1e6 carry ~1e-10 absolute rounding; relative area error stays ~1e-7.
        assert!((polygon_area(&v) / 0.5e-6 - 1.0).abs() < 1e-6);
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [DVec3::Z, -DVec3::Z, DVec3::new(1.0, 2.0, -3.0).normalize()] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12 && t.dot(b).abs() < 1e-12);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn rng_is_reproducible_and_uniform() {
        let mut a = Pcg32::keyed(0, 42);
        let mut b = Pcg32::keyed(0, 42);
        let xs: Vec<f64> = (0..10_000).map(|_| a.next_f64()).collect();
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        assert!(xs.iter().zip((0..).map(|_| b.next_f64())).all(|(x, y)| *x == y));
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        assert!((mean - 0.5).abs() < 0.01);
    }
}
