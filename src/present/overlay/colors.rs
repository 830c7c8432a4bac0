//! Colour scales for the overlays and their legends: viridis for link form factors and cluster
//! depths, a warm heat scale for the error heatmap, both on a logarithmic scale (spanning the
//! values, or robust: 10th to 99th percentile, at most four decades), and a categorical palette
//! for quadtree depth.

/// Viridis (matplotlib), 9 stops: perceptually uniform and readable by colour-blind viewers.
const VIRIDIS: [[f32; 3]; 9] = [
    [0.267, 0.005, 0.329],
    [0.283, 0.141, 0.458],
    [0.254, 0.265, 0.530],
    [0.207, 0.372, 0.553],
    [0.164, 0.471, 0.558],
    [0.128, 0.567, 0.551],
    [0.135, 0.659, 0.518],
    [0.267, 0.749, 0.441],
    [0.993, 0.906, 0.144],
];

/// Inferno-like warm scale for the error heatmap (black → red → yellow → white).
const HEAT: [[f32; 3]; 6] = [
    [0.0, 0.0, 0.04],
    [0.34, 0.06, 0.43],
    [0.73, 0.21, 0.33],
    [0.97, 0.55, 0.04],
    [0.98, 0.85, 0.2],
    [1.0, 1.0, 0.85],
];

/// Which colour scale a legend shows.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Palette {
    Viridis,
    Heat,
}

impl Palette {
    /// Colour at t ∈ [0, 1] (clamped; NaN maps to 0).
    #[must_use]
    pub fn at(self, t: f64) -> [f32; 3] {
        let table: &[[f32; 3]] = match self {
            Palette::Viridis => &VIRIDIS,
            Palette::Heat => &HEAT,
        };
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let x = t * (table.len() - 1) as f64;
        let i = (x.floor() as usize).min(table.len() - 2);
        let f = (x - i as f64) as f32;
        let (a, b) = (table[i], table[i + 1]);
        [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]
    }
}

/// Percentiles bounding the error heatmap's colour scale (see [`LogScale::robust`]).
const ROBUST_LO_PERCENTILE: usize = 10;
const ROBUST_HI_PERCENTILE: usize = 99;
/// The heatmap spans at most this many decades: errors 10⁴ below the largest are "none" to
/// the eye, and a round-off-sized 2nd percentile (1e-15) would flatten every other colour.
const ROBUST_MAX_DECADES: i32 = 4;

/// A logarithmic scale from `lo` to `hi` (both > 0), for colour bars.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LogScale {
    pub lo: f64,
    pub hi: f64,
}

impl LogScale {
    /// The scale spanning the positive finite values, or `None` when there are none. A span of
    /// less than one decade is widened to one decade so that colours stay meaningful.
    #[must_use]
    pub fn spanning(values: impl IntoIterator<Item = f64>) -> Option<LogScale> {
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for v in values {
            if v > 0.0 && v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if hi <= 0.0 {
            return None;
        }
        if hi / lo < 10.0 {
            lo = hi / 10.0;
        }
        Some(LogScale { lo, hi })
    }
    /// A scale over the bulk of the positive finite values: from the 10th to the 99th
    /// percentile (values outside clamp to the ends), so one outlier or a few near-zero values
    /// do not squash every colour to one end. At least one decade wide, at most
    /// `ROBUST_MAX_DECADES`.
    #[must_use]
    pub fn robust(values: impl IntoIterator<Item = f64>) -> Option<LogScale> {
        let mut v: Vec<f64> = values.into_iter().filter(|x| *x > 0.0 && x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let at = |q: usize| v[((v.len() - 1) * q) / 100];
        let hi = at(ROBUST_HI_PERCENTILE);
        let lo = at(ROBUST_LO_PERCENTILE).max(hi * 10f64.powi(-ROBUST_MAX_DECADES)).min(hi / 10.0);
        Some(LogScale { lo, hi })
    }
    /// Position of `v` on the scale, in [0, 1] (values ≤ lo give 0).
    #[must_use]
    pub fn t(&self, v: f64) -> f64 {
        if v.is_nan() || v <= self.lo {
            return 0.0;
        }
        ((v.log10() - self.lo.log10()) / (self.hi.log10() - self.lo.log10())).clamp(0.0, 1.0)
    }
    /// The value at position t (inverse of [`LogScale::t`]).
    #[must_use]
    pub fn value_at(&self, t: f64) -> f64 {
        10f64.powf(self.lo.log10() + t * (self.hi.log10() - self.lo.log10()))
    }
}

/// Colour of quadtree depth `d`: a categorical palette (12 distinct hues, then it repeats).
#[must_use]
pub fn depth_color(depth: u8) -> [f32; 3] {
    const DEPTH: [[f32; 3]; 12] = [
        [1.0, 1.0, 1.0],
        [0.12, 0.47, 0.71],
        [1.0, 0.5, 0.05],
        [0.17, 0.63, 0.17],
        [0.84, 0.15, 0.16],
        [0.58, 0.4, 0.74],
        [0.55, 0.34, 0.29],
        [0.89, 0.47, 0.76],
        [0.5, 0.5, 0.5],
        [0.74, 0.74, 0.13],
        [0.09, 0.75, 0.81],
        [0.0, 0.0, 0.0],
    ];
    DEPTH[usize::from(depth) % DEPTH.len()]
}

/// Heatmap colours of per-element error values (indexed like `values`) on a robust log scale
/// ([`LogScale::robust`]); zero or negative error gets the scale's bottom colour.
#[must_use]
pub fn heatmap_colors(values: &[f64]) -> (Vec<[f32; 3]>, Option<LogScale>) {
    let scale = LogScale::robust(values.iter().copied());
    let colors = values.iter().map(|&v| Palette::Heat.at(scale.map_or(0.0, |s| s.t(v)))).collect();
    (colors, scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::overlay::test_support::EXACT;

    #[test]
    fn log_scale_and_heatmap() {
        let s = LogScale { lo: 1e-3, hi: 1.0 };
        assert!((s.t(1e-2) - 1.0 / 3.0).abs() < EXACT);
        assert!((s.value_at(s.t(0.05)) - 0.05).abs() < EXACT);
        assert_eq!(s.t(0.0), 0.0);
        assert!(LogScale::spanning([0.0, -1.0, f64::NAN]).is_none());
        let narrow = LogScale::spanning([0.5, 0.6]).unwrap();
        assert!((narrow.hi / narrow.lo - 10.0).abs() < EXACT, "widened to one decade");
        let (c, s) = heatmap_colors(&[0.0, 1e-4, 1e-2]);
        assert_eq!(c[0], Palette::Heat.at(0.0));
        assert_eq!(c[2], Palette::Heat.at(1.0));
        assert!(s.is_some());
        // One tiny and one huge outlier among 100 values do not set the ends of the scale.
        let mut v: Vec<f64> = (1..=98).map(|i| f64::from(i) * 1e-3).collect();
        v.extend([1e-16, 1e3]);
        let r = LogScale::robust(v).unwrap();
        assert!(r.lo >= 1e-3 && r.hi <= 0.1, "{r:?}");
        let r = LogScale::robust((0..100).map(|i| if i < 50 { 1e-15 } else { 1.0 })).unwrap();
        assert!((r.lo - 1e-4).abs() < 1e-12, "at most four decades: {r:?}");
        assert_eq!(Palette::Viridis.at(f64::NAN), Palette::Viridis.at(0.0));
    }
}
