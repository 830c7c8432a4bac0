//! CPU-side display data for the viewer: shaded triangles, quadtree edges, links, the error
//! heatmap, colour scales and picking. Plain vertex and colour lists — no wgpu here, so all of it
//! is unit-tested headless; `render` only uploads what this module returns.
//!
//! ## What is drawn
//! - **Radiosity**: each leaf element's B (flat), or Gouraud-interpolated vertex values
//!   (smooth). Vertex values are the average of the leaves that share the vertex as a corner
//!   ("nodal averaging", Cohen & Wallace 1993, sec. 9.2.1); a vertex that lies inside a larger
//!   neighbour's edge (a *T-vertex*: the quadtree's midpoints between elements of different
//!   depth, anywhere along the edge in a BSP or graded discontinuity mesh) instead takes the
//!   value interpolated along that edge [Baum, Mann, Smith & Winget 1991], so the shading has no
//!   cracks:
//!
//!   ```text
//!   A ────────── B        value(M) = (1 − t) value(A) + t value(B),   t = |AM| / |AB|,
//!   │  big       │        longest edges first, repeated until no value changes,
//!   ├──────M─────┤        so a chain of T-vertices stays continuous.
//!   │ s1   │  s2 │
//!   ```
//! - **Conforming mesh**: each leaf is triangulated with the T-vertices on its edges (corners
//!   of finer neighbours, [`VertexField::boundary`]), so no cracks open along T-junctions.
//!   Across patches too: where two input patches meet along an edge (a wall and the floor, two
//!   faces of a box) each is refined on its own, so one side's corners lie inside the other
//!   side's edges. Those corners are inserted into the other side's boundary ([`Seams`]), and
//!   every corner takes one canonical position shared by all patches, so both sides of a seam
//!   draw the same vertices and the rasteriser leaves no background pixel between them.
//! - **Quadtree**: every leaf's edges, coloured by its depth below the input patch (the HSA91
//!   quadtree, Hanrahan, Salzman & Aupperle 1991, sec. 3). Drawn by the mesh shader from each
//!   vertex's position in its leaf's parameter square, so it costs no extra geometry; see
//!   `crate::render`.
//! - **Links**: a line between the centroids of receiver and source for each link
//!   (B_p gathers ρ_p F_pq V_pq B_q through it; lecture 17's p/q), coloured by log₁₀ F on a
//!   perceptual scale. Filters: one element's links, a minimum F, visibility class.
//! - **Error**: a per-element error value (the solver's own estimate, or the true error against a
//!   reference when one exists) on a log colour scale.

use crate::math::{DVec3, Rgb, polygon_centroid, polygon_normal};
use crate::solver::hierarchical::ClusterEnd;
use std::collections::HashMap;

/// One element as the viewer sees it (leaf or interior). `id` indexes the element list.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementView {
    pub id: u32,
    /// Input patch index.
    pub patch: u32,
    pub parent: Option<u32>,
    /// Depth below the input patch (0 = the patch itself).
    pub depth: u8,
    pub leaf: bool,
    /// `n_vertices` (3 or 4) valid entries, counter-clockwise seen from the front.
    pub vertices: [DVec3; 4],
    pub n_vertices: u8,
    pub area: f64,
    pub reflectance: Rgb,
    pub emission: Rgb,
    pub radiosity: Rgb,
    /// The solver's own error estimate for B (units of B); 0 where it has none.
    pub error_estimate: f64,
    /// Why refinement stopped at this element (a short label).
    pub stop: &'static str,
}

impl ElementView {
    /// The valid vertices (at most four, whatever `n_vertices` says).
    #[must_use]
    pub fn verts(&self) -> &[DVec3] {
        &self.vertices[..usize::from(self.n_vertices).min(4)]
    }
    /// Area centroid (the origin for an element without vertices).
    #[must_use]
    pub fn centroid(&self) -> DVec3 {
        let v = self.verts();
        if v.is_empty() { DVec3::ZERO } else { polygon_centroid(v) }
    }
    /// Unit normal (zero for an element without vertices or area).
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        let v = self.verts();
        if v.is_empty() { DVec3::ZERO } else { polygon_normal(v) }
    }
}

/// One link: the receiver gathers from the source (`ff` = F from receiver to source, `vis` ∈ \[0, 1\]).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LinkView {
    pub receiver: u32,
    pub source: u32,
    pub ff: f32,
    pub vis: f32,
}

impl ElementView {
    /// The viewer's copy of a solver element.
    #[must_use]
    pub fn from_info(e: &crate::solver::hierarchical::ElementInfo) -> ElementView {
        ElementView {
            id: e.id,
            patch: e.patch,
            parent: e.parent,
            depth: e.depth,
            leaf: e.children.is_none(),
            vertices: e.vertices,
            n_vertices: e.n_vertices,
            area: e.area,
            reflectance: e.reflectance,
            emission: e.emission,
            radiosity: e.radiosity,
            error_estimate: e.error_estimate,
            stop: e.stop.label(),
        }
    }
}

impl ElementView {
    /// A leaf of depth 0 without parent on input patch `patch_index` (a mesh solve's element, a
    /// reference region): the first four of `vertices` (3 or 4 expected) and the patch's
    /// material.
    #[must_use]
    pub fn flat_leaf(
        id: u32,
        patch_index: usize,
        patch: &crate::scene::Patch,
        vertices: &[DVec3],
        area: f64,
        radiosity: Rgb,
        error_estimate: f64,
        stop: &'static str,
    ) -> ElementView {
        let n = vertices.len().min(4);
        let mut v = [vertices.first().copied().unwrap_or(DVec3::ZERO); 4];
        v[..n].copy_from_slice(&vertices[..n]);
        ElementView {
            id,
            patch: patch_index as u32,
            parent: None,
            depth: 0,
            leaf: true,
            vertices: v,
            n_vertices: n as u8,
            area,
            reflectance: patch.reflectance,
            emission: patch.emission,
            radiosity,
            error_estimate,
            stop,
        }
    }
}

impl LinkView {
    /// The viewer's copy of a solver link.
    #[must_use]
    pub fn from_info(l: &crate::solver::hierarchical::LinkInfo) -> LinkView {
        LinkView { receiver: l.receiver, source: l.source, ff: l.ff, vis: l.vis }
    }
}

/// Visibility at or above `1 - VIS_CLASS_EPS` counts as "full", at or below as "none": the
/// visible fraction is a ray count ratio, so exact 0 and 1 are the natural classes.
pub const VIS_CLASS_EPS: f32 = 1e-6;

/// The visibility class of a link.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum VisClass {
    Full,
    Partial,
    None,
}

