//! The element hierarchy: an arena of elements with newtype ids, quads and triangles split 1→4.
//!
//! Roots are the input patches (element id = patch index). A quad splits at its edge midpoints and
//! its bilinear centre into four quads; a triangle into four triangles (three corners and the
//! centre one). Children are stored contiguously: `first_child .. first_child + 4`.
//!
//! ```text
//!   quad v0..v3 (counter-clockwise)         triangle v0 v1 v2
//!   v3 ── m23 ── v2                          v2
//!   │  nw │  ne  │    children, in order:    │ ╲
//!   m30 ── c ── m12   0 sw [v0 m01 c m30]    m20─m12     0 [v0 m01 m20]
//!   │  sw │  se  │    1 se [m01 v1 m12 c]    │ ╲ │ ╲     1 [m01 v1 m12]
//!   v0 ── m01 ── v1   2 ne [c m12 v2 m23]    v0─m01─v1   2 [m20 m12 v2]
//!                     3 nw [m30 c m23 v3]                3 [m12 m20 m01] (centre)
//! ```
//! [Hanrahan, Salzman, Aupperle 1991, sec. 3: "quadtree" subdivision of input polygons]

use crate::math::{DVec3, Rgb, polygon_area, polygon_centroid};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;

/// Index of an element in the arena.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct ElementId(pub u32);

/// "No element" in the compact `u32` fields.
pub const NONE: u32 = u32::MAX;

/// Why an element was not refined further (for the viewer's inspector).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// Refinement has not looked at this element as a receiver yet.
    #[default]
    Unrefined,
    /// It has children.
    Subdivided,
    /// Every link it receives has both form-factor estimates below Feps.
    BelowFeps,
    /// Every link it receives has B·F below BFeps.
    BelowBfEps,
    /// Its gathered radiosity varies less than the error threshold across it (error oracle).
    BelowErrorEps,
    /// A link wanted it subdivided, but its area is at the Aeps floor.
    AepsFloor,
    /// A link wanted it subdivided, but it is at the maximum depth.
    MaxDepth,
    /// A link wanted it subdivided, but the link budget (`max_links`) stopped the refinement
    /// first.
    LinkBudget,
}

impl StopReason {
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            StopReason::Unrefined => "not refined yet",
            StopReason::Subdivided => "subdivided",
            StopReason::BelowFeps => "all links below Feps",
            StopReason::BelowErrorEps => "its radiosity varies less than the error threshold",
            StopReason::BelowBfEps => "all links below BFeps",
            StopReason::AepsFloor => "at the Aeps floor (area too small to split)",
            StopReason::MaxDepth => "at the maximum depth",
            StopReason::LinkBudget => "the link budget stopped its refinement",
        }
    }
    /// Severity order used when several links disagree: a floor beats "below eps".
    pub(crate) fn rank(self) -> u8 {
        match self {
            StopReason::Unrefined => 0,
            StopReason::BelowFeps | StopReason::BelowBfEps | StopReason::BelowErrorEps => 1,
            StopReason::AepsFloor | StopReason::LinkBudget => 2,
            StopReason::MaxDepth => 3,
            StopReason::Subdivided => 4,
        }
    }
}

