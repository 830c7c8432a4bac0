//! A CPU renderer of radiosity solutions: one primary ray per pixel through [`Accel::first_hit`],
//! the element under the hit point looked up on the hit patch, the pixel coloured by a caller's
//! `shade(element)`. Used by `radlab solve --png` and for error images.
//!
//! Radiosity is view-independent: for a diffuse surface the radiance leaving it is L = B/π in
//! every direction [Cohen & Wallace 1993, sec. 2.4], so an image of a solution is just B (up to the
//! constant π) of the first surface each pixel sees. [`View::radiosity_image`] shows linear B scaled so
//! the 99th percentile of the visible pixels' luminance maps to white, then sRGB-encoded
//! (IEC 61966-2-1); [`View::value_image`] maps any per-element value through a colour map and draws a
//! colour bar with its min/max written in a tiny built-in digit font.
//!
//! ## How it works
//! ```text
//!   pixel ──ray──▶ Accel::first_hit ──▶ (patch, t) ──▶ hit point x on the patch plane
//!                                                 └──▶ patch grid cell of x ──▶ element ∋ x
//! ```
//! Per patch, its elements are projected to the patch's 2D frame and binned into a uniform grid
//! (about one element per cell), built once per render. A ray that hits a patch from behind is
//! drawn in a flat [`BACK_FACE`] colour, a ray that hits nothing in [`BACKGROUND`].
//!
//! Rows are rendered in parallel (rayon); every pixel is a pure function of its coordinates, so
//! the image is identical for any thread count.

use crate::geometry::accel::Accel;
use crate::math::{DVec3, orthonormal_basis};
use crate::scene::{Scene, Viewpoint};
use crate::solver::SolvedElement;
use rayon::prelude::*;
use std::path::Path;

/// Colour of pixels that see no surface (display-referred).
pub const BACKGROUND: [f32; 3] = [0.10, 0.11, 0.14];
/// Colour of pixels that see the back of a (one-sided) patch.
pub const BACK_FACE: [f32; 3] = [0.55, 0.12, 0.50];
/// Colour of pixels on a patch that has no element in the solution (or a value that is not finite).
pub const NO_VALUE: [f32; 3] = [0.35, 0.35, 0.35];

/// Relative tolerance (of the element's size) for a point on an element's edge to count as inside.
const INSIDE_REL: f64 = 1e-9;
/// How much more a back face seen by a default open-scene camera counts than a front face.
pub const BACK_FACE_PENALTY: f64 = 2.0;
/// The percentile of visible-pixel luminance that maps to white in [`View::radiosity_image`].
const EXPOSURE_PERCENTILE: f64 = 0.99;

/// A pinhole camera.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
}

impl From<Viewpoint> for Camera {
    fn from(v: Viewpoint) -> Camera {
        Camera { eye: v.eye, target: v.target, up: v.up, fov_y_deg: v.fov_y_deg }
    }
}

impl Camera {
    /// The scene's own camera if it has one; otherwise a framing of its bounds (y up):
    ///
    /// - **Closed scenes** (rays from the bounds' centre in 14 directions all hit a patch from its
    ///   front — a room seen from inside): from inside, near the upper (+x, +z) corner at 3/4 of
    ///   the height, looking at the opposite lower part of the room, 70° field of view.
    /// - **Open scenes**: from outside, far enough that the bounding sphere fits a 45° field of
    ///   view, from the direction (an oblique default or one of the 26 directions of a cube's faces,
    ///   edges and corners) where Σ area × cos(patch normal, to eye) is largest, back faces
    ///   weighted [`BACK_FACE_PENALTY`]× (occlusion ignored): the view that sees most fronts.
    #[must_use]
    pub fn for_scene(scene: &Scene) -> Camera {
        if let Some(v) = scene.camera {
            return v.into();
        }
        let b = scene.bounds();
        let (lo, hi) = (b.min, b.max);
        let c = b.center();
        let radius = (0.5 * b.diagonal()).max(f64::MIN_POSITIVE);
        if is_closed_from(scene, c) {
            let at = |f: DVec3| lo + (hi - lo) * f;
            return Camera {
                eye: at(DVec3::new(0.9, 0.75, 0.9)),
                target: at(DVec3::new(0.3, 0.3, 0.3)),
                up: DVec3::Y,
                fov_y_deg: 70.0,
            };
        }
        let fov: f64 = 45.0;
        let dist = radius / (0.5 * fov.to_radians()).sin();
        // Candidates: an oblique default, then the 26 directions of a cube's faces, edges and
        // corners; the best sees the most front-facing area (back faces count against it).
        let mut candidates = vec![DVec3::new(0.35, 0.45, 0.8).normalize()];
        for x in [-1.0, 0.0, 1.0] {
            for y in [-1.0, 0.0, 1.0] {
                for z in [-1.0, 0.0, 1.0] {
                    if (x, y, z) != (0.0, 0.0, 0.0) {
                        candidates.push(DVec3::new(x, y, z).normalize());
                    }
                }
            }
        }
        let score = |dir: DVec3| -> f64 {
            let eye = c + dir * dist;
            scene
                .patches
                .iter()
                .map(|p| {
                    let cos = p.normal.dot((eye - p.centroid).normalize_or_zero());
                    p.area * if cos >= 0.0 { cos } else { BACK_FACE_PENALTY * cos }
                })
                .sum()
        };
        let mut dir = candidates[0];
        let mut best = score(dir);
        for &d in &candidates[1..] {
            let s = score(d);
            if s > best * (1.0 + 1e-9) + 1e-300 {
                best = s;
                dir = d;
            }
        }
        let up = if dir.cross(DVec3::Y).length() < 1e-3 { DVec3::Z } else { DVec3::Y };
        Camera { eye: c + dir * dist, target: c, up, fov_y_deg: fov }
    }

