//! Smooth shading: each leaf corner's value is the average of the leaves sharing it within its
//! input patch (nodal averaging, Cohen & Wallace 1993, sec. 9.2.1), and a corner inside a larger
//! neighbour's edge (a T-vertex) takes the value interpolated along that edge [Baum, Mann,
//! Smith & Winget 1991], longest edges first until nothing changes. Corners are merged by
//! quantised position and given one canonical position for all patches; a leaf's boundary lists
//! its corners with the T-vertices and seam points on each edge, for a conforming triangulation.

use super::ElementView;
use super::quantize::{ANY_PATCH, Key, MERGE_REL, Quantizer};
use super::seams::Seams;
use crate::math::{DVec3, Rgb, WordMap, WordSet};

/// Most anchoring passes (a chain of T-vertices hanging on each other takes one pass per link
/// when its edges are not longest-first; the quadtree's depth cap is 30).
const MAX_ANCHOR_PASSES: usize = 64;

/// An edge (its end keys, in key order) → the corners strictly inside it, as (t from the first
/// key's end, key), sorted by t.
type TVertices = WordMap<(Key, Key), Vec<(f64, Key)>>;

/// The leaves' corners, merged per input patch: a canonical position for each (so that every
/// leaf that shares a corner emits bit-identical coordinates) and the Gouraud value there
/// (nodal average; T-vertices anchored to the larger neighbour's edge, see the module docs).
pub struct VertexField {
    quant: Quantizer,
    /// Corner key → (canonical position, smooth radiosity).
    corners: WordMap<Key, (DVec3, Rgb)>,
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
        let mut canonical: WordMap<Key, DVec3> =
            WordMap::with_capacity_and_hasher(leaves.len() * 2, Default::default());
        for &l in leaves {
            for v in elements[l as usize].verts() {
                canonical.entry(quant.key(ANY_PATCH, *v)).or_insert(*v);
            }
        }
        let mut sums: WordMap<Key, (DVec3, Rgb, u32)> =
            WordMap::with_capacity_and_hasher(leaves.len() * 2, Default::default());
        for &l in leaves {
            let e = &elements[l as usize];
            for v in e.verts() {
                let p = canonical.get(&quant.key(ANY_PATCH, *v)).copied().unwrap_or(*v);
                let s = sums.entry(quant.key(e.patch, *v)).or_insert((p, Rgb::ZERO, 0));
                s.1 += e.radiosity;
                s.2 += 1;
            }
        }
        let mut corners: WordMap<Key, (DVec3, Rgb)> =
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
    corners: &WordMap<Key, (DVec3, Rgb)>,
    elements: &[ElementView],
    leaves: &[u32],
) -> TVertices {
    let mut by_patch: WordMap<u32, Vec<(Key, DVec3)>> = WordMap::default();
    for (k, (p, _)) in corners {
        by_patch.entry(k.0).or_default().push((*k, *p));
    }
    let grids: WordMap<u32, crate::eval::reconstruction::BucketGrid<Key>> = by_patch
        .into_iter()
        .map(|(patch, v)| (patch, crate::eval::reconstruction::BucketGrid::new(v)))
        .collect();
    let tol = 4.0 * quant.diag * MERGE_REL;
    let mut out = TVertices::default();
    let mut seen = WordSet::default();
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
fn anchor(corners: &mut WordMap<Key, (DVec3, Rgb)>, t_vertices: &TVertices) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::overlay::test_support::{EXACT, quad, right_edge_boundary, t_junction};

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
        let els = t_junction();
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
        right_edge_boundary(&f, &els[0]);
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
}