/// One element of the hierarchy.
// Field order is kept (repr(C)): the fields push-pull and gather touch come first, in the
// first cache lines; geometry follows.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct Element {
    pub parent: u32,
    pub first_child: u32,
    pub area: f64,
    /// Σ F over this element's fully visible own links.
    pub f_sum: f64,
    /// Σ F·V over this element's own links that are not fully visible.
    pub fv_partial: f64,
    /// Σ F·V over this element's own links (for the escaped-energy balance).
    pub fv_sum: f64,
    /// Largest channel of any leaf's radiosity below (and including) this element, from the last
    /// push-pull: the BF oracle's source term for partially visible links.
    pub b_max: f64,
    /// Radiosity: leaves E + ρ·H; interior elements the area average of their children (pull).
    pub radiosity: Rgb,
    /// Irradiance gathered over this element's own links, Σ F·V·B_source (before push).
    pub gathered: Rgb,
    /// The part of `gathered` that comes through fully visible links (V = 1).
    pub gathered_full: Rgb,
    /// How `gathered` varies across the element: its gradient Σ slope·B_source over the own
    /// links (`Link::slope`), in the tangent basis `orthonormal_basis(normal)` (u, v).
    pub gathered_slope: [Rgb; 2],
    /// Σ `Link::slope` over the own links: how the element's row of F·V varies across it (u, v).
    pub fv_slope: [f64; 2],
    pub emission: Rgb,
    pub reflectance: Rgb,
    pub patch: u32,
    pub depth: u8,
    pub n_verts: u8,
    pub stop: StopReason,
    /// Largest vertex-to-vertex distance (cached: the oracle asks for it per link).
    pub diam: f64,
    pub centroid: DVec3,
    pub normal: DVec3,
    pub verts: [DVec3; 4],
}

/// An element with nothing gathered, the rest placeholders: what [`Element::with_nothing_gathered`]
/// takes its gather sums from.
const NOTHING_GATHERED: Element = Element {
    parent: NONE,
    first_child: NONE,
    area: 0.0,
    f_sum: 0.0,
    fv_partial: 0.0,
    fv_sum: 0.0,
    b_max: 0.0,
    radiosity: Rgb::ZERO,
    gathered: Rgb::ZERO,
    gathered_full: Rgb::ZERO,
    gathered_slope: [Rgb::ZERO; 2],
    fv_slope: [0.0; 2],
    emission: Rgb::ZERO,
    reflectance: Rgb::ZERO,
    patch: 0,
    depth: 0,
    n_verts: 0,
    stop: StopReason::Unrefined,
    diam: 0.0,
    centroid: DVec3::ZERO,
    normal: DVec3::ZERO,
    verts: [DVec3::ZERO; 4],
};

impl Element {
    /// This element with the sums a gather fills in cleared: how a new element starts.
    #[must_use]
    fn with_nothing_gathered(self) -> Element {
        let n = &NOTHING_GATHERED;
        Element {
            gathered: n.gathered,
            gathered_full: n.gathered_full,
            gathered_slope: n.gathered_slope,
            fv_slope: n.fv_slope,
            fv_sum: n.fv_sum,
            f_sum: n.f_sum,
            fv_partial: n.fv_partial,
            ..self
        }
    }

    #[must_use]
    pub fn vertices(&self) -> &[DVec3] {
        &self.verts[..self.n_verts as usize]
    }
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.first_child == NONE
    }
    #[must_use]
    pub fn children(&self) -> Option<[u32; 4]> {
        (self.first_child != NONE).then(|| {
            let c = self.first_child;
            [c, c + 1, c + 2, c + 3]
        })
    }
    #[must_use]
    pub fn parent(&self) -> Option<u32> {
        (self.parent != NONE).then_some(self.parent)
    }
    /// Largest distance between two vertices (cached at creation).
    #[must_use]
    pub fn diameter(&self) -> f64 {
        self.diam
    }
}

/// Children made per parallel task in [`Hierarchy::split_many`].
const PARALLEL_CHILDREN: usize = 256;