    /// The ray through pixel (`x`, `y`) (pixel centres, y down) of a `w`×`h` image: (origin, unit direction).
    #[must_use]
    pub fn ray(&self, x: f64, y: f64, w: usize, h: usize) -> (DVec3, DVec3) {
        let forward = (self.target - self.eye).normalize_or(DVec3::NEG_Z);
        let mut right = forward.cross(self.up).normalize_or_zero();
        if right == DVec3::ZERO {
            right = orthonormal_basis(forward).0;
        }
        let up = right.cross(forward);
        let tan = (0.5 * self.fov_y_deg.to_radians()).tan();
        let aspect = w as f64 / h.max(1) as f64;
        let sx = (2.0 * (x + 0.5) / w.max(1) as f64 - 1.0) * tan * aspect;
        let sy = (1.0 - 2.0 * (y + 0.5) / h.max(1) as f64) * tan;
        (self.eye, (forward + right * sx + up * sy).normalize())
    }
}

/// Do rays from `p` in 14 directions (6 axes, 8 diagonals) all hit some patch from its front?
/// Brute force over the patches (no BVH needed: 14 rays).
fn is_closed_from(scene: &Scene, p: DVec3) -> bool {
    let mut dirs = vec![DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z];
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                dirs.push(DVec3::new(sx, sy, sz).normalize());
            }
        }
    }
    dirs.iter().all(|&d| {
        let mut best: Option<(f64, bool)> = None;
        for patch in &scene.patches {
            let denom = patch.normal.dot(d);
            if denom.abs() < 1e-12 {
                continue;
            }
            let t = (patch.plane_d() - patch.normal.dot(p)) / denom;
            let ahead = t > 0.0; // false for NaN
            if !ahead || best.is_some_and(|(bt, _)| bt <= t) {
                continue;
            }
            let x = p + d * t;
            let n = patch.vertices.len();
            let inside = (0..n).all(|k| {
                let a = patch.vertices[k];
                let b = patch.vertices[(k + 1) % n];
                (b - a).cross(x - a).dot(patch.normal) >= 0.0
            });
            if inside {
                best = Some((t, denom < 0.0));
            }
        }
        best.is_some_and(|(_, front)| front)
    })
}

/// An RGB image, row-major from the top-left, display-referred values in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    #[must_use]
    pub fn new(width: usize, height: usize, fill: [f32; 3]) -> Image {
        Image { width, height, pixels: vec![fill; width * height] }
    }

    #[must_use]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }

    fn set(&mut self, x: usize, y: usize, c: [f32; 3]) {
        if x < self.width && y < self.height {
            self.pixels[y * self.width + x] = c;
        }
    }

    /// 8-bit RGB bytes (values clamped to [0, 1], rounded).
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
    }

    /// Write an 8-bit sRGB PNG.
    pub fn write_png(&self, path: &Path) -> std::io::Result<()> {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        encode_srgb8_png(file, self.width as u32, self.height as u32, &self.to_rgb8())
    }
}

