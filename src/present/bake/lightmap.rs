//! The lightmap form of a bake: the solution's radiosity over every input patch, rasterised into
//! one square texture atlas that the original (unrefined) meshes address through `TEXCOORD_1`.
//!
//! Each patch gets its own chart, at one texel density d (texels per scene unit) for the whole
//! scene, so every square metre of wall gets the same number of texels. A chart is the patch laid
//! flat in its own plane (a patch is planar, so the map is exact: no distortion); the charts are
//! shelf-packed, tallest first [Jylänki 2010, "A thousand ways to pack the bin", the SHELF
//! next-fit rule] and d is the largest that fits (bisection).
//!
//! A texel holds the solution's own reconstruction at its centre — the radiosity of the leaf
//! element that contains it, linear in the element's slope where it has one
//! ([`crate::eval::pointwise::PiecewiseConstant`]) — exposed and clipped as `COLOR_0` is, then
//! sRGB-encoded, because glTF decodes a base-colour texture from sRGB [glTF 2.0, sec. 3.9.2]:
//!
//! ```text
//!   texel = round(255 · sRGB(clamp(B(x) · exposure, 0, 1)))     x = the texel's centre on the patch
//! ```
//!
//! ## How it works
//! ```text
//!   patch (3-D)            chart (plane frame)          atlas (texels, row 0 = v 0)
//!     v3 ──── v2           ^ b                          ┌──────────────────────────┐
//!     │        │           │ ┌──────┐ h                 │ ░░░░░░░░ ░░░░░ ░░░░      │ ░ gutter:
//!     │        │   ──►     │ │      │       ──►         │ ░▓▓▓▓▓▓░ ░▓▓▓░ ░▓▓░ ...  │   copies of
//!     v0 ──── v1           │ └──────┘                   │ ░░░░░░░░ ░░░░░ ░░░░      │   the chart's
//!                          o────────► a  (a ∥ v1 − v0)  │ shelf 2 …                │   edge texels
//!                             w                         └──────────────────────────┘
//! ```
//! 1. Chart: a = (v1 − v0)/|v1 − v0|, b = n × a (turned to (b, −a) where that makes the box
//!    wider than tall); the patch's bounding box in (a, b) is w × h.
//! 2. Size: ⌈w d⌉ × ⌈h d⌉ texels, at least 1 × 1, plus `padding` texels on every side; sorted by
//!    height (then width, then patch index) and placed left to right in shelves. d is bisected
//!    between 0 and √(size² / Σ w h); if even 1 × 1 charts do not fit, the bake is refused.
//! 3. Texels: the centre of each texel of a chart, moved to the nearest point of the patch (a
//!    texel that straddles a triangle's long edge reads the value at that edge), is located in the
//!    patch's leaf elements and evaluated.
//! 4. Gutter: each padding texel repeats the nearest texel of its own chart, so bilinear
//!    filtering at a chart's border never reads a neighbour or the black background. The sampler
//!    is LINEAR without mipmaps: a mip level would average across charts.
//!
//! The texture coordinates of a vertex are its position in the chart mapped to the atlas, the
//! chart's box onto its interior texels: uv = (x + w_t (p_a − lo_a)/w, y + h_t (p_b − lo_b)/h) /
//! size. Work and memory are bounded by the size (at most 8192² texels, 3 bytes each) and the
//! patch count; the bytes are deterministic (atlas rows in parallel, each written by one task).

use super::BakeError;
use crate::eval::pointwise::{PiecewiseConstant, Reconstruction};
use crate::math::DVec3;
use crate::present::image::srgb_encode;
use crate::scene::{Patch, Scene};
use crate::solver::Solution;
use rayon::prelude::*;

/// How each texel is computed from B; written to the extras.
pub const TEXEL_RULE: &str = "lightmap texel = round(255 * sRGB(clamp(B(x) * exposure, 0, 1))), 8-bit RGB PNG \
(sRGB-encoded, as glTF base-colour textures are); B(x) = the solution at the texel's centre x on its patch \
(the leaf element holding x, linear in its slope where it has one)";

/// The settings of a lightmap: its size and the gutter around each chart.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct LightmapParams {
    /// Width = height of the atlas in texels: a power of two in [`Self::MIN_SIZE`]..=[`Self::MAX_SIZE`].
    pub size: u32,
    /// Texels of gutter on every side of each chart (copies of the chart's edge), so bilinear
    /// filtering at a chart's border reads only its own colours; 1 suffices without mipmaps,
    /// 2 also keeps the first mip level of a viewer that makes them anyway clean.
    pub padding: u32,
}

