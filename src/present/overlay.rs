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
//!   side's edges. Those corners are inserted into the other side's boundary (`seams`), and
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
//!
//! ## Files
//! This file holds the views of elements and links and the line list; `smooth` the vertex
//! values and leaf boundaries, over `quantize` (positions merged) and `seams` (where patches
//! meet); `links` the link and cluster overlays; `colors` the colour scales; `pick` the hover
//! highlight and picking.

mod colors;
mod links;
mod pick;
mod quantize;
mod seams;
mod smooth;

pub use colors::{LogScale, Palette, depth_color, heatmap_colors};
pub use links::{
    CLUSTER_LINK_DASHES, DEFAULT_MAX_LINKS, Decimation, LinkFilter, LinkLines, ancestors, cluster_chain,
    cluster_lines, cluster_link_lines, link_lines,
};
pub use pick::{HIGHLIGHT_LINK, HIGHLIGHT_RECEIVER, HIGHLIGHT_SOURCE, Highlight, highlight_lines, pick};
pub use quantize::MERGE_REL;
pub use seams::SEAM_REL;
pub use smooth::{BoundaryPoint, VertexField, vertex_radiosity};

use crate::math::{DVec3, Rgb};
pub use crate::solver::hierarchical::ElementCore;

/// One element as the viewer sees it (leaf or interior), of any solver's solution: the solver
/// layer's [`ElementCore`] (which it dereferences to), whether it is a leaf, and why refinement
/// stopped there. `id` indexes the element list.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementView {
    pub core: ElementCore,
    pub leaf: bool,
    /// Why refinement stopped at this element (a short label).
    pub stop: &'static str,
}

impl std::ops::Deref for ElementView {
    type Target = ElementCore;
    fn deref(&self) -> &ElementCore {
        &self.core
    }
}

impl std::ops::DerefMut for ElementView {
    fn deref_mut(&mut self) -> &mut ElementCore {
        &mut self.core
    }
}

impl ElementView {
    /// The viewer's copy of a solver element.
    #[must_use]
    pub fn from_info(e: &crate::solver::hierarchical::ElementInfo) -> ElementView {
        ElementView { core: e.core, leaf: e.children.is_none(), stop: e.stop.label() }
    }

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
        let core = ElementCore {
            id,
            patch: patch_index as u32,
            parent: None,
            depth: 0,
            vertices: v,
            n_vertices: n as u8,
            area,
            reflectance: patch.reflectance,
            emission: patch.emission,
            radiosity,
            error_estimate,
        };
        ElementView { core, leaf: true, stop }
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
    /// The viewer's copy of a solver link.
    #[must_use]
    pub fn from_info(l: &crate::solver::hierarchical::LinkInfo) -> LinkView {
        LinkView { receiver: l.receiver, source: l.source, ff: l.ff, vis: l.vis }
    }

    /// Its visibility class (full, partial, none; see [`VIS_CLASS_EPS`]).
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

/// Fixtures of the overlays' unit tests.
#[cfg(test)]
pub(crate) mod test_support {
    use super::{BoundaryPoint, ElementCore, ElementView, VertexField};
    use crate::math::{DVec3, Rgb};

    /// A leaf square of side `s` at (`x0`, `y0`) in the z = 0 plane, radiosity `b` in every channel.
    pub(crate) fn quad(id: u32, depth: u8, x0: f64, y0: f64, s: f64, b: f64) -> ElementView {
        quad_rgb(id, depth, x0, y0, s, Rgb::splat(b))
    }

    /// [`quad`] with radiosity `b`.
    pub(crate) fn quad_rgb(id: u32, depth: u8, x0: f64, y0: f64, s: f64, b: Rgb) -> ElementView {
        let core = ElementCore {
            id,
            patch: 0,
            parent: None,
            depth,
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
            radiosity: b,
            error_estimate: 0.0,
        };
        ElementView { core, leaf: true, stop: "" }
    }

    /// Exact for values that are sums of a few halves; only rounding remains.
    pub(super) const EXACT: f64 = 1e-12;

    /// The boundary of `e`, a 2×2 leaf at the origin, checked: its corners, and on its right edge
    /// the T-vertices (2, 1) and (2, 1.5), whose parameter coordinates run along it (u = 1).
    pub(super) fn right_edge_boundary(f: &VertexField, e: &ElementView) -> Vec<BoundaryPoint> {
        let b = f.boundary(e);
        let pts: Vec<[f64; 2]> = b.iter().map(|p| [p.position.x, p.position.y]).collect();
        assert_eq!(pts, vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 1.5], [2.0, 2.0], [0.0, 2.0]]);
        assert_eq!(b[2].uv, [1.0, 0.5]);
        assert_eq!(b[3].uv, [1.0, 0.75]);
        b
    }

    /// A 2×2 square (depth 1, B = 10) and on its right two stacked unit squares (depth 2, B = 0
    /// and 4): (2, 1) is a T-vertex on the big square's right edge.
    pub(crate) fn t_junction() -> Vec<ElementView> {
        vec![quad(0, 1, 0.0, 0.0, 2.0, 10.0), quad(1, 2, 2.0, 0.0, 1.0, 0.0), quad(2, 2, 2.0, 1.0, 1.0, 4.0)]
    }
}
