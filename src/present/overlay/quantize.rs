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