impl LightmapParams {
    /// The smallest atlas offered.
    pub const MIN_SIZE: u32 = 64;
    /// The largest atlas offered: 8192² texels, 192 MiB of RGB before compression.
    pub const MAX_SIZE: u32 = 8192;

    /// A `size` × `size` atlas with a 2-texel gutter.
    #[must_use]
    pub const fn new(size: u32) -> LightmapParams {
        LightmapParams { size, padding: 2 }
    }

    /// [`BakeError::BadLightmapSize`] unless `size` is a power of two in range and the padding
    /// leaves room for a texel.
    pub fn check(&self) -> Result<(), BakeError> {
        let ok = self.size.is_power_of_two()
            && (Self::MIN_SIZE..=Self::MAX_SIZE).contains(&self.size)
            && self.padding < Self::MIN_SIZE / 4;
        if ok { Ok(()) } else { Err(BakeError::BadLightmapSize(self.size)) }
    }
}

/// 8-bit sRGB of linear values without a `powf` per texel: level k is taken where
/// t_k ≤ v < t_(k+1), t_k the linear value that [`srgb_encode`] maps to (k − ½)/255 (found by
/// bisection), i.e. round(255 · srgb_encode(clamp(v, 0, 1))).
struct Srgb8 {
    thresholds: [f64; 255],
}

impl Srgb8 {
    fn new() -> Srgb8 {
        Srgb8 {
            thresholds: std::array::from_fn(|k| {
                let target = (k as f64 + 0.5) / 255.0;
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..64 {
                    let mid = 0.5 * (lo + hi);
                    if srgb_encode(mid) < target { lo = mid } else { hi = mid }
                }
                hi
            }),
        }
    }

    fn level(&self, linear: f64) -> u8 {
        // NaN (never here: the bake checks B) would read as 0.
        self.thresholds.partition_point(|&t| t <= linear) as u8
    }
}

