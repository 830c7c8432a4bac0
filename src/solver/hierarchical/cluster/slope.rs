//! A patch's slope of what it gathers through its own cluster links: the least-squares
//! gradient of the links' transfer at the patch's four child points (the element links'
//! fit, `oracle::FitWeights`), limited so that the irradiance stays ≥ 0 at every vertex.

use crate::math::{DVec3, Rgb};
use crate::solver::hierarchical::oracle;

/// A patch's fit of its cluster links' transfer ([`super::ClusterTransfer::irradiance_and_slopes`]).
pub(super) struct PatchSlope<'a> {
    pts: [DVec3; 4],
    /// The patch's centroid, where the slope's shift is zero (push-pull's).
    centroid: DVec3,
    normal: DVec3,
    t1: DVec3,
    t2: DVec3,
    fit: oracle::FitWeights,
    vertices: &'a [DVec3],
}

impl<'a> PatchSlope<'a> {
    pub(super) fn new(e: &'a crate::solver::hierarchy::Element) -> Option<PatchSlope<'a>> {
        let pts = oracle::child_points(e);
        let c = (pts[0] + pts[1] + pts[2] + pts[3]) * 0.25;
        let (t1, t2) = crate::math::orthonormal_basis(e.normal);
        let fit = oracle::FitWeights::new(&pts, c, t1, t2)?;
        Some(PatchSlope { pts, centroid: e.centroid, normal: e.normal, t1, t2, fit, vertices: e.vertices() })
    }

    /// The gradient (basis t1, t2) of the transfer from a node centred at `src` to this patch
    /// (centred at `at`), relative to its value at `at`: the distance term π d² + reg and the
    /// receiver's cosine evaluated at the fit points.
    pub(super) fn gradient(&self, at: DVec3, src: DVec3, reg: f32) -> [f64; 2] {
        let reg = f64::from(reg);
        let pi = std::f64::consts::PI;
        let d0 = src - at;
        let at_centre = pi * d0.length_squared() + reg;
        let vals = self.pts.map(|x| {
            let d = src - x;
            let l2 = d.length_squared();
            if !(l2 > 0.0) {
                return 0.0;
            }
            at_centre / (pi * l2 + reg) * (self.normal.dot(d) / l2.sqrt()).max(0.0)
        });
        let mean = (vals[0] + vals[1] + vals[2] + vals[3]) * 0.25;
        let (mut gu, mut gv) = (0.0, 0.0);
        for ((v, wu), wv) in vals.iter().zip(self.fit.u).zip(self.fit.v) {
            gu += (v - mean) * wu;
            gv += (v - mean) * wv;
        }
        if gu.is_finite() && gv.is_finite() { [gu, gv] } else { [0.0; 2] }
    }

    /// `grad` scaled down, per channel, so that `value` plus the slope's shift stays ≥ 0 at
    /// every vertex of the patch.
    pub(super) fn limit(&self, value: Rgb, grad: [Rgb; 2]) -> [Rgb; 2] {
        let mut scale = [1.0f64; 3];
        for v in self.vertices {
            let (du, dv) = ((*v - self.centroid).dot(self.t1), (*v - self.centroid).dot(self.t2));
            for (ch, scale) in scale.iter_mut().enumerate() {
                let shift = grad[0].0[ch] * du + grad[1].0[ch] * dv;
                if shift < 0.0 && value.0[ch] + shift < 0.0 {
                    *scale = scale.min((value.0[ch].max(0.0) / -shift).max(0.0));
                }
            }
        }
        grad.map(|g| Rgb(std::array::from_fn(|ch| g.0[ch] * scale[ch])))
    }
}