/// Encode `rgb` (width × height 8-bit RGB triples, rows top down) as a PNG tagged sRGB into
/// `out`; the same input gives the same bytes.
pub fn encode_srgb8_png<W: std::io::Write>(
    out: W,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> std::io::Result<()> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer.write_image_data(rgb).map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)
}

/// What a pixel sees.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum PixelHit {
    Background,
    BackFace,
    /// The front of a patch that has no element covering the hit point.
    NoElement,
    Element(usize),
}

/// Per-patch lookup grid: elements in the patch's 2D frame.
struct PatchGrid {
    origin: DVec3,
    t1: DVec3,
    t2: DVec3,
    min: [f64; 2],
    cell: [f64; 2],
    dims: [usize; 2],
    /// Element indices per cell (row-major), candidates whose 2D bounds overlap the cell.
    cells: Vec<Vec<u32>>,
    /// 2D polygons of the patch's elements (by element index, only this patch's are `Some`).
    polys: Vec<(usize, Vec<[f64; 2]>)>,
}

/// Which element of each patch contains a point: built once per render.
struct ElementLocator {
    grids: Vec<Option<PatchGrid>>,
}

impl ElementLocator {
    fn new(scene: &Scene, elements: &[SolvedElement]) -> ElementLocator {
        let mut by_patch: Vec<Vec<usize>> = vec![Vec::new(); scene.patches.len()];
        for (i, e) in elements.iter().enumerate() {
            if let Some(v) = by_patch.get_mut(e.patch) {
                v.push(i);
            }
        }
        let grids = by_patch
            .into_iter()
            .enumerate()
            .map(|(p, list)| {
                if list.is_empty() {
                    return None;
                }
                let patch = &scene.patches[p];
                let (t1, t2) = orthonormal_basis(patch.normal);
                let origin = patch.vertices[0];
                let to2 = |v: DVec3| [(v - origin).dot(t1), (v - origin).dot(t2)];
                let polys: Vec<(usize, Vec<[f64; 2]>)> = list
                    .iter()
                    .map(|&i| (i, elements[i].vertices.iter().map(|&v| to2(v)).collect()))
                    .collect();
                let mut min = [f64::INFINITY; 2];
                let mut max = [f64::NEG_INFINITY; 2];
                for (_, poly) in &polys {
                    for q in poly {
                        for k in 0..2 {
                            min[k] = min[k].min(q[k]);
                            max[k] = max[k].max(q[k]);
                        }
                    }
                }
                let side = (polys.len() as f64).sqrt().ceil().clamp(1.0, 256.0) as usize;
                let dims = [side, side];
                let cell = [0, 1].map(|k| ((max[k] - min[k]) / side as f64).max(f64::MIN_POSITIVE));
                let mut cells = vec![Vec::new(); side * side];
                for (slot, (_, poly)) in polys.iter().enumerate() {
                    let lo = [0, 1].map(|k| poly.iter().map(|q| q[k]).fold(f64::INFINITY, f64::min));
                    let hi = [0, 1].map(|k| poly.iter().map(|q| q[k]).fold(f64::NEG_INFINITY, f64::max));
                    let c0 = [0, 1].map(|k| cell_of(lo[k], min[k], cell[k], dims[k]));
                    let c1 = [0, 1].map(|k| cell_of(hi[k], min[k], cell[k], dims[k]));
                    for cy in c0[1]..=c1[1] {
                        for cx in c0[0]..=c1[0] {
                            cells[cy * side + cx].push(slot as u32);
                        }
                    }
                }
                Some(PatchGrid { origin, t1, t2, min, cell, dims, cells, polys })
            })
            .collect();
        ElementLocator { grids }
    }

    /// The element of `patch` containing `x` (or, at an edge missed by round-off, the nearest
    /// candidate of its cell).
    fn locate(&self, patch: usize, x: DVec3) -> Option<usize> {
        let g = self.grids.get(patch)?.as_ref()?;
        let q = [(x - g.origin).dot(g.t1), (x - g.origin).dot(g.t2)];
        let c = [0, 1].map(|k| cell_of(q[k], g.min[k], g.cell[k], g.dims[k]));
        let cands = &g.cells[c[1] * g.dims[0] + c[0]];
        let mut nearest: Option<(f64, usize)> = None;
        for &slot in cands {
            let (elem, poly) = &g.polys[slot as usize];
            if inside_2d(poly, q) {
                return Some(*elem);
            }
            let n = poly.len() as f64;
            let cx = poly.iter().map(|p| p[0]).sum::<f64>() / n;
            let cy = poly.iter().map(|p| p[1]).sum::<f64>() / n;
            let d = (cx - q[0]).powi(2) + (cy - q[1]).powi(2);
            if nearest.is_none_or(|(bd, _)| d < bd) {
                nearest = Some((d, *elem));
            }
        }
        nearest.map(|(_, e)| e)
    }
}

