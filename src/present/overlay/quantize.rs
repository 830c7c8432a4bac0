//! Points merged by quantised position: a key per point (its input patch, or every patch, and
//! its coordinates in units of `MERGE_REL` × the scene's diagonal), so that leaves sharing a
//! corner find each other whatever the rounding of their vertices.

use super::ElementView;
use crate::math::DVec3;

/// Positions are merged when they agree to this fraction of the scene's diagonal: elements are
/// split at exact midpoints in f64, so shared corners agree to rounding (~1e-16 relative).
pub const MERGE_REL: f64 = 1e-9;

/// A quantised position: (input patch, or [`ANY_PATCH`], then x, y, z in quanta).
pub(super) type Key = (u32, i64, i64, i64);

/// The `patch` of a [`Key`] that merges points of every patch.
pub(super) const ANY_PATCH: u32 = u32::MAX;

/// A map keyed by [`Key`]s (or tuples of them), hashed by [`KeyHasher`].
pub(super) type KeyMap<K, V> = std::collections::HashMap<K, V, std::hash::BuildHasherDefault<KeyHasher>>;

/// The hash of the display build's maps: the multiply-and-rotate word hash of rustc's
/// `FxHasher` (its 2.x constant and final rotation). The keys are quantised positions made by
/// the program, not chosen by an adversary, so the standard map's SipHash buys nothing here; it
/// was about 40 % of the display thread's time (perf, splash_room). No output depends on a
/// map's order.
#[derive(Clone, Copy, Default)]
pub(super) struct KeyHasher(u64);

impl KeyHasher {
    fn add(&mut self, word: u64) {
        self.0 = self.0.wrapping_add(word).wrapping_mul(0xf135_7aea_2e62_a9c5);
    }
}

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0.rotate_left(26)
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

/// The quantum and origin of the keys: `MERGE_REL` × the elements' bounding-box diagonal, from its
/// lower corner.
pub(super) struct Quantizer {
    origin: DVec3,
    inv: f64,
    /// The scene's bounding-box diagonal (1 for an empty or degenerate scene).
    pub(super) diag: f64,
}

impl Quantizer {
    pub(super) fn new(elements: &[ElementView]) -> Quantizer {
        let mut min = DVec3::splat(f64::INFINITY);
        let mut max = DVec3::splat(f64::NEG_INFINITY);
        for e in elements {
            for v in e.verts() {
                min = min.min(*v);
                max = max.max(*v);
            }
        }
        let diag = (max - min).length();
        let diag = if diag > 0.0 && diag.is_finite() { diag } else { 1.0 };
        Quantizer {
            origin: if min.is_finite() { min } else { DVec3::ZERO },
            inv: 1.0 / (diag * MERGE_REL),
            diag,
        }
    }
    pub(super) fn key(&self, patch: u32, p: DVec3) -> Key {
        let q = (p - self.origin) * self.inv;
        (patch, q.x.round() as i64, q.y.round() as i64, q.z.round() as i64)
    }
}