impl LinkView {
    #[must_use]
    pub fn class(&self) -> VisClass {
        if self.vis >= 1.0 - VIS_CLASS_EPS {
            VisClass::Full
        } else if self.vis <= VIS_CLASS_EPS {
            VisClass::None
        } else {
            VisClass::Partial
        }
    }
}

/// A line segment list: vertices in pairs, each with an RGBA colour (linear 0..1, display space).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LineList {
    pub points: Vec<DVec3>,
    pub colors: Vec<[f32; 4]>,
}

impl LineList {
    /// Add one segment.
    pub fn push(&mut self, a: DVec3, b: DVec3, color: [f32; 4]) {
        self.points.extend([a, b]);
        self.colors.extend([color, color]);
    }
    #[must_use]
    pub fn segments(&self) -> usize {
        self.points.len() / 2
    }
}

// ---------------------------------------------------------------------------------------------
// Colour scales

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

// ---------------------------------------------------------------------------------------------
// Smooth shading

/// Positions are merged when they agree to this fraction of the scene's diagonal: elements are
/// split at exact midpoints in f64, so shared corners agree to rounding (~1e-16 relative).
pub const MERGE_REL: f64 = 1e-9;

type Key = (u32, i64, i64, i64);

/// The `patch` of a [`Key`] that merges points of every patch.
const ANY_PATCH: u32 = u32::MAX;

struct Quantizer {
    origin: DVec3,
    inv: f64,
    /// The scene's bounding-box diagonal (1 for an empty or degenerate scene).
    diag: f64,
}

impl Quantizer {
    fn new(elements: &[ElementView]) -> Quantizer {
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
    fn key(&self, patch: u32, p: DVec3) -> Key {
        let q = (p - self.origin) * self.inv;
        (patch, q.x.round() as i64, q.y.round() as i64, q.z.round() as i64)
    }
}

/// Most anchoring passes (a chain of T-vertices hanging on each other takes one pass per link
/// when its edges are not longest-first; the quadtree's depth cap is 30).
const MAX_ANCHOR_PASSES: usize = 64;

/// An edge (its end keys, in key order) → the corners strictly inside it, as (t from the first
/// key's end, key), sorted by t.
type TVertices = HashMap<(Key, Key), Vec<(f64, Key)>>;

/// The leaves' corners, merged per input patch: a canonical position for each (so that every
/// leaf that shares a corner emits bit-identical coordinates) and the Gouraud value there
/// (nodal average; T-vertices anchored to the larger neighbour's edge, see the module docs).
pub struct VertexField {
    quant: Quantizer,
    /// Corner key → (canonical position, smooth radiosity).
    corners: HashMap<Key, (DVec3, Rgb)>,
    /// The T-vertices inside each leaf edge that has some.
    t_vertices: TVertices,
    seams: Seams,
}

/// A point on a leaf's boundary: a corner or a T-vertex, with its position in the leaf's
/// parameter square (quads: corners (0,0), (1,0), (1,1), (0,1); triangles: (0,0), (1,0), (0,1)).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct BoundaryPoint {
    pub position: DVec3,
    pub uv: [f64; 2],
    /// Smooth-shading value at the point.
    pub value: Rgb,
}