fn cell_of(v: f64, min: f64, cell: f64, n: usize) -> usize {
    (((v - min) / cell).floor().max(0.0) as usize).min(n - 1)
}

/// Point in a convex 2D polygon of either orientation, with an edge tolerance relative to its size.
fn inside_2d(poly: &[[f64; 2]], q: [f64; 2]) -> bool {
    let n = poly.len();
    let mut area2 = 0.0;
    for k in 0..n {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        area2 += a[0] * b[1] - a[1] * b[0];
    }
    let sign = if area2 >= 0.0 { 1.0 } else { -1.0 };
    let scale = area2.abs();
    (0..n).all(|k| {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        let cross = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]);
        sign * cross >= -INSIDE_REL * scale
    })
}

/// What a picture shows: a solution's `elements` on `scene` (with its BVH), seen from
/// `camera`, `width` × `height` pixels.
#[derive(Clone, Copy)]
pub struct View<'a> {
    pub scene: &'a Scene,
    pub accel: &'a Accel,
    pub elements: &'a [SolvedElement],
    pub camera: Camera,
    pub width: usize,
    pub height: usize,
}

impl View<'_> {
    /// What every pixel sees (row-major from the top-left).
    #[must_use]
    pub fn hits(&self) -> Vec<PixelHit> {
        self.points().into_iter().map(|(hit, _)| hit).collect()
    }

    /// [`View::hits`] with the point each pixel's ray hits (the origin where it hits nothing).
    fn points(&self) -> Vec<(PixelHit, DVec3)> {
        let View { scene, accel, elements, camera, width: w, height: h } = *self;
        let locator = ElementLocator::new(scene, elements);
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let locator = &locator;
                (0..w).map(move |x| {
                    let (o, d) = camera.ray(x as f64, y as f64, w, h);
                    let Some((patch, t)) = accel.first_hit(o, d, u32::MAX) else {
                        return (PixelHit::Background, o);
                    };
                    let patch = patch as usize;
                    let at = o + d * t;
                    if scene.patches[patch].normal.dot(d) >= 0.0 {
                        return (PixelHit::BackFace, at);
                    }
                    (locator.locate(patch, at).map_or(PixelHit::NoElement, PixelHit::Element), at)
                })
            })
            .collect()
    }

    /// Render: each pixel gets `shade(element)` for the element it sees, or one of the flat
    /// colours [`BACKGROUND`], [`BACK_FACE`], [`NO_VALUE`].
    pub fn render(&self, shade: impl Fn(usize) -> [f32; 3] + Sync) -> Image {
        let hits = self.hits();
        let pixels = hits.par_iter().map(|h| flat_or(*h, &shade)).collect();
        Image { width: self.width, height: self.height, pixels }
    }

    /// Image of the radiosity B (each element's value with its slope at the pixel's point):
    /// linear, scaled so that the 99th percentile of the visible pixels' luminance is 1,
    /// clipped, sRGB-encoded. Also returns the exposure scale used.
    #[must_use]
    pub fn radiosity_image_with_exposure(&self) -> (Image, f64) {
        let elements = self.elements;
        let points = self.points();
        let hits: Vec<PixelHit> = points.iter().map(|(hit, _)| *hit).collect();
        let scale = exposure_of_hits(&hits, elements);
        // Each element's own reconstruction at the pixel's point (its value with its slope).
        let pixels = points
            .par_iter()
            .map(|&(hit, at)| {
                let shade = |e: usize| -> [f32; 3] {
                    let b = elements[e].radiosity_at(at);
                    if !b.is_finite() {
                        return NO_VALUE;
                    }
                    b.0.map(|c| srgb_encode(c * scale) as f32)
                };
                flat_or(hit, &shade)
            })
            .collect();
        (Image { width: self.width, height: self.height, pixels }, scale)
    }

    /// [`View::radiosity_image_with_exposure`] without the scale.
    #[must_use]
    pub fn radiosity_image(&self) -> Image {
        self.radiosity_image_with_exposure().0
    }

    /// The exposure scale [`View::radiosity_image`] uses, without shading an image: 1 over the
    /// 99th percentile of the visible pixels' luminance of B (1 if no pixel sees a lit
    /// element). `radlab solve --bake` uses it so that a bake looks like the `--png` of the
    /// same solve.
    #[must_use]
    pub fn auto_exposure(&self) -> f64 {
        exposure_of_hits(&self.hits(), self.elements)
    }

    /// Image of one value per element (`values[i]` for `elements[i]`) through `colormap`, with
    /// a colour bar along the bottom labelled with the range's min (left) and max (right).
    /// Non-finite values are drawn in [`NO_VALUE`].
    #[must_use]
    pub fn value_image(&self, values: &[f64], colormap: Colormap) -> Image {
        let (w, h) = (self.width, self.height);
        debug_assert_eq!(values.len(), self.elements.len(), "one value per element");
        let (lo, hi) = colormap.range(values);
        let span = if hi > lo { hi - lo } else { 1.0 };
        // The bar takes a band at the bottom when the image is tall enough to hold it.
        let band = if h >= 48 && w >= 48 { (h / 8).clamp(20, 64) } else { 0 };
        let view_h = h - band;
        let shade = |e: usize| -> [f32; 3] {
            match values.get(e) {
                Some(v) if v.is_finite() => colormap.at((v - lo) / span),
                _ => NO_VALUE,
            }
        };
        let view = View { height: view_h, ..*self }.render(shade);
        let mut img = Image::new(w, h, BACKGROUND);
        img.pixels[..w * view_h].copy_from_slice(&view.pixels);
        if band > 0 {
            draw_colorbar(&mut img, view_h, band, colormap, lo, hi);
        }
        img
    }
}