/// One patch's place in the atlas: its plane frame and its texel rectangle.
#[derive(Clone, Debug)]
pub struct Chart {
    /// The patch (index into `scene.patches`).
    pub patch: usize,
    origin: DVec3,
    axes: [DVec3; 2],
    /// The patch's vertices in the plane frame.
    polygon: Vec<[f64; 2]>,
    /// The patch's bounding box in the plane frame: its low corner and its (positive) extent.
    lo: [f64; 2],
    extent: [f64; 2],
    /// The chart's interior texels: `x..x + w` × `y..y + h` of the atlas (the gutter lies around).
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl Chart {
    fn new(patch: usize, p: &Patch) -> Chart {
        let a = (p.vertices[1] - p.vertices[0]).normalize();
        let chart = Chart::in_frame(patch, p, [a, p.normal.cross(a).normalize()]);
        // Landscape: the frame turned a quarter (b, −a: still right-handed, the polygon still
        // counter-clockwise) where the box is taller than wide, so shelves waste less.
        if chart.extent[1] > chart.extent[0] {
            Chart::in_frame(patch, p, [chart.axes[1], -chart.axes[0]])
        } else {
            chart
        }
    }

    fn in_frame(patch: usize, p: &Patch, axes: [DVec3; 2]) -> Chart {
        let origin = p.vertices[0];
        let polygon: Vec<[f64; 2]> =
            p.vertices.iter().map(|&v| [(v - origin).dot(axes[0]), (v - origin).dot(axes[1])]).collect();
        let lo = [0, 1].map(|k| polygon.iter().map(|q| q[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1].map(|k| polygon.iter().map(|q| q[k]).fold(f64::NEG_INFINITY, f64::max));
        let extent = [hi[0] - lo[0], hi[1] - lo[1]];
        Chart { patch, origin, axes, polygon, lo, extent, x: 0, y: 0, w: 0, h: 0 }
    }

    /// Interior texels along each axis at `density` texels per scene unit (at least 1).
    fn texels(&self, density: f64, size: u32) -> [u32; 2] {
        self.extent.map(|e| (e * density).ceil().clamp(1.0, f64::from(size)) as u32)
    }

    /// The atlas texture coordinates (in [0, 1], v down) of a point of the patch.
    #[must_use]
    pub fn uv(&self, p: DVec3, size: u32) -> [f32; 2] {
        let q = [(p - self.origin).dot(self.axes[0]), (p - self.origin).dot(self.axes[1])];
        let s = f64::from(size);
        let t = |k: usize, start: u32, n: u32| {
            (f64::from(start) + f64::from(n) * (q[k] - self.lo[k]) / self.extent[k]) / s
        };
        [t(0, self.x, self.w) as f32, t(1, self.y, self.h) as f32]
    }

    /// A point of the patch in the patch's own plane, in scene units from the corner of its
    /// bounding box (`TEXCOORD_0` of the lightmap form).
    #[must_use]
    pub fn plane_uv(&self, p: DVec3) -> [f32; 2] {
        let q = [(p - self.origin).dot(self.axes[0]), (p - self.origin).dot(self.axes[1])];
        [(q[0] - self.lo[0]) as f32, (q[1] - self.lo[1]) as f32]
    }

    /// The point of the patch a texel (i, j) of the chart's interior stands for: its centre,
    /// moved onto the patch if it lies outside.
    #[must_use]
    pub fn texel_point(&self, i: u32, j: u32) -> DVec3 {
        let q = [
            self.lo[0] + self.extent[0] * (f64::from(i) + 0.5) / f64::from(self.w),
            self.lo[1] + self.extent[1] * (f64::from(j) + 0.5) / f64::from(self.h),
        ];
        let [u, v] = nearest_in_convex(&self.polygon, q);
        self.origin + self.axes[0] * u + self.axes[1] * v
    }
}

/// The nearest point to `q` of a convex polygon given counter-clockwise (`q` if inside).
fn nearest_in_convex(polygon: &[[f64; 2]], q: [f64; 2]) -> [f64; 2] {
    let n = polygon.len();
    let edge = |k: usize| (polygon[k], polygon[(k + 1) % n]);
    let inside = (0..n).all(|k| {
        let (a, b) = edge(k);
        (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) >= 0.0
    });
    if inside {
        return q;
    }
    let mut best = (f64::INFINITY, q);
    for k in 0..n {
        let (a, b) = edge(k);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let t = if len2 > 0.0 {
            (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = [a[0] + t * d[0], a[1] + t * d[1]];
        let dist2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
        if dist2 < best.0 {
            best = (dist2, p);
        }
    }
    best.1
}

/// A rasterised atlas.
#[derive(Clone, Debug)]
pub struct Lightmap {
    pub params: LightmapParams,
    /// Texels per scene unit along each chart's axes (at least this: a chart's texel count is
    /// rounded up).
    pub texels_per_unit: f64,
    /// One chart per patch, in patch order.
    pub charts: Vec<Chart>,
    /// `size² × 3` bytes, sRGB, row 0 first (texture coordinate v = 0).
    pub rgb: Vec<u8>,
    /// Interior texels with a channel of B · exposure outside [0, 1].
    pub clipped_texels: usize,
}

impl Lightmap {
    /// Lay out every patch of `scene` and rasterise `solution` into the atlas.
    pub fn bake(
        scene: &Scene,
        solution: &Solution,
        exposure: f64,
        params: LightmapParams,
    ) -> Result<Lightmap, BakeError> {
        params.check()?;
        let (charts, texels_per_unit) = pack(scene, params)?;
        let reconstruction = PiecewiseConstant::new(scene, &solution.elements)?;
        let size = params.size as usize;
        let p = params.padding;
        // The charts each atlas row crosses, gutter included.
        let mut crossing: Vec<Vec<u32>> = vec![Vec::new(); size];
        for (k, c) in charts.iter().enumerate() {
            for y in c.y - p..c.y + c.h + p {
                crossing[y as usize].push(k as u32);
            }
        }
        let srgb8 = Srgb8::new();
        // Rows in parallel, each written by itself: the bytes do not depend on the thread count.
        let mut rgb = vec![0u8; size * size * 3];
        let clipped_texels = rgb
            .par_chunks_mut(3 * size)
            .zip(&crossing)
            .enumerate()
            .map(|(y, (row, crossing))| {
                let mut clipped = 0;
                for &k in crossing {
                    let c = &charts[k as usize];
                    // A gutter row above or below the chart repeats its first or last row.
                    let j = (y as u32).saturating_sub(c.y).min(c.h - 1);
                    let gutter_row = j != (y as u32).wrapping_sub(c.y);
                    for i in 0..c.w {
                        let b = reconstruction.radiosity_at(c.patch, c.texel_point(i, j));
                        let exposed = b.0.map(|v| v * exposure);
                        if !gutter_row && exposed.iter().any(|v| !(0.0..=1.0).contains(v)) {
                            clipped += 1;
                        }
                        let at = 3 * (c.x + i) as usize;
                        row[at..at + 3].copy_from_slice(&exposed.map(|v| srgb8.level(v)));
                    }
                    // The gutter left and right repeats the row's first and last texel.
                    let (first, last) = (3 * c.x as usize, 3 * (c.x + c.w - 1) as usize);
                    for g in 1..=p as usize {
                        row.copy_within(first..first + 3, first - 3 * g);
                        row.copy_within(last..last + 3, last + 3 * g);
                    }
                }
                clipped
            })
            .sum();
        Ok(Lightmap { params, texels_per_unit, charts, rgb, clipped_texels })
    }

    /// Fraction of the atlas covered by chart interiors (the rest is gutter and unused).
    #[must_use]
    pub fn coverage(&self) -> f64 {
        let used: u64 = self.charts.iter().map(|c| u64::from(c.w) * u64::from(c.h)).sum();
        used as f64 / f64::from(self.params.size).powi(2)
    }

    /// The atlas as an 8-bit RGB PNG, tagged sRGB (deterministic bytes).
    #[must_use]
    pub fn png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        crate::present::image::encode_srgb8_png(&mut out, self.params.size, self.params.size, &self.rgb)
            .expect("the atlas holds size² RGB texels, encoded to memory");
        out
    }
}

/// One chart per patch, placed, and the texel density they were placed at (module docs, steps
/// 1–2).
fn pack(scene: &Scene, params: LightmapParams) -> Result<(Vec<Chart>, f64), BakeError> {
    if scene.patches.is_empty() {
        return Err(BakeError::Empty);
    }
    let mut charts: Vec<Chart> = scene.patches.iter().enumerate().map(|(i, p)| Chart::new(i, p)).collect();
    // Tallest first, then widest, then patch order: the order the shelves are filled in, which
    // ⌈· d⌉ keeps for every d.
    let mut order: Vec<usize> = (0..charts.len()).collect();
    order.sort_by(|&i, &j| {
        let (a, b) = (&charts[i].extent, &charts[j].extent);
        b[1].total_cmp(&a[1]).then(b[0].total_cmp(&a[0])).then(i.cmp(&j))
    });
    let fits = |charts: &mut [Chart], density: f64| shelves(charts, &order, density, params);
    if !fits(&mut charts, 0.0) {
        return Err(BakeError::LightmapTooSmall { size: params.size, charts: charts.len() });
    }
    let area: f64 = charts.iter().map(|c| c.extent[0] * c.extent[1]).sum();
    // At `hi` the charts alone (no gutter) cover the whole atlas: the gutter makes it too much.
    let (mut lo, mut hi) = (0.0, f64::from(params.size) / area.sqrt());
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if fits(&mut charts, mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // Place the charts at `lo` (the last call may have been a density that did not fit).
    let placed = fits(&mut charts, lo);
    debug_assert!(placed, "the density last found to fit, fits");
    Ok((charts, lo))
}

/// Place the charts in `order` in shelves at `density`; false if they overflow the atlas.
fn shelves(charts: &mut [Chart], order: &[usize], density: f64, params: LightmapParams) -> bool {
    let (size, p) = (params.size, params.padding);
    let (mut x, mut y, mut shelf) = (0u32, 0u32, 0u32);
    for &i in order {
        let [w, h] = charts[i].texels(density, size);
        let (pw, ph) = (w + 2 * p, h + 2 * p);
        if pw > size {
            return false;
        }
        if x + pw > size {
            (x, y, shelf) = (0, y + shelf, 0);
        }
        if y + ph > size {
            return false;
        }
        let c = &mut charts[i];
        (c.x, c.y, c.w, c.h) = (x + p, y + p, w, h);
        x += pw;
        shelf = shelf.max(ph);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    #[test]
    fn sizes_outside_the_range_or_not_powers_of_two_are_refused() {
        for ok in [64, 128, 1024, 8192] {
            assert!(LightmapParams::new(ok).check().is_ok(), "{ok}");
        }
        for bad in [0, 1, 32, 63, 100, 1000, 16384] {
            assert!(
                matches!(LightmapParams::new(bad).check(), Err(BakeError::BadLightmapSize(s)) if s == bad)
            );
        }
    }

    #[test]
    fn charts_do_not_overlap_and_keep_the_density_uniform() {
        let scene = builtin::load("splash_room").unwrap();
        let params = LightmapParams::new(512);
        let (charts, d) = pack(&scene, params).unwrap();
        assert!(d > 0.0);
        let p = params.padding;
        let padded = |c: &Chart| (c.x - p, c.y - p, c.x + c.w + p, c.y + c.h + p);
        for (i, a) in charts.iter().enumerate() {
            let (ax0, ay0, ax1, ay1) = padded(a);
            assert!(ax1 <= params.size && ay1 <= params.size, "chart {i} leaves the atlas");
            // Uniform density: the texel count is ⌈extent · d⌉ (at least 1).
            for k in 0..2 {
                let n = [a.w, a.h][k];
                assert_eq!(n, ((a.extent[k] * d).ceil() as u32).max(1), "chart {i} axis {k}");
            }
            for b in &charts[i + 1..] {
                let (bx0, by0, bx1, by1) = padded(b);
                assert!(
                    ax1 <= bx0 || bx1 <= ax0 || ay1 <= by0 || by1 <= ay0,
                    "charts {i} and {} overlap",
                    b.patch
                );
            }
        }
        // The bisection is tight: 1 % more density no longer fits.
        let mut again = charts.clone();
        let mut order: Vec<usize> = (0..again.len()).collect();
        order.sort_by(|&i, &j| {
            let (a, b) = (&again[i].extent, &again[j].extent);
            b[1].total_cmp(&a[1]).then(b[0].total_cmp(&a[0])).then(i.cmp(&j))
        });
        assert!(!shelves(&mut again, &order, d * 1.01, params));
    }

    #[test]
    fn too_many_charts_for_the_atlas_is_an_error() {
        // 64² texels hold at most ⌊64 / 5⌋² = 144 charts of 1 × 1 texel with a 2-texel gutter.
        let scene = builtin::load("splash_room").unwrap();
        assert!(scene.patches.len() > 144, "{} patches", scene.patches.len());
        assert!(matches!(
            pack(&scene, LightmapParams::new(64)),
            Err(BakeError::LightmapTooSmall { size: 64, .. })
        ));
    }

    #[test]
    fn uv_maps_the_chart_box_onto_its_texels_and_texel_points_lie_on_the_patch() {
        let scene = builtin::build("cornell").unwrap();
        let params = LightmapParams::new(256);
        let (charts, _) = pack(&scene, params).unwrap();
        let s = f64::from(params.size);
        let mut inside = 0;
        for c in &charts {
            let patch = &scene.patches[c.patch];
            for v in &patch.vertices {
                let [u, w] = c.uv(*v, params.size).map(f64::from);
                assert!(u * s >= f64::from(c.x) - 1e-3 && u * s <= f64::from(c.x + c.w) + 1e-3);
                assert!(w * s >= f64::from(c.y) - 1e-3 && w * s <= f64::from(c.y + c.h) + 1e-3);
            }
            for (i, j) in [(0, 0), (c.w - 1, 0), (0, c.h - 1), (c.w - 1, c.h - 1), (c.w / 2, c.h / 2)] {
                let x = c.texel_point(i, j);
                assert!((x - patch.vertices[0]).dot(patch.normal).abs() < 1e-9, "off the plane");
                // The point maps into the chart; a texel centre on the patch maps back onto itself.
                let [u, w] = c.uv(x, params.size).map(|t| f64::from(t) * s);
                assert!(u >= f64::from(c.x) - 1e-3 && u <= f64::from(c.x + c.w) + 1e-3, "{u}");
                assert!(w >= f64::from(c.y) - 1e-3 && w <= f64::from(c.y + c.h) + 1e-3, "{w}");
                let q = [
                    c.lo[0] + c.extent[0] * (f64::from(i) + 0.5) / f64::from(c.w),
                    c.lo[1] + c.extent[1] * (f64::from(j) + 0.5) / f64::from(c.h),
                ];
                if nearest_in_convex(&c.polygon, q) == q {
                    inside += 1;
                    let centre = [f64::from(c.x + i) + 0.5, f64::from(c.y + j) + 0.5];
                    assert!(
                        (u - centre[0]).abs() < 1e-3 && (w - centre[1]).abs() < 1e-3,
                        "{u},{w} vs {centre:?}"
                    );
                }
            }
        }
        assert!(inside >= 3 * charts.len(), "{inside} texel centres on their patches");
    }

    #[test]
    fn srgb8_levels_are_the_rounded_encoding() {
        let s = Srgb8::new();
        for i in 0..=100_000 {
            let v = f64::from(i) / 100_000.0;
            assert_eq!(s.level(v), (srgb_encode(v) * 255.0).round() as u8, "{v}");
        }
        assert_eq!((s.level(-1.0), s.level(0.0), s.level(1.0), s.level(7.0)), (0, 0, 255, 255));
    }

    #[test]
    fn nearest_point_of_a_triangle() {
        let tri = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(nearest_in_convex(&tri, [0.25, 0.25]), [0.25, 0.25]);
        assert_eq!(nearest_in_convex(&tri, [1.0, 1.0]), [0.5, 0.5]);
        assert_eq!(nearest_in_convex(&tri, [-1.0, 0.5]), [0.0, 0.5]);
        assert_eq!(nearest_in_convex(&tri, [2.0, -1.0]), [1.0, 0.0]);
    }
}