const QUAD_UV: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
const TRI_UV: [[f64; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];

impl VertexField {
    /// Merge the corners of `leaves` (indices into `elements`) and compute their values.
    #[must_use]
    pub fn build(elements: &[ElementView], leaves: &[u32]) -> VertexField {
        let quant = Quantizer::new(elements);
        // One canonical position per point, whatever the patch (the first leaf's, in leaf
        // order), so corners shared across a seam are bit-identical on both sides.
        let mut canonical: HashMap<Key, DVec3> = HashMap::with_capacity(leaves.len() * 2);
        for &l in leaves {
            for v in elements[l as usize].verts() {
                canonical.entry(quant.key(ANY_PATCH, *v)).or_insert(*v);
            }
        }
        let mut sums: HashMap<Key, (DVec3, Rgb, u32)> = HashMap::with_capacity(leaves.len() * 2);
        for &l in leaves {
            let e = &elements[l as usize];
            for v in e.verts() {
                let p = canonical.get(&quant.key(ANY_PATCH, *v)).copied().unwrap_or(*v);
                let s = sums.entry(quant.key(e.patch, *v)).or_insert((p, Rgb::ZERO, 0));
                s.1 += e.radiosity;
                s.2 += 1;
            }
        }
        let mut corners: HashMap<Key, (DVec3, Rgb)> =
            sums.into_iter().map(|(k, (p, s, n))| (k, (p, s / f64::from(n)))).collect();
        let t_vertices = find_t_vertices(&quant, &corners, elements, leaves);
        anchor(&mut corners, &t_vertices);
        let seams = Seams::build(elements, leaves, &quant, &canonical);
        VertexField { quant, corners, t_vertices, seams }
    }

    /// Canonical position and smooth value of a corner of a leaf on `patch`.
    #[must_use]
    pub fn corner(&self, patch: u32, p: DVec3) -> Option<(DVec3, Rgb)> {
        self.corners.get(&self.quant.key(patch, p)).copied()
    }

    /// The leaf's boundary, counter-clockwise like its vertices: each corner followed by the
    /// T-vertices on the edge to the next corner (corners of other leaves of the same patch that
    /// lie inside that edge: the quadtree's midpoints, anywhere in a BSP mesh). Triangulating
    /// this polygon instead of the bare corners makes the mesh conforming: no cracks where a
    /// large leaf meets subdivided neighbours.
    #[must_use]
    pub fn boundary(&self, e: &ElementView) -> Vec<BoundaryPoint> {
        let v = e.verts();
        let uv: &[[f64; 2]] = if v.len() == 4 { &QUAD_UV } else { &TRI_UV };
        let mut out = Vec::with_capacity(v.len() + 4);
        for i in 0..v.len() {
            let j = (i + 1) % v.len();
            let (pa, va) = self.corner(e.patch, v[i]).unwrap_or((v[i], e.radiosity));
            let start = out.len();
            out.push(BoundaryPoint { position: pa, uv: uv[i], value: va });
            self.inside_edge(e.patch, v[i], v[j], (uv[i], uv[j]), &mut out);
            if !self.seams.is_empty() {
                let (pb, vb) = self.corner(e.patch, v[j]).unwrap_or((v[j], e.radiosity));
                let end = BoundaryPoint { position: pb, uv: uv[j], value: vb };
                self.seams.insert(e.patch, v[i], v[j], &mut out, start, end);
            }
        }
        out
    }

    /// Push the T-vertices strictly inside the leaf edge a → b, in order from a, with their
    /// parameter coordinates along the edge (the parameter is linear along an edge of a
    /// triangle or a bilinear quad).
    fn inside_edge(
        &self,
        patch: u32,
        a: DVec3,
        b: DVec3,
        (ua, ub): ([f64; 2], [f64; 2]),
        out: &mut Vec<BoundaryPoint>,
    ) {
        let (ka, kb) = (self.quant.key(patch, a), self.quant.key(patch, b));
        let forward = ka < kb;
        let Some(inside) = self.t_vertices.get(&if forward { (ka, kb) } else { (kb, ka) }) else { return };
        let mut push = |&(t, k): &(f64, Key)| {
            let Some(&(position, value)) = self.corners.get(&k) else { return };
            let s = if forward { t } else { 1.0 - t };
            let uv = [ua[0] + s * (ub[0] - ua[0]), ua[1] + s * (ub[1] - ua[1])];
            out.push(BoundaryPoint { position, uv, value });
        };
        if forward {
            inside.iter().for_each(&mut push);
        } else {
            inside.iter().rev().for_each(&mut push);
        }
    }
}

/// Where input patches meet: pairs of collinear, overlapping patch edges of different patches,
/// and on each edge the leaf corners of its partner patches (projected onto it).
///
/// ```text
///   patch P (coarse)         ● a corner of a Q leaf on the shared edge, inside a P leaf's edge:
///  ┌────────────────┐        inserted into that P leaf's boundary (and every P corner into
///  ├───●────●───●───┤        Q's), so both sides of the seam rasterise the same edges
///  │ Q │    │   │   │
/// ```
///
/// Patch edges are the edges of the root elements (`parent == None`); without roots in the
/// element list there are no seams.
struct Seams {
    edges: Vec<SeamEdge>,
    /// Seam edges of each patch.
    by_patch: HashMap<u32, Vec<usize>>,
    /// Distance (scene units) within which a point is on an edge.
    tol: f64,
}

struct SeamEdge {
    a: DVec3,
    /// Unit direction a → b.
    dir: DVec3,
    len: f64,
    /// Partner patches' leaf corners on this edge: (parameter along `dir`, canonical position),
    /// sorted by parameter.
    points: Vec<(f64, DVec3)>,
}

impl SeamEdge {
    fn new(a: DVec3, b: DVec3) -> Option<SeamEdge> {
        let len = (b - a).length();
        (len > 0.0 && len.is_finite()).then(|| SeamEdge { a, dir: (b - a) / len, len, points: Vec::new() })
    }
    /// Parameter of `p` along the edge if `p` lies on it (within `tol`).
    fn param(&self, p: DVec3, tol: f64) -> Option<f64> {
        let w = p - self.a;
        let t = w.dot(self.dir);
        ((w - t * self.dir).length_squared() <= tol * tol && t >= -tol && t <= self.len + tol).then_some(t)
    }
}

/// Points are on a seam edge when within this fraction of the scene's diagonal of it: input
/// vertices stored as f32 (glTF) agree to ~1e-7 of the scene's size.
pub const SEAM_REL: f64 = 1e-6;

impl Seams {
    fn build(
        elements: &[ElementView],
        leaves: &[u32],
        quant: &Quantizer,
        canonical: &HashMap<Key, DVec3>,
    ) -> Seams {
        let tol = SEAM_REL * quant.diag;
        let mut edges: Vec<(u32, SeamEdge)> = Vec::new();
        for r in elements.iter().filter(|e| e.parent.is_none()) {
            let v = r.verts();
            for i in 0..v.len() {
                if let Some(edge) = SeamEdge::new(v[i], v[(i + 1) % v.len()]) {
                    edges.push((r.patch, edge));
                }
            }
        }
        // Pairs of collinear, overlapping edges of different patches (sweep over x).
        let lo_x = |e: &SeamEdge| e.a.x.min(e.a.x + e.dir.x * e.len);
        let hi_x = |e: &SeamEdge| e.a.x.max(e.a.x + e.dir.x * e.len);
        let mut order: Vec<usize> = (0..edges.len()).collect();
        order.sort_by(|&i, &j| lo_x(&edges[i].1).total_cmp(&lo_x(&edges[j].1)));
        let mut partners: Vec<Vec<usize>> = vec![Vec::new(); edges.len()];
        for (k, &i) in order.iter().enumerate() {
            let (pi, ei) = &edges[i];
            for &j in &order[k + 1..] {
                let (pj, ej) = &edges[j];
                if lo_x(ej) > hi_x(ei) + tol {
                    break;
                }
                if pi == pj {
                    continue;
                }
                let b = ej.a + ej.dir * ej.len;
                let collinear = |e: &SeamEdge, p: DVec3| {
                    let w = p - e.a;
                    (w - w.dot(e.dir) * e.dir).length_squared() <= tol * tol
                };
                if !(collinear(ei, ej.a) && collinear(ei, b)) {
                    continue;
                }
                let (t0, t1) = (ei.dir.dot(ej.a - ei.a), ei.dir.dot(b - ei.a));
                if t0.max(t1) > tol && t0.min(t1) < ei.len - tol {
                    partners[i].push(j);
                    partners[j].push(i);
                }
            }
        }
        let mut by_patch: HashMap<u32, Vec<usize>> = HashMap::new();
        for (i, (p, _)) in edges.iter().enumerate() {
            if !partners[i].is_empty() {
                by_patch.entry(*p).or_default().push(i);
            }
        }
        if by_patch.is_empty() {
            return Seams { edges: Vec::new(), by_patch, tol };
        }
        // Each seam edge's own leaf corners, then handed to its partners.
        let mut own: Vec<Vec<DVec3>> = vec![Vec::new(); edges.len()];
        for &l in leaves {
            let e = &elements[l as usize];
            let Some(seam) = by_patch.get(&e.patch) else { continue };
            for v in e.verts() {
                for &i in seam {
                    if edges[i].1.param(*v, tol).is_some() {
                        own[i].push(canonical.get(&quant.key(ANY_PATCH, *v)).copied().unwrap_or(*v));
                    }
                }
            }
        }
        for (i, pts) in own.iter().enumerate() {
            for &j in &partners[i] {
                let target = &edges[j].1;
                let mut add: Vec<(f64, DVec3)> =
                    pts.iter().filter_map(|p| target.param(*p, tol).map(|t| (t, *p))).collect();
                edges[j].1.points.append(&mut add);
            }
        }
        for (_, e) in &mut edges {
            e.points.sort_by(|a, b| a.0.total_cmp(&b.0));
            e.points.dedup_by(|a, b| (a.0 - b.0).abs() <= tol);
        }
        Seams { edges: edges.into_iter().map(|(_, e)| e).collect(), by_patch, tol }
    }

    fn is_empty(&self) -> bool {
        self.by_patch.is_empty()
    }

    /// Insert the partner corners strictly inside the leaf edge a → b of `patch` into
    /// `out[start..]` (the edge's start point and its own T-vertices, in order; `end` is the next
    /// corner), with parameter coordinates and smooth values interpolated along the edge.
    fn insert(
        &self,
        patch: u32,
        a: DVec3,
        b: DVec3,
        out: &mut Vec<BoundaryPoint>,
        start: usize,
        end: BoundaryPoint,
    ) {
        let Some(seam) = self.by_patch.get(&patch) else { return };
        for &i in seam {
            let edge = &self.edges[i];
            let (Some(ta), Some(tb)) = (edge.param(a, self.tol), edge.param(b, self.tol)) else { continue };
            // Strictly inside: more than `tol` from either end. A leaf edge no longer than
            // 2·tol along the seam (a sliver, a collapsed corner) has no inside.
            let (lo, hi) = (ta.min(tb) + self.tol, ta.max(tb) - self.tol);
            if !(lo < hi) {
                continue;
            }
            let first = edge.points.partition_point(|p| p.0 <= lo);
            let last = edge.points.partition_point(|p| p.0 < hi);
            let Some(inside) = edge.points.get(first..last).filter(|s| !s.is_empty()) else { continue };
            // Fraction along a → b of each point already there, and of the new ones.
            let len = (b - a).length();
            let s_of = |p: DVec3| (p - a).dot(b - a) / (len * len);
            let mut own: Vec<(f64, BoundaryPoint)> =
                out[start..].iter().map(|p| (s_of(p.position), *p)).collect();
            own.push((1.0, end));
            let mut merged: Vec<BoundaryPoint> = Vec::with_capacity(own.len() + inside.len());
            let mut k = 0; // own[k] is the next own point at or after the current position
            let points: Box<dyn Iterator<Item = &(f64, DVec3)>> =
                if ta <= tb { Box::new(inside.iter()) } else { Box::new(inside.iter().rev()) };
            for &(_, p) in points {
                let s = s_of(p);
                while k < own.len() && own[k].0 <= s {
                    if k + 1 < own.len() {
                        merged.push(own[k].1);
                    }
                    k += 1;
                }
                // Skip points that coincide with one already there (same canonical position).
                let near = |q: &BoundaryPoint| (q.position - p).length_squared() <= self.tol * self.tol;
                if merged.last().is_some_and(near) || own.get(k).is_some_and(|q| near(&q.1)) {
                    continue;
                }
                let (Some(prev), Some(next)) = (k.checked_sub(1).map(|i| own[i]), own.get(k).copied()) else {
                    continue;
                };
                let f =
                    if next.0 > prev.0 { ((s - prev.0) / (next.0 - prev.0)).clamp(0.0, 1.0) } else { 0.0 };
                let lerp2 = |x: [f64; 2], y: [f64; 2]| [x[0] + f * (y[0] - x[0]), x[1] + f * (y[1] - x[1])];
                merged.push(BoundaryPoint {
                    position: p,
                    uv: lerp2(prev.1.uv, next.1.uv),
                    value: prev.1.value + (next.1.value - prev.1.value) * f,
                });
            }
            while k + 1 < own.len() {
                merged.push(own[k].1);
                k += 1;
            }
            out.truncate(start);
            out.extend(merged);
        }
    }
}

/// Radiosity at each corner of each leaf in `leaves` (indices into `elements`), for Gouraud
/// shading: nodal averages within each input patch, T-vertices anchored to the larger
/// neighbour's edge (see the module docs). Entries past `n_vertices` are zero.
#[must_use]
pub fn vertex_radiosity(elements: &[ElementView], leaves: &[u32]) -> Vec<[Rgb; 4]> {
    let field = VertexField::build(elements, leaves);
    leaves
        .iter()
        .map(|&l| {
            let e = &elements[l as usize];
            let mut out = [Rgb::ZERO; 4];
            for (o, v) in out.iter_mut().zip(e.verts()) {
                *o = field.corner(e.patch, *v).map_or(e.radiosity, |c| c.1);
            }
            out
        })
        .collect()
}

/// Every leaf edge with corners of the same patch strictly inside it (within 4 quanta of it),
/// keyed by its end keys in key order, each list sorted by t from the first key's end.
fn find_t_vertices(
    quant: &Quantizer,
    corners: &HashMap<Key, (DVec3, Rgb)>,
    elements: &[ElementView],
    leaves: &[u32],
) -> TVertices {
    let mut by_patch: HashMap<u32, Vec<(Key, DVec3)>> = HashMap::new();
    for (k, (p, _)) in corners {
        by_patch.entry(k.0).or_default().push((*k, *p));
    }
    let grids: HashMap<u32, crate::eval::reconstruction::BucketGrid<Key>> = by_patch
        .into_iter()
        .map(|(patch, v)| (patch, crate::eval::reconstruction::BucketGrid::new(v)))
        .collect();
    let tol = 4.0 * quant.diag * MERGE_REL;
    let mut out = TVertices::new();
    let mut seen = std::collections::HashSet::new();
    for &l in leaves {
        let e = &elements[l as usize];
        let Some(grid) = grids.get(&e.patch) else { continue };
        let v = e.verts();
        for i in 0..v.len() {
            let (ka, kb) = (quant.key(e.patch, v[i]), quant.key(e.patch, v[(i + 1) % v.len()]));
            if ka == kb || !seen.insert(if ka < kb { (ka, kb) } else { (kb, ka) }) {
                continue;
            }
            let (a, b) = (corners[&ka].0, corners[&kb].0);
            let (key, from, to) = if ka < kb { ((ka, kb), a, b) } else { ((kb, ka), b, a) };
            let mut inside = grid.on_segment(from, to, tol, |k| k != ka && k != kb);
            if !inside.is_empty() {
                inside.sort_by(|x, y| x.0.total_cmp(&y.0));
                out.insert(key, inside);
            }
        }
    }
    out
}

/// Give every T-vertex the value interpolated along the edge it lies inside, longest edges
/// first, repeated until nothing changes (an end point may hang on another edge in turn).
fn anchor(corners: &mut HashMap<Key, (DVec3, Rgb)>, t_vertices: &TVertices) {
    // (length, end keys, T-vertices inside)
    let mut edges: Vec<_> =
        t_vertices.iter().map(|(k, inside)| (corners[&k.0].0.distance(corners[&k.1].0), k, inside)).collect();
    edges.sort_by(|x, y| y.0.total_cmp(&x.0).then_with(|| x.1.cmp(y.1)));
    for _ in 0..MAX_ANCHOR_PASSES {
        let mut changed = false;
        for (_, (ka, kb), inside) in &edges {
            let (va, vb) = (corners[ka].1, corners[kb].1);
            for &(t, k) in *inside {
                if let Some(c) = corners.get_mut(&k) {
                    let new = va * (1.0 - t) + vb * t;
                    changed |= new != c.1;
                    c.1 = new;
                }
            }
        }
        if !changed {
            break;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Overlays

/// Default decimation of the links overlay: beyond a few thousand lines a room is a solid
/// fan of lines.
pub const DEFAULT_MAX_LINKS: usize = 3000;

/// How the links overlay thins out when more links pass the filter than `max_lines`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Decimation {
    /// Every k-th link in receiver order: a representative sample of the whole hierarchy.
    Strided,
    /// The largest form factors (often the tiny elements along shared corners).
    LargestF,
}

/// Which links to draw.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LinkFilter {
    /// Only the links this element gathers through: those whose receiver is the element or one
    /// of its ancestors (an element also gathers through the links of the elements above it).
    /// The links it shoots through (it as source) are the reverse links of other elements.
    pub element: Option<u32>,
    pub min_ff: f32,
    pub full: bool,
    pub partial: bool,
    pub none: bool,
    /// Decimation: at most this many lines, chosen by `decimation`.
    pub max_lines: usize,
    pub decimation: Decimation,
}

impl Default for LinkFilter {
    fn default() -> Self {
        LinkFilter {
            element: None,
            min_ff: 0.0,
            full: true,
            partial: true,
            none: false,
            max_lines: DEFAULT_MAX_LINKS,
            decimation: Decimation::Strided,
        }
    }
}

/// Link lines and what was kept.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkLines {
    pub lines: LineList,
    /// Links passing the filter.
    pub matched: usize,
    /// Links drawn (after decimation).
    pub shown: usize,
    /// The colour scale of F over the matched links.
    pub scale: Option<LogScale>,
}

/// The element and its ancestors (an element gathers through its own links and its ancestors').
#[must_use]
pub fn ancestors(elements: &[ElementView], id: u32) -> Vec<u32> {
    let mut out = vec![id];
    let mut cur = elements.get(id as usize).and_then(|e| e.parent);
    while let Some(p) = cur {
        if out.len() > 64 {
            break; // a cycle would be a solver bug; never loop forever on display
        }
        out.push(p);
        cur = elements.get(p as usize).and_then(|e| e.parent);
    }
    out
}

/// Lines between link endpoints' centroids, coloured by log₁₀ F (viridis), `alpha` each.
#[must_use]
pub fn link_lines(
    elements: &[ElementView],
    links: &[LinkView],
    filter: &LinkFilter,
    alpha: f32,
) -> LinkLines {
    let chain = filter.element.map(|id| ancestors(elements, id));
    let mut kept: Vec<&LinkView> = links
        .iter()
        .filter(|l| {
            (l.receiver as usize) < elements.len()
                && (l.source as usize) < elements.len()
                && l.ff >= filter.min_ff
                && match l.class() {
                    VisClass::Full => filter.full,
                    VisClass::Partial => filter.partial,
                    VisClass::None => filter.none,
                }
                && chain.as_ref().is_none_or(|c| c.contains(&l.receiver))
        })
        .collect();
    let matched = kept.len();
    let scale = LogScale::spanning(kept.iter().map(|l| f64::from(l.ff)));
    if kept.len() > filter.max_lines {
        match filter.decimation {
            Decimation::LargestF => {
                kept.sort_by(|a, b| {
                    b.ff.total_cmp(&a.ff).then(a.receiver.cmp(&b.receiver)).then(a.source.cmp(&b.source))
                });
                kept.truncate(filter.max_lines);
            }
            Decimation::Strided => {
                let stride = kept.len().div_ceil(filter.max_lines.max(1));
                kept = kept.into_iter().step_by(stride).collect();
            }
        }
    }
    let mut lines = LineList::default();
    for l in &kept {
        let t = scale.map_or(0.0, |s| s.t(f64::from(l.ff)));
        let [r, g, b] = Palette::Viridis.at(t);
        lines.push(
            elements[l.receiver as usize].centroid(),
            elements[l.source as usize].centroid(),
            [r, g, b, alpha],
        );
    }
    LinkLines { shown: kept.len(), lines, matched, scale }
}

/// Each cluster link is drawn as this many dashes (with as many gaps), so it reads apart from
/// the element links' solid lines.
pub const CLUSTER_LINK_DASHES: usize = 6;

/// Dashed lines between the two ends' centres of the cluster links (clustered solves) that pass
/// `filter`'s minimum F and visibility classes, coloured by log₁₀ F on `scale`
/// (the element links' scale, so both read on one colour bar; `None`: the cluster links' own),
/// at most `filter.max_lines` of them, taken in the order given (the viewer keeps them largest
/// F first). `picked`, when given, keeps only the links with an end among those nodes: the
/// picked element's patch and the clusters holding it ([`cluster_chain`]), whose links the
/// element gathers through (`filter.element` itself names an element, not a cluster).
#[must_use]
pub fn cluster_link_lines(
    links: &[crate::solver::hierarchical::ClusterLinkView],
    filter: &LinkFilter,
    picked: Option<&[ClusterEnd]>,
    scale: Option<LogScale>,
    alpha: f32,
) -> LinkLines {
    let class = |vis: f32| LinkView { receiver: 0, source: 0, ff: 0.0, vis }.class();
    let kept: Vec<_> = links
        .iter()
        .filter(|l| {
            picked.is_none_or(|on| l.ends.iter().any(|e| on.contains(e)))
                && l.ff >= f64::from(filter.min_ff)
                && match class(l.vis) {
                    VisClass::Full => filter.full,
                    VisClass::Partial => filter.partial,
                    VisClass::None => filter.none,
                }
        })
        .collect();
    let matched = kept.len();
    let scale = scale.or_else(|| LogScale::spanning(kept.iter().map(|l| l.ff)));
    let mut lines = LineList::default();
    for l in kept.iter().take(filter.max_lines) {
        let [r, g, b] = Palette::Viridis.at(scale.map_or(0.0, |s| s.t(l.ff)));
        let at = |k: usize| l.from.lerp(l.to, k as f64 / (2 * CLUSTER_LINK_DASHES - 1) as f64);
        for dash in 0..CLUSTER_LINK_DASHES {
            lines.push(at(2 * dash), at(2 * dash + 1), [r, g, b, alpha]);
        }
    }
    LinkLines { shown: matched.min(filter.max_lines), lines, matched, scale }
}

/// The cluster-link ends an element of input patch `patch` gathers through: the patch itself,
/// then the clusters holding it, smallest first (`clusters` and `patch_cluster` as
/// [`crate::solver::hierarchical::Snapshot`] has them; only the patch when it has none).
#[must_use]
pub fn cluster_chain(
    clusters: &[crate::solver::hierarchical::ClusterInfo],
    patch_cluster: &[u32],
    patch: u32,
) -> Vec<ClusterEnd> {
    let mut chain = vec![ClusterEnd::Patch(patch)];
    let mut at = patch_cluster.get(patch as usize).copied().filter(|&c| c != u32::MAX);
    while let Some(i) = at {
        chain.push(ClusterEnd::Cluster(i));
        at = clusters.get(i as usize).and_then(|c| c.parent);
    }
    chain
}

/// The twelve edges of every cluster's bounding box whose depth is in `depths` (inclusive),
/// coloured by depth (viridis over the range shown): the cluster overlay.
#[must_use]
pub fn cluster_lines(
    clusters: &[crate::solver::hierarchical::ClusterInfo],
    depths: std::ops::RangeInclusive<u8>,
    alpha: f32,
) -> LineList {
    let mut lines = LineList::default();
    let span = f64::from(depths.end().saturating_sub(*depths.start()).max(1));
    for c in clusters.iter().filter(|c| depths.contains(&c.depth)) {
        let t = f64::from(c.depth - depths.start()) / span;
        let [r, g, b] = Palette::Viridis.at(t);
        let corner = |k: usize| {
            DVec3::new(
                if k & 1 == 0 { c.bmin.x } else { c.bmax.x },
                if k & 2 == 0 { c.bmin.y } else { c.bmax.y },
                if k & 4 == 0 { c.bmin.z } else { c.bmax.z },
            )
        };
        // Corners differing in one bit share an edge.
        for k in 0..8 {
            for bit in [1, 2, 4] {
                if k & bit == 0 {
                    lines.push(corner(k), corner(k | bit), [r, g, b, alpha]);
                }
            }
        }
    }
    lines
}

/// Heatmap colours of per-element error values (indexed like `values`) on a robust log scale
/// ([`LogScale::robust`]); zero or negative error gets the scale's bottom colour.
#[must_use]
pub fn heatmap_colors(values: &[f64]) -> (Vec<[f32; 3]>, Option<LogScale>) {
    let scale = LogScale::robust(values.iter().copied());
    let colors = values.iter().map(|&v| Palette::Heat.at(scale.map_or(0.0, |s| s.t(v)))).collect();
    (colors, scale)
}

// ---------------------------------------------------------------------------------------------
// Hover highlight

/// What the viewer highlights in 3-D and in the blocking matrix: one link (a block of the
/// matrix hovered) or one element (hovered or picked in the viewport).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Highlight {
    /// Receiver p gathers from source q.
    Link {
        receiver: u32,
        source: u32,
    },
    Element(u32),
}