fn flat_or(hit: PixelHit, shade: &impl Fn(usize) -> [f32; 3]) -> [f32; 3] {
    match hit {
        PixelHit::Background => BACKGROUND,
        PixelHit::BackFace => BACK_FACE,
        PixelHit::NoElement => NO_VALUE,
        PixelHit::Element(e) => shade(e),
    }
}

/// sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
#[must_use]
pub fn srgb_encode(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

fn exposure_of_hits(hits: &[PixelHit], elements: &[SolvedElement]) -> f64 {
    let mut lum: Vec<f64> = hits
        .iter()
        .filter_map(|h| match h {
            PixelHit::Element(e) => Some(elements[*e].radiosity.luminance()),
            _ => None,
        })
        .filter(|l| l.is_finite())
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    let k = ((lum.len() - 1) as f64 * EXPOSURE_PERCENTILE).round() as usize;
    let (_, p, _) = lum.select_nth_unstable_by(k, f64::total_cmp);
    if *p > 0.0 { 1.0 / *p } else { 1.0 }
}

/// Colour maps for [`View::value_image`] (display-referred colours).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Colormap {
    /// Perceptually uniform, dark purple (min) → yellow (max) [van der Walt & Smith, matplotlib 2015].
    Viridis,
    /// Blue (−m) → light grey (0) → red (+m) with m = max |value|: for signed errors.
    Diverging,
}

#[allow(clippy::approx_constant)] // 0.318 is a sample of the colour map, not 1/π
const VIRIDIS: [[f32; 3]; 11] = [
    [0.267, 0.005, 0.329],
    [0.282, 0.141, 0.459],
    [0.255, 0.267, 0.529],
    [0.208, 0.373, 0.553],
    [0.165, 0.471, 0.557],
    [0.129, 0.569, 0.549],
    [0.133, 0.659, 0.518],
    [0.267, 0.749, 0.439],
    [0.478, 0.820, 0.318],
    [0.741, 0.875, 0.149],
    [0.992, 0.906, 0.145],
];
const DIVERGING: [[f32; 3]; 3] = [[0.230, 0.299, 0.754], [0.865, 0.865, 0.865], [0.706, 0.016, 0.150]];

impl Colormap {
    /// Colour at `t` ∈ [0, 1] (clamped), piecewise linear between the map's control points.
    #[must_use]
    pub fn at(self, t: f64) -> [f32; 3] {
        let table: &[[f32; 3]] = match self {
            Colormap::Viridis => &VIRIDIS,
            Colormap::Diverging => &DIVERGING,
        };
        let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
        let x = t * (table.len() - 1) as f64;
        let i = (x.floor() as usize).min(table.len() - 2);
        let f = (x - i as f64) as f32;
        [0, 1, 2].map(|c| table[i][c] + (table[i + 1][c] - table[i][c]) * f)
    }