/// Child `k` (0..4, in the order of the module docs) of `parent`, whose id is `id`; not yet in
/// the arena.
fn child(parent: &Element, id: u32, k: usize) -> Element {
    let v = parent.verts;
    let n = parent.n_verts;
    let verts: [DVec3; 4] = if n == 4 {
        let m01 = 0.5 * (v[0] + v[1]);
        let m12 = 0.5 * (v[1] + v[2]);
        let m23 = 0.5 * (v[2] + v[3]);
        let m30 = 0.5 * (v[3] + v[0]);
        let c = 0.25 * (v[0] + v[1] + v[2] + v[3]);
        [[v[0], m01, c, m30], [m01, v[1], m12, c], [c, m12, v[2], m23], [m30, c, m23, v[3]]][k]
    } else {
        let m01 = 0.5 * (v[0] + v[1]);
        let m12 = 0.5 * (v[1] + v[2]);
        let m20 = 0.5 * (v[2] + v[0]);
        let z = DVec3::ZERO;
        [[v[0], m01, m20, z], [m01, v[1], m12, z], [m20, m12, v[2], z], [m12, m20, m01, z]][k]
    };
    let used = &verts[..n as usize];
    Element {
        parent: id,
        first_child: NONE,
        depth: parent.depth + 1,
        stop: StopReason::Unrefined,
        verts,
        area: polygon_area(used),
        diam: max_pairwise_distance(used),
        centroid: polygon_centroid(used),
        ..parent.clone()
    }
    .with_nothing_gathered()
}

fn max_pairwise_distance(v: &[DVec3]) -> f64 {
    let mut d: f64 = 0.0;
    for i in 0..v.len() {
        for j in i + 1..v.len() {
            d = d.max(v[i].distance(v[j]));
        }
    }
    d
}

/// The arena. Element `i < patches` is the root of patch `i`.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    pub elements: Vec<Element>,
    pub roots: usize,
}