/// Outline colour of a highlighted receiver (orange).
pub const HIGHLIGHT_RECEIVER: [f32; 4] = [1.0, 0.55, 0.1, 1.0];
/// Outline colour of a highlighted source (cyan).
pub const HIGHLIGHT_SOURCE: [f32; 4] = [0.2, 0.85, 1.0, 1.0];
/// Colour of a highlighted link's line.
pub const HIGHLIGHT_LINK: [f32; 4] = [1.0, 1.0, 1.0, 1.0];

/// The lines of a highlight: each element's outline (receiver orange, source cyan, a lone
/// element orange), then for a link the line between the two centroids (white). Ids outside
/// `elements` draw nothing.
#[must_use]
pub fn highlight_lines(elements: &[ElementView], h: Highlight) -> LineList {
    let mut out = LineList::default();
    let mut outline = |id: u32, color: [f32; 4]| {
        let Some(e) = elements.get(id as usize) else { return false };
        let v = e.verts();
        for i in 0..v.len() {
            out.push(v[i], v[(i + 1) % v.len()], color);
        }
        true
    };
    match h {
        Highlight::Element(id) => {
            outline(id, HIGHLIGHT_RECEIVER);
        }
        Highlight::Link { receiver, source } => {
            if outline(receiver, HIGHLIGHT_RECEIVER) & outline(source, HIGHLIGHT_SOURCE) {
                let (r, s) = (&elements[receiver as usize], &elements[source as usize]);
                out.push(r.centroid(), s.centroid(), HIGHLIGHT_LINK);
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Picking

/// Relative tolerance of the inside test (fraction of the element's edge length), so a ray
/// through a shared edge hits one of the two elements.
const PICK_EDGE_EPS: f64 = 1e-9;

/// The nearest leaf hit by the ray `origin + t·dir` (t > 0), either side; `(id, t)`.
#[must_use]
pub fn pick(elements: &[ElementView], leaves: &[u32], origin: DVec3, dir: DVec3) -> Option<(u32, f64)> {
    let mut best: Option<(u32, f64)> = None;
    for &l in leaves {
        let e = &elements[l as usize];
        let v = e.verts();
        if v.len() < 3 {
            continue;
        }
        let n = e.normal();
        let denom = n.dot(dir);
        if denom.abs() < 1e-300 {
            continue;
        }
        let t = n.dot(v[0] - origin) / denom;
        if t.is_nan() || t <= 0.0 || best.is_some_and(|(_, bt)| t >= bt) {
            continue;
        }
        let p = origin + dir * t;
        let inside = (0..v.len()).all(|i| {
            let a = v[i];
            let b = v[(i + 1) % v.len()];
            let edge = b - a;
            edge.cross(p - a).dot(n) >= -PICK_EDGE_EPS * edge.length_squared()
        });
        if inside {
            best = Some((e.id, t));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cluster_boxes_draw_twelve_edges_in_the_depths_asked_for() {
        use crate::solver::hierarchical::ClusterInfo;
        let c = |depth: u8, lo: f64| ClusterInfo {
            depth,
            bmin: DVec3::splat(lo),
            bmax: DVec3::splat(lo + 1.0),
            patches: 2,
            links: 0,
            parent: None,
        };
        let clusters = [c(0, 0.0), c(1, 2.0), c(2, 4.0), c(2, 6.0)];
        let all = cluster_lines(&clusters, 0..=2, 1.0);
        assert_eq!(all.segments(), 4 * 12);
        // Every edge is axis-aligned and one box side long.
        for seg in all.points.chunks(2) {
            let d = (seg[1] - seg[0]).abs();
            assert!((d.x + d.y + d.z - 1.0).abs() < 1e-12 && d.max_element() == 1.0, "{seg:?}");
        }
        let deep = cluster_lines(&clusters, 2..=2, 1.0);
        assert_eq!(deep.segments(), 2 * 12);
        assert!(deep.points.iter().all(|p| p.x >= 4.0));
        // Colour by depth: the root and the deepest level differ.
        assert_ne!(all.colors[0], all.colors[all.colors.len() - 1]);
    }

    #[test]
    fn highlight_outlines_both_elements_and_draws_the_link() {
        let e = vec![quad(0, 0, 0.0, 0.0, 1.0, 0.5), quad(1, 0, 2.0, 0.0, 1.0, 0.5)];
        let l = highlight_lines(&e, Highlight::Link { receiver: 0, source: 1 });
        assert_eq!(l.segments(), 4 + 4 + 1, "two quads' edges and the link");
        assert_eq!(l.colors[0], HIGHLIGHT_RECEIVER);
        assert_eq!(l.colors[8], HIGHLIGHT_SOURCE);
        let n = l.points.len();
        assert_eq!((l.points[n - 2], l.points[n - 1]), (e[0].centroid(), e[1].centroid()));
        assert_eq!(l.colors[n - 1], HIGHLIGHT_LINK);
        assert_eq!(highlight_lines(&e, Highlight::Element(1)).segments(), 4);
        assert_eq!(
            highlight_lines(&e, Highlight::Link { receiver: 0, source: 7 }).segments(),
            4,
            "no link line to a missing element"
        );
    }

    fn quad(id: u32, depth: u8, x0: f64, y0: f64, s: f64, b: f64) -> ElementView {
        ElementView {
            id,
            patch: 0,
            parent: None,
            depth,
            leaf: true,
            vertices: [
                DVec3::new(x0, y0, 0.0),
                DVec3::new(x0 + s, y0, 0.0),
                DVec3::new(x0 + s, y0 + s, 0.0),
                DVec3::new(x0, y0 + s, 0.0),
            ],
            n_vertices: 4,
            area: s * s,
            reflectance: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            radiosity: Rgb::splat(b),
            error_estimate: 0.0,
            stop: "",
        }
    }

    /// Exact for values that are sums of a few halves; only rounding remains.
    const EXACT: f64 = 1e-12;

    #[test]
    fn nodal_average_of_a_regular_grid() {
        // Two unit squares side by side: the shared edge's corners average both.
        let els = vec![quad(0, 0, 0.0, 0.0, 1.0, 1.0), quad(1, 0, 1.0, 0.0, 1.0, 3.0)];
        let v = vertex_radiosity(&els, &[0, 1]);
        assert!((v[0][0].r() - 1.0).abs() < EXACT); // outer corner: only element 0
        assert!((v[0][1].r() - 2.0).abs() < EXACT); // shared corner (1,0): mean of 1 and 3
        assert!((v[1][0].r() - 2.0).abs() < EXACT);
        assert!((v[1][1].r() - 3.0).abs() < EXACT);
    }

    #[test]
    fn t_vertex_takes_the_big_edge_interpolation() {
        // A big 2×2 square on the left; on the right two 1×1 squares stacked: the point (2,1) is a
        // T-vertex on the big square's right edge.
        let els = vec![
            quad(0, 1, 0.0, 0.0, 2.0, 10.0),
            quad(1, 2, 2.0, 0.0, 1.0, 0.0),
            quad(2, 2, 2.0, 1.0, 1.0, 4.0),
        ];
        let v = vertex_radiosity(&els, &[0, 1, 2]);
        // Corners of the big edge: (2,0) = mean(10, 0) = 5; (2,2) = mean(10, 4) = 7.
        assert!((v[0][1].r() - 5.0).abs() < EXACT);
        assert!((v[0][2].r() - 7.0).abs() < EXACT);
        // The T-vertex (2,1) is corner 3 of element 1 and corner 0 of element 2: it must be the
        // midpoint of 5 and 7 (not the nodal mean of 0 and 4), so the shading has no crack.
        assert!((v[1][3].r() - 6.0).abs() < EXACT, "got {}", v[1][3].r());
        assert!((v[2][0].r() - 6.0).abs() < EXACT);
    }

    #[test]
    fn patches_do_not_share_vertices() {
        let mut b = quad(1, 0, 1.0, 0.0, 1.0, 3.0);
        b.patch = 1;
        let els = vec![quad(0, 0, 0.0, 0.0, 1.0, 1.0), b];
        let v = vertex_radiosity(&els, &[0, 1]);
        assert!((v[0][1].r() - 1.0).abs() < EXACT);
        assert!((v[1][0].r() - 3.0).abs() < EXACT);
    }

    #[test]
    fn boundary_has_the_t_vertices_of_finer_neighbours() {
        // A 2×2 square on the left; on its right a unit square below, and four half-unit squares
        // above: T-vertices (2,1) and (2,1.5) on the big square's right edge.
        let els = vec![
            quad(0, 1, 0.0, 0.0, 2.0, 10.0),
            quad(1, 2, 2.0, 0.0, 1.0, 0.0),
            quad(2, 3, 2.0, 1.0, 0.5, 4.0),
            quad(3, 3, 2.0, 1.5, 0.5, 4.0),
            quad(4, 3, 2.5, 1.0, 0.5, 4.0),
            quad(5, 3, 2.5, 1.5, 0.5, 4.0),
        ];
        let leaves: Vec<u32> = (0..6).collect();
        let f = VertexField::build(&els, &leaves);
        let b = f.boundary(&els[0]);
        let pts: Vec<[f64; 2]> = b.iter().map(|p| [p.position.x, p.position.y]).collect();
        assert_eq!(pts, vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 1.5], [2.0, 2.0], [0.0, 2.0]]);
        // Parameter coordinates run along the right edge (u = 1).
        assert_eq!(b[2].uv, [1.0, 0.5]);
        assert_eq!(b[3].uv, [1.0, 0.75]);
        // The unit square has one T-vertex, (2.5,1), on its top edge; a half-unit square none.
        assert_eq!(f.boundary(&els[1]).len(), 5);
        assert_eq!(f.boundary(&els[2]).len(), 4);
        // A different patch's corners are not T-vertices unless the patches meet along the edge
        // (see `boundary_has_the_corners_of_the_neighbouring_patch`): here patch 1's elements have
        // a parent that is not in the list, so there are no patch edges to share.
        let mut other = els.clone();
        for e in &mut other[1..] {
            e.patch = 1;
            e.parent = Some(0);
        }
        assert_eq!(VertexField::build(&other, &leaves).boundary(&other[0]).len(), 4);
    }

    #[test]
    fn boundary_has_the_corners_of_the_neighbouring_patch() {
        // Patch 0: one 2×2 leaf (its own root). Patch 1 on its right: a root split into four, so
        // its corner (2,1) lies inside patch 0's right edge, and (2,1.5) of a finer leaf too.
        let mut root = quad(1, 0, 2.0, 0.0, 2.0, 0.0);
        root.patch = 1;
        root.leaf = false;
        let mut els = vec![quad(0, 0, 0.0, 0.0, 2.0, 10.0), root];
        for (x, y, s) in [(2.0, 0.0, 1.0), (3.0, 0.0, 1.0), (3.0, 1.0, 1.0), (2.0, 1.0, 0.5), (2.5, 1.0, 0.5)]
        {
            let mut e = quad(els.len() as u32, 1, x, y, s, 4.0);
            e.patch = 1;
            e.parent = Some(1);
            els.push(e);
        }
        for (x, y) in [(2.0, 1.5), (2.5, 1.5)] {
            let mut e = quad(els.len() as u32, 2, x, y, 0.5, 4.0);
            e.patch = 1;
            e.parent = Some(1);
            els.push(e);
        }
        let leaves: Vec<u32> = (0..els.len() as u32).filter(|&i| i != 1).collect();
        let f = VertexField::build(&els, &leaves);
        let b = f.boundary(&els[0]);
        let pts: Vec<[f64; 2]> = b.iter().map(|p| [p.position.x, p.position.y]).collect();
        assert_eq!(pts, vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 1.5], [2.0, 2.0], [0.0, 2.0]]);
        // Interpolated along the edge: parameters on u = 1, values those of patch 0's own corners
        // (its only leaf: 10 everywhere), not patch 1's.
        assert_eq!(b[2].uv, [1.0, 0.5]);
        assert_eq!(b[3].uv, [1.0, 0.75]);
        assert!(b.iter().all(|p| (p.value.r() - 10.0).abs() < EXACT), "{b:?}");
        // Patch 1's leaf at (2,0): its own T-vertex (2.5,1) only (its edge x = 2 from y = 1 to 0
        // holds no corner of patch 0).
        let b2: Vec<[f64; 2]> = f.boundary(&els[2]).iter().map(|p| [p.position.x, p.position.y]).collect();
        assert_eq!(b2, vec![[2.0, 0.0], [3.0, 0.0], [3.0, 1.0], [2.5, 1.0], [2.0, 1.0]]);
        // Without roots there are no seams.
        let no_roots: Vec<ElementView> = els
            .iter()
            .cloned()
            .map(|mut e| {
                e.parent = Some(0);
                e
            })
            .collect();
        assert_eq!(VertexField::build(&no_roots, &leaves).boundary(&no_roots[0]).len(), 4);
    }

    fn links() -> Vec<LinkView> {
        vec![
            LinkView { receiver: 0, source: 1, ff: 0.2, vis: 1.0 },
            LinkView { receiver: 1, source: 0, ff: 0.002, vis: 0.5 },
            LinkView { receiver: 2, source: 1, ff: 0.02, vis: 0.0 },
        ]
    }

    #[test]
    fn link_filter_and_log_colours() {
        let els = vec![
            quad(0, 0, 0.0, 0.0, 1.0, 1.0),
            quad(1, 0, 1.0, 0.0, 1.0, 1.0),
            quad(2, 0, 2.0, 0.0, 1.0, 1.0),
        ];
        let all = LinkFilter { none: true, ..LinkFilter::default() };
        let r = link_lines(&els, &links(), &all, 1.0);
        assert_eq!((r.matched, r.shown), (3, 3));
        let s = r.scale.unwrap();
        assert!((s.lo - 0.002).abs() < 1e-9 && (s.hi - 0.2).abs() < 1e-7);
        // Largest F gets the top colour, smallest the bottom one.
        assert_eq!(r.lines.colors[0][..3], Palette::Viridis.at(1.0));
        assert_eq!(r.lines.colors[2][..3], Palette::Viridis.at(0.0));
        // Default filter hides invisible links.
        assert_eq!(link_lines(&els, &links(), &LinkFilter::default(), 1.0).matched, 2);
        // Minimum F and element filters.
        let f = LinkFilter { min_ff: 0.01, none: true, ..LinkFilter::default() };
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 2);
        let f = LinkFilter { element: Some(2), none: true, ..LinkFilter::default() };
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 1);
        // Decimation: the strongest, or every k-th.
        let f = LinkFilter {
            max_lines: 1,
            none: true,
            decimation: Decimation::LargestF,
            ..LinkFilter::default()
        };
        let r = link_lines(&els, &links(), &f, 1.0);
        assert_eq!((r.matched, r.shown), (3, 1));
        assert!((r.lines.points[0].x - 0.5).abs() < EXACT, "the F=0.2 link starts at element 0's centre");
        let f = LinkFilter { max_lines: 2, none: true, ..LinkFilter::default() };
        let r = link_lines(&els, &links(), &f, 1.0);
        assert_eq!((r.matched, r.shown), (3, 2), "stride 2 keeps links 0 and 2");
        assert!((r.lines.points[2].x - 2.5).abs() < EXACT, "the second kept link starts at element 2");
    }

    #[test]
    fn element_filter_includes_ancestors_links() {
        let mut els = vec![
            quad(0, 0, 0.0, 0.0, 1.0, 1.0),
            quad(1, 0, 1.0, 0.0, 1.0, 1.0),
            quad(2, 0, 2.0, 0.0, 1.0, 1.0),
        ];
        els[2].parent = Some(0);
        let f = LinkFilter { element: Some(2), none: true, ..LinkFilter::default() };
        // Element 2 gathers through its own link (receiver 2) and its parent 0's (receiver 0),
        // not through the link 0 shoots through (source 0, receiver 1).
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 2);
    }

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

    #[test]
    fn pick_nearest_leaf_either_side() {
        let mut far = quad(1, 0, 0.0, 0.0, 1.0, 1.0);
        for v in &mut far.vertices {
            v.z = -1.0;
        }
        let els = vec![quad(0, 0, 0.0, 0.0, 1.0, 1.0), far];
        let down = DVec3::new(0.0, 0.0, -1.0);
        assert_eq!(pick(&els, &[0, 1], DVec3::new(0.5, 0.5, 2.0), down).map(|h| h.0), Some(0));
        assert_eq!(pick(&els, &[1], DVec3::new(0.5, 0.5, 2.0), down).map(|h| h.0), Some(1));
        // From below the front faces of both still count; the nearest is element 1.
        assert_eq!(pick(&els, &[0, 1], DVec3::new(0.5, 0.5, -3.0), -down).map(|h| h.0), Some(1));
        assert_eq!(pick(&els, &[0, 1], DVec3::new(1.5, 0.5, 2.0), down), None);
    }
}