    /// The value range the map spans for these values (finite ones only).
    #[must_use]
    pub fn range(self, values: &[f64]) -> (f64, f64) {
        let finite = values.iter().copied().filter(|v| v.is_finite());
        let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        if lo > hi {
            return (0.0, 1.0);
        }
        match self {
            Colormap::Viridis => (lo, hi),
            Colormap::Diverging => {
                let m = lo.abs().max(hi.abs());
                (-m, m)
            }
        }
    }
}

/// Colour bar in rows [top, top + band): a gradient strip, then min and max labels under it.
fn draw_colorbar(img: &mut Image, top: usize, band: usize, colormap: Colormap, lo: f64, hi: f64) {
    let margin = (band / 4).max(2);
    let strip_h = (band * 2 / 5).max(4);
    let (x0, x1) = (margin, img.width.saturating_sub(margin));
    for x in x0..x1 {
        let t = (x - x0) as f64 / (x1 - x0).saturating_sub(1).max(1) as f64;
        let c = colormap.at(t);
        for y in top + 2..top + 2 + strip_h {
            img.set(x, y, c);
        }
    }
    let scale = ((band - strip_h - 4) / 6).max(1);
    let text_y = top + 3 + strip_h + 1;
    let white = [0.95, 0.95, 0.95];
    draw_text(img, x0, text_y, scale, &format_value(lo), white);
    let max_text = format_value(hi);
    let width = text_width(&max_text, scale);
    draw_text(img, x1.saturating_sub(width), text_y, scale, &max_text, white);
}

/// A short label for a value: plain decimals for moderate magnitudes, else scientific.
#[must_use]
pub fn format_value(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.3e}")
    }
}

/// 3×5 glyphs, one row per 3 bits (MSB = left), top row first.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b001, 0b001, 0b001],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '+' => [0b000, 0b010, 0b111, 0b010, 0b000],
        'e' => [0b000, 0b111, 0b111, 0b100, 0b111],
        ' ' => [0; 5],
        _ => return None,
    })
}

fn text_width(s: &str, scale: usize) -> usize {
    s.chars().filter(|c| glyph(*c).is_some()).count() * 4 * scale
}

/// Draw `s` with its top-left at (x, y), each glyph pixel a `scale`×`scale` square.
fn draw_text(img: &mut Image, x: usize, y: usize, scale: usize, s: &str, color: [f32; 3]) {
    let mut cx = x;
    for ch in s.chars() {
        let Some(rows) = glyph(ch) else { continue };
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) != 0 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            img.set(cx + col * scale + dx, y + r * scale + dy, color);
                        }
                    }
                }
            }
        }
        cx += 4 * scale;
    }
}