impl Hierarchy {
    /// One root element per input patch, radiosity = emission.
    #[must_use]
    pub fn from_scene(scene: &Scene) -> Hierarchy {
        let elements = scene
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut verts = [DVec3::ZERO; 4];
                verts[..p.vertices.len()].copy_from_slice(&p.vertices);
                Element {
                    patch: i as u32,
                    parent: NONE,
                    first_child: NONE,
                    depth: 0,
                    n_verts: p.vertices.len() as u8,
                    stop: StopReason::Unrefined,
                    verts,
                    area: p.area,
                    diam: max_pairwise_distance(&p.vertices),
                    centroid: p.centroid,
                    normal: p.normal,
                    reflectance: p.reflectance,
                    emission: p.emission,
                    radiosity: p.emission,
                    b_max: p.emission.max_channel(),
                    ..NOTHING_GATHERED
                }
            })
            .collect();
        Hierarchy { elements, roots: scene.patches.len() }
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.elements.len()
    }
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }

    #[must_use]
    pub fn get(&self, id: u32) -> &Element {
        &self.elements[id as usize]
    }

    /// Split element `id` into four children (no-op if it already has them). Returns the first
    /// child's id. Children inherit the parent's radiosity.
    pub fn split(&mut self, id: u32) -> u32 {
        let e = &self.elements[id as usize];
        if e.first_child != NONE {
            return e.first_child;
        }
        let first = self.elements.len() as u32;
        let parent = e.clone();
        self.elements.extend((0..4).map(|k| child(&parent, id, k)));
        let p = &mut self.elements[id as usize];
        p.first_child = first;
        p.stop = StopReason::Subdivided;
        first
    }

    /// Split every leaf among `ids` (ascending, no duplicates), in that order: the same ids and
    /// elements as calling [`Hierarchy::split`] on each, with the children made in parallel.
    /// Returns how many were split.
    pub fn split_many(&mut self, ids: &[u32]) -> usize {
        debug_assert!(ids.windows(2).all(|w| w[0] < w[1]), "ids ascending and distinct");
        let leaves: Vec<u32> =
            ids.iter().copied().filter(|&id| self.elements[id as usize].is_leaf()).collect();
        let parents: Vec<Element> = leaves.iter().map(|&id| self.elements[id as usize].clone()).collect();
        let first = self.elements.len() as u32;
        self.elements.par_extend(
            (0..4 * leaves.len())
                .into_par_iter()
                .with_min_len(PARALLEL_CHILDREN)
                .map(|i| child(&parents[i / 4], leaves[i / 4], i % 4)),
        );
        for (k, &id) in leaves.iter().enumerate() {
            let p = &mut self.elements[id as usize];
            p.first_child = first + 4 * k as u32;
            p.stop = StopReason::Subdivided;
        }
        leaves.len()
    }

    /// Ids of the leaves, in id order.
    #[must_use]
    pub fn leaves(&self) -> Vec<u32> {
        (0..self.elements.len() as u32).filter(|&i| self.elements[i as usize].is_leaf()).collect()
    }

    /// The chain from `id` up to its root, `id` first.
    pub fn ancestors(&self, id: u32) -> impl Iterator<Item = u32> + '_ {
        let mut cur = id;
        std::iter::from_fn(move || {
            if cur == NONE {
                None
            } else {
                let r = cur;
                cur = self.elements[cur as usize].parent;
                Some(r)
            }
        })
    }

    /// Element counts per depth.
    #[must_use]
    pub fn depth_histogram(&self) -> Vec<usize> {
        let mut h = Vec::new();
        for e in &self.elements {
            let d = e.depth as usize;
            if h.len() <= d {
                h.resize(d + 1, 0);
            }
            h[d] += 1;
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Patch, Scene};

    fn scene_with(verts: Vec<DVec3>) -> Scene {
        Scene::new("t", "t", vec![Patch::new(verts, Rgb::splat(0.5), Rgb::ONE, "m", 0, "p", "m").unwrap()])
    }

    #[test]
    fn quad_split_preserves_area_orientation_and_links_parents() {
        let sc = scene_with(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.5, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]);
        let mut h = Hierarchy::from_scene(&sc);
        let c = h.split(0);
        assert_eq!(h.split(0), c, "split is idempotent");
        let kids = h.get(0).children().unwrap();
        let total: f64 = kids.iter().map(|&k| h.get(k).area).sum();
        assert!((total - h.get(0).area).abs() < 1e-12);
        for k in kids {
            let e = h.get(k);
            assert_eq!(e.parent(), Some(0));
            assert_eq!(e.depth, 1);
            assert!(crate::math::polygon_normal(e.vertices()).dot(DVec3::Z) > 0.999);
        }
        h.split(kids[2]);
        assert_eq!(h.ancestors(h.len() as u32 - 1).collect::<Vec<_>>(), vec![h.len() as u32 - 1, kids[2], 0]);
        assert_eq!(h.depth_histogram(), vec![1, 4, 4]);
        assert_eq!(h.leaves().len(), 7);
    }

    #[test]
    fn triangle_split_into_four_equal_triangles() {
        let sc = scene_with(vec![DVec3::ZERO, DVec3::X, DVec3::Y]);
        let mut h = Hierarchy::from_scene(&sc);
        h.split(0);
        for k in h.get(0).children().unwrap() {
            let e = h.get(k);
            assert!((e.area - 0.125).abs() < 1e-15);
            assert!(crate::math::polygon_normal(e.vertices()).dot(DVec3::Z) > 0.999);
        }
    }

    #[test]
    fn split_many_makes_the_same_elements_as_splitting_one_by_one() {
        let sc = Scene::load("builtin:splash_room").unwrap();
        let mut one = Hierarchy::from_scene(&sc);
        let mut many = one.clone();
        // Three passes; each splits every third leaf (and an already split element, a no-op).
        for pass in 0..3u32 {
            let mut ids: Vec<u32> = one.leaves().into_iter().filter(|i| (i + pass) % 3 == 0).collect();
            ids.push(0);
            ids.sort_unstable();
            ids.dedup();
            let mut n = 0;
            for &id in &ids {
                if one.get(id).is_leaf() {
                    one.split(id);
                    n += 1;
                }
            }
            assert_eq!(many.split_many(&ids), n, "pass {pass}: the leaves among the ids are split");
        }
        assert!(one.len() > 1000, "enough elements to be split in parallel");
        assert_eq!(one.len(), many.len());
        for (a, b) in one.elements.iter().zip(&many.elements) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
    }
}