/// Error image: each region coloured by its entry of `errors` (e.g. [`crate::eval::metrics::ErrorReport::per_element`],
/// the error relative to the scene's RMS reflected radiosity) through the viridis map, with a
/// colour bar, from `camera` — to sit next to the solution's own image.
#[must_use]
pub fn error_image(
    scene: &Scene,
    accel: &Accel,
    regions: &[crate::eval::reference::RefElement],
    errors: &[f64],
    camera: &Camera,
    width: usize,
    height: usize,
) -> Image {
    let elements: Vec<SolvedElement> = regions
        .iter()
        .map(|r| {
            let area = crate::math::polygon_area(&r.vertices);
            SolvedElement::constant(r.patch, r.vertices.clone(), area, crate::math::Rgb::ZERO)
        })
        .collect();
    let view = View { scene, accel, elements: &elements, camera: *camera, width, height };
    view.value_image(errors, Colormap::Viridis)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;
    use crate::scene::builtin;

    /// One element per patch with B = E (no solve needed to test the renderer).
    fn emission_elements(scene: &Scene) -> Vec<SolvedElement> {
        SolvedElement::whole_patches(scene, |i| scene.patches[i].emission + Rgb::splat(0.1 * i as f64))
    }

    /// Split every quad patch into n×n bilinear elements and every triangle 1→4 at its edge
    /// midpoints; element k gets B = k.
    fn split_elements(scene: &Scene, n: usize) -> Vec<SolvedElement> {
        let mut out = Vec::new();
        let mut push = |patch: usize, verts: Vec<DVec3>| {
            let (k, area) = (out.len(), crate::math::polygon_area(&verts));
            out.push(SolvedElement::constant(patch, verts, area, Rgb::splat(k as f64)));
        };
        for (i, p) in scene.patches.iter().enumerate() {
            let v = &p.vertices;
            if v.len() == 3 {
                let m = [0, 1, 2].map(|k| v[k].lerp(v[(k + 1) % 3], 0.5));
                push(i, vec![v[0], m[0], m[2]]);
                push(i, vec![m[0], v[1], m[1]]);
                push(i, vec![m[2], m[1], v[2]]);
                push(i, vec![m[0], m[1], m[2]]);
                continue;
            }
            let at = |s: f64, t: f64| v[0].lerp(v[1], s).lerp(v[3].lerp(v[2], s), t);
            let h = 1.0 / n as f64;
            for a in 0..n {
                for b in 0..n {
                    let (s, t) = (a as f64 * h, b as f64 * h);
                    push(i, vec![at(s, t), at(s + h, t), at(s + h, t + h), at(s, t + h)]);
                }
            }
        }
        out
    }

    /// A built-in scene, its BVH and elements on it.
    struct Fixture {
        scene: Scene,
        accel: Accel,
        elements: Vec<SolvedElement>,
    }

    impl Fixture {
        /// `name` with [`emission_elements`], or with [`split_elements`] `n` × `n` for `Some(n)`.
        fn new(name: &str, split: Option<usize>) -> Fixture {
            let scene = builtin::build(name).unwrap();
            let accel = Accel::build(&scene);
            let elements = split.map_or_else(|| emission_elements(&scene), |n| split_elements(&scene, n));
            Fixture { scene, accel, elements }
        }

        fn view(&self, camera: Camera, width: usize, height: usize) -> View<'_> {
            View { scene: &self.scene, accel: &self.accel, elements: &self.elements, camera, width, height }
        }
    }

    #[test]
    fn closed_rooms_are_seen_from_inside_open_scenes_from_outside() {
        let furnace = builtin::build("furnace").unwrap();
        let cam = Camera::for_scene(&furnace);
        let b = furnace.bounds();
        assert!(cam.eye.cmpgt(b.min).all() && cam.eye.cmplt(b.max).all(), "inside: {}", cam.eye);
        let perp = builtin::build("perpendicular").unwrap();
        let cam = Camera::for_scene(&perp);
        let b = perp.bounds();
        assert!(!(cam.eye.cmpgt(b.min).all() && cam.eye.cmplt(b.max).all()), "outside: {}", cam.eye);
        let cornell = builtin::build("cornell").unwrap();
        assert_eq!(Camera::for_scene(&cornell), Camera::from(cornell.camera.unwrap()));
        // Open scenes are framed so that the fronts of both squares show and no back face does.
        for name in ["parallel", "perpendicular"] {
            let f = Fixture::new(name, None);
            let hits = f.view(Camera::for_scene(&f.scene), 40, 30).hits();
            assert!(!hits.contains(&PixelHit::BackFace), "{name}: back face in the default view");
            assert!(hits.contains(&PixelHit::Element(0)) && hits.contains(&PixelHit::Element(1)), "{name}");
        }
    }

    #[test]
    fn every_pixel_of_a_closed_room_sees_a_front_face_element() {
        let f = Fixture::new("furnace", Some(2));
        let hits = f.view(Camera::for_scene(&f.scene), 40, 30).hits();
        assert!(hits.iter().all(|h| matches!(h, PixelHit::Element(_))), "{hits:?}");
        // The located element contains the hit point: its patch is the hit patch, and all four
        // quarters of several faces show up.
        let mut seen = std::collections::BTreeSet::new();
        for h in &hits {
            if let PixelHit::Element(e) = h {
                seen.insert(*e);
            }
        }
        assert!(seen.len() >= 8, "only {} distinct elements visible", seen.len());
    }

    #[test]
    fn element_lookup_matches_brute_force() {
        // 16×16 elements per quad (grids of 16×16 cells), triangles split 1→4.
        let Fixture { scene, accel, elements } = Fixture::new("cornell", Some(16));
        let cam = Camera::for_scene(&scene);
        // Hit points come from an f32 BVH in a frame where the scene's diagonal is 1.
        let hit_tol = 1e-5 * scene.bounds().diagonal();
        let (w, h) = (64, 64);
        let hits =
            View { scene: &scene, accel: &accel, elements: &elements, camera: cam, width: w, height: h }
                .hits();
        let mut checked = 0;
        for y in 0..h {
            for x in 0..w {
                let PixelHit::Element(e) = hits[y * w + x] else { continue };
                let (o, d) = cam.ray(x as f64, y as f64, w, h);
                let (patch, t) = accel.first_hit(o, d, u32::MAX).unwrap();
                assert_eq!(elements[e].patch, patch as usize);
                let p = o + d * t;
                let el = &elements[e];
                let n = scene.patches[el.patch].normal;
                let k = el.vertices.len();
                let outside = (0..k)
                    .map(|i| {
                        let (a, b) = (el.vertices[i], el.vertices[(i + 1) % k]);
                        -(b - a).cross(p - a).dot(n) / (b - a).length()
                    })
                    .fold(f64::NEG_INFINITY, f64::max);
                assert!(outside <= hit_tol, "pixel ({x}, {y}): hit point {outside} outside element {e}");
                checked += 1;
            }
        }
        assert!(checked > w * h / 2, "only {checked} pixels see an element");
    }

    #[test]
    fn backfaces_and_background_get_flat_colours() {
        let f = Fixture::new("parallel", None);
        // From below the bottom square (which faces up): its back is seen in the middle.
        let cam = Camera {
            eye: DVec3::new(0.5, -2.0, 0.5),
            target: DVec3::new(0.5, 0.0, 0.5),
            up: DVec3::Z,
            fov_y_deg: 40.0,
        };
        let img = f.view(cam, 21, 21).render(|_| [1.0, 1.0, 1.0]);
        assert_eq!(img.get(10, 10), BACK_FACE);
        assert_eq!(img.get(0, 0), BACKGROUND);
        // From between the squares looking up: the emitter's front.
        let cam = Camera {
            eye: DVec3::new(0.5, 0.5, 0.5),
            target: DVec3::new(0.5, 1.0, 0.5),
            up: DVec3::Z,
            fov_y_deg: 40.0,
        };
        let img = f.view(cam, 21, 21).render(|e| [e as f32, 0.0, 0.0]);
        assert_eq!(img.get(10, 10), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn radiosity_image_exposes_the_99th_percentile_to_white() {
        let mut f = Fixture::new("furnace", None);
        for e in &mut f.elements {
            e.radiosity = Rgb::splat(2.0);
        }
        let view = f.view(Camera::for_scene(&f.scene), 24, 16);
        let (img, scale) = view.radiosity_image_with_exposure();
        assert!((scale - 0.5).abs() < 1e-12);
        assert_eq!(view.auto_exposure(), scale);
        assert!(img.pixels.iter().all(|p| *p == [1.0, 1.0, 1.0]));
        assert!((srgb_encode(0.5) - 0.735_356_983_052_04).abs() < 1e-12);
    }

    #[test]
    fn rendering_is_identical_for_any_thread_count() {
        let f = Fixture::new("cornell", Some(2));
        let view = f.view(Camera::for_scene(&f.scene), 48, 40);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let a = one.install(|| view.radiosity_image());
        let b = three.install(|| view.radiosity_image());
        assert_eq!(a, b);
    }

    #[test]
    fn value_image_has_a_labelled_colour_bar() {
        let f = Fixture::new("cube-one-light", None);
        let values: Vec<f64> = (0..f.elements.len()).map(|i| i as f64 * 0.5).collect();
        let (w, h) = (96, 80);
        let img = f.view(Camera::for_scene(&f.scene), w, h).value_image(&values, Colormap::Viridis);
        let band = (h / 8).clamp(20, 64);
        let bar_y = h - band + 4;
        let margin = (band / 4).max(2);
        // The strip runs from the min colour (left) to the max colour (right).
        assert_eq!(img.get(margin, bar_y), Colormap::Viridis.at(0.0));
        assert_eq!(img.get(w - margin - 1, bar_y), Colormap::Viridis.at(1.0));
        // Labels are drawn: some near-white pixels below the strip.
        let label_px = (h - band / 2..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get(x, y)[0] > 0.9)
            .count();
        assert!(label_px > 10, "{label_px} label pixels");
        assert_eq!(format_value(2.5), "2.5");
        assert_eq!(format_value(0.0), "0");
        assert_eq!(format_value(1.5e-5), "1.500e-5");
        assert!(format_value(-123.456).starts_with("-123.456"));
    }

    #[test]
    fn png_round_trips_its_size() {
        let img = Image::new(7, 5, [0.5, 0.25, 1.0]);
        let path = std::env::temp_dir().join(format!("radlab-image-test-{}.png", std::process::id()));
        img.write_png(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert_eq!(&bytes[1..4], b"PNG");
        // IHDR width and height (big-endian) right after the signature and chunk header.
        assert_eq!(u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]), 7);
        assert_eq!(u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]), 5);
        assert_eq!(img.to_rgb8()[..3], [128, 64, 255]);
    }
}
