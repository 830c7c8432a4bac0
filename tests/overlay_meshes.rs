//! The viewer's conforming mesh ([`VertexField`]: T-vertices inside leaf edges, seams where
//! input patches meet) on the meshes every solver produces — the quadtree, a clustered solve,
//! the contact mesh, graded discontinuity meshes (CDT and BSP), the reference's point cells —
//! and on degenerate ones made to break it: slivers, leaf edges shorter than twice the seam
//! tolerance, collapsed corners. It must never panic, and every boundary it returns must be the
//! leaf's own outline:
//!
//! - the leaf's corners, in order, each followed by the points inserted on the edge to the next;
//! - every point on the leaf's outline (within the seam tolerance), its parameter coordinates
//!   in the unit square, its value finite.
//!
//! The random cases are plain seeded loops ([`Pcg32`]): the same cases on every run.

use radlab::eval::reference::{Cell, PointSet, RefPoint};
use radlab::math::{DVec3, Pcg32, Rgb};
use radlab::mesh::remesh::RemeshParams;
use radlab::present::overlay::{
    ElementCore, ElementView, MERGE_REL, SEAM_REL, VertexField, vertex_radiosity,
};
use radlab::scene::Scene;
use radlab::solver::discontinuity::HierarchicalOnMesh;
use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::meshed::{MeshMethod, MeshSolveParams};
use radlab::solver::params::{Clustering, HierarchicalParams};
use std::sync::Arc;

/// The scenes every mesh is built on (small enough for the debug build).
const SCENES: [&str; 3] = ["builtin:cornell", "builtin:table-room", "builtin:shadow-narrow"];

/// Elements of a graded discontinuity mesh (few: the solve couples every pair).
const GRADED_BUDGET: usize = 250;

/// A point is on the leaf's outline when this close to it, × the scene's diagonal: seam points
/// lie within `SEAM_REL` of the patch edge the leaf edge lies on (within `SEAM_REL` itself), and
/// corners move by the merge quantum.
const ON_OUTLINE_REL: f64 = 2.0 * SEAM_REL + 4.0 * MERGE_REL;

/// Parameter coordinates are interpolated along edges: outside [0, 1] by rounding only.
const UV_SLACK: f64 = 1e-9;

/// Diagonal of the elements' bounding box, as the overlay measures it.
fn diagonal(elements: &[ElementView]) -> f64 {
    let (lo, hi) = elements
        .iter()
        .flat_map(|e| e.verts().iter().copied())
        .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let d = (hi - lo).length();
    if d > 0.0 && d.is_finite() { d } else { 1.0 }
}

fn distance_to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t =
        if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    p.distance(a + ab * t)
}

/// Build the conforming mesh of `leaves` and check every leaf's boundary (module docs).
fn check(label: &str, elements: &[ElementView], leaves: &[u32]) {
    let field = VertexField::build(elements, leaves);
    let tol = ON_OUTLINE_REL * diagonal(elements);
    for &l in leaves {
        let e = &elements[l as usize];
        let v = e.verts();
        let b = field.boundary(e);
        assert!(b.len() >= v.len(), "{label}: leaf {l} lost corners: {} of {}", b.len(), v.len());
        assert!(b[0].position.distance(v[0]) <= tol, "{label}: leaf {l} starts at its first corner");
        // Its corners in order: the i-th corner is the first point near it after the previous.
        let mut at = 0;
        for (i, corner) in v.iter().enumerate() {
            let Some(k) = b[at..].iter().position(|p| p.position.distance(*corner) <= tol) else {
                panic!("{label}: leaf {l}'s corner {i} {corner:?} missing or out of order in {b:?}")
            };
            at += k + 1;
        }
        for p in &b {
            let off = (0..v.len()).map(|i| distance_to_segment(p.position, v[i], v[(i + 1) % v.len()]));
            let off = off.fold(f64::INFINITY, f64::min);
            assert!(
                off <= tol,
                "{label}: leaf {l}: {:?} is {off:e} off its outline (tol {tol:e})",
                p.position
            );
            assert!(
                p.uv.iter().all(|c| (-UV_SLACK..=1.0 + UV_SLACK).contains(c)),
                "{label}: leaf {l}: uv {:?}",
                p.uv
            );
            assert!(p.value.0.iter().all(|c| c.is_finite()), "{label}: leaf {l}: value {:?}", p.value);
        }
    }
    let values = vertex_radiosity(elements, leaves);
    assert!(values.iter().flatten().all(|c| c.0.iter().all(|x| x.is_finite())), "{label}: smooth values");
}

/// [`check`] on the leaves, then on seeded random subsets of them (a subset leaves holes and
/// changes which corners are T-vertices and which seams have partners).
fn check_with_subsets(label: &str, elements: &[ElementView], leaves: &[u32]) {
    check(label, elements, leaves);
    for seed in 0..3 {
        let mut rng = Pcg32::keyed(seed, 0x5ea3);
        let subset: Vec<u32> = leaves.iter().copied().filter(|_| rng.next_f64() < 0.7).collect();
        check(&format!("{label}, subset {seed}"), elements, &subset);
    }
}

fn scene(name: &str) -> Arc<Scene> {
    Arc::new(Scene::load(name).unwrap_or_else(|e| panic!("{name}: {e}")))
}

/// The viewer's copy of a hierarchical solver's state: every element, the leaves drawn.
fn of_solver(s: &HierarchicalSolver) -> (Vec<ElementView>, Vec<u32>) {
    let elements: Vec<ElementView> =
        s.snapshot_with(false).elements.iter().map(ElementView::from_info).collect();
    let leaves = elements.iter().filter(|e| e.leaf).map(|e| e.id).collect();
    (elements, leaves)
}

/// The viewer's copy of a solution on a mesh: every element a leaf of its own (as the viewer
/// shows mesh solves and the reference), so every element edge may be a seam.
fn flat_leaves(scene: &Scene, elements: &[(usize, Vec<DVec3>)]) -> (Vec<ElementView>, Vec<u32>) {
    let views: Vec<ElementView> = elements
        .iter()
        .enumerate()
        .map(|(i, (patch, vertices))| {
            let b = Rgb::splat(0.1 + 0.8 * ((i * 37) % 101) as f64 / 100.0);
            ElementView::flat_leaf(i as u32, *patch, &scene.patches[*patch], vertices, 1.0, b, 0.0, "")
        })
        .collect();
    (views, (0..elements.len() as u32).collect())
}

#[test]
fn quadtree_and_clustered_solves() {
    for name in SCENES {
        let scene = scene(name);
        for cluster in [Clustering::Off, Clustering::On] {
            let p = HierarchicalParams { cluster, ..HierarchicalParams::interactive() };
            let mut s = HierarchicalSolver::new(Arc::clone(&scene), p).unwrap();
            s.solve(&mut |_, _| {});
            let (elements, leaves) = of_solver(&s);
            check_with_subsets(&format!("{name} quadtree, clustering {cluster:?}"), &elements, &leaves);
        }
    }
}

#[test]
fn contact_mesh_solves() {
    for name in SCENES {
        let scene = scene(name);
        let mut on_mesh =
            HierarchicalOnMesh::new(&scene, &RemeshParams::contacts(), HierarchicalParams::interactive())
                .unwrap();
        on_mesh.solver.solve(&mut |_, _| {});
        // The hierarchy on the pieces (each piece a root), then its leaves pulled back onto the
        // input patches, as the viewer draws them.
        let (elements, leaves) = of_solver(&on_mesh.solver);
        check_with_subsets(&format!("{name} contact mesh, on the pieces"), &elements, &leaves);
        let solution = on_mesh.finish(false).solution;
        let pieces: Vec<_> = solution.elements.iter().map(|e| (e.patch, e.vertices.clone())).collect();
        let (elements, leaves) = flat_leaves(&scene, &pieces);
        check_with_subsets(&format!("{name} contact mesh"), &elements, &leaves);
    }
}

#[test]
fn graded_discontinuity_meshes() {
    for name in SCENES {
        let scene = scene(name);
        for method in [MeshMethod::DiscontinuityCdt, MeshMethod::DiscontinuityBsp] {
            let p = MeshSolveParams::new(method).graded(GRADED_BUDGET);
            let m = radlab::solver::meshed::solve(&scene, &p, &mut |_, _| {})
                .unwrap_or_else(|e| panic!("{name} {}: {e}", p.label()));
            let pieces: Vec<_> = m.solution.elements.iter().map(|e| (e.patch, e.vertices.clone())).collect();
            let (elements, leaves) = flat_leaves(&scene, &pieces);
            check_with_subsets(&format!("{name} {}", p.label()), &elements, &leaves);
        }
    }
}

/// The reference's point cells as the viewer draws the reference: a 4 × 4 grid on every patch,
/// cells split at random down to level 3 (a triangle's apex cells have two corners in one).
#[test]
fn reference_point_cells() {
    for name in SCENES {
        let scene = scene(name);
        let mut rng = Pcg32::keyed(7, name.len() as u64);
        let mut cells = Vec::new();
        for patch in 0..scene.patches.len() as u32 {
            let mut todo: Vec<Cell> = (0..16).map(|k| Cell { patch, level: 0, i: k % 4, j: k / 4 }).collect();
            while let Some(c) = todo.pop() {
                if c.level < 3 && rng.next_f64() < 0.3 {
                    let (level, i, j) = (c.level + 1, 2 * c.i, 2 * c.j);
                    let child = |i, j| Cell { patch, level, i, j };
                    todo.extend([child(i, j), child(i + 1, j), child(i, j + 1), child(i + 1, j + 1)]);
                } else {
                    cells.push(c);
                }
            }
        }
        let set = PointSet {
            grids: vec![(4, 4); scene.patches.len()],
            points: cells
                .into_iter()
                .map(|cell| RefPoint { patch: cell.patch as usize, position: DVec3::ZERO, area: 0.0, cell })
                .collect(),
        };
        let regions: Vec<_> = set.cell_regions(&scene).into_iter().map(|r| (r.patch, r.vertices)).collect();
        let (elements, leaves) = flat_leaves(&scene, &regions);
        check_with_subsets(&format!("{name} reference cells"), &elements, &leaves);
    }
}

// ---------------------------------------------------------------------------------------------
// Degenerate meshes built by hand

fn quad(id: u32, patch: u32, parent: Option<u32>, v: [DVec3; 4], b: f64) -> ElementView {
    ElementView {
        core: ElementCore {
            id,
            patch,
            parent,
            depth: u8::from(parent.is_some()),
            vertices: v,
            n_vertices: 4,
            area: 1.0,
            reflectance: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            radiosity: Rgb::splat(b),
            error_estimate: 0.0,
        },
        leaf: parent.is_some(),
        stop: "",
    }
}

fn p(x: f64, y: f64) -> DVec3 {
    DVec3::new(x, y, 0.0)
}

/// Two unit patches side by side, meeting along x = 1 (a seam): patch 0's leaf `left` and
/// patch 1 cut at y = `cut` into two leaves.
fn two_patches(left: [DVec3; 4], cut: f64) -> Vec<ElementView> {
    vec![
        quad(0, 0, None, [p(0., 0.), p(1., 0.), p(1., 1.), p(0., 1.)], 0.0),
        quad(1, 0, Some(0), left, 1.0),
        quad(2, 1, None, [p(1., 0.), p(2., 0.), p(2., 1.), p(1., 1.)], 0.0),
        quad(3, 1, Some(2), [p(1., 0.), p(2., 0.), p(2., cut), p(1., cut)], 2.0),
        quad(4, 1, Some(2), [p(1., cut), p(2., cut), p(2., 1.), p(1., 1.)], 3.0),
    ]
}

#[test]
fn a_leaf_edge_shorter_than_twice_the_seam_tolerance() {
    let tol = SEAM_REL * diagonal(&two_patches([p(0., 0.); 4], 0.5));
    let (y, s) = (0.5, 0.1 * tol);
    // A sliver of patch 0 whose edge on the seam is 0.1 tol long, and a corner of patch 1 in
    // the middle of it.
    let sliver = [p(0.5, y), p(1., y), p(1., y + s), p(0.5, y + s)];
    check("sliver on a seam", &two_patches(sliver, y + 0.5 * s), &[1, 3, 4]);
    // The same edge collapsed to a point, with patch 1's corner on it.
    let collapsed = [p(0.5, y - 0.1), p(1., y), p(1., y), p(0.5, y + 0.1)];
    check("collapsed corner on a seam", &two_patches(collapsed, y), &[1, 3, 4]);
    // A triangle with that corner (n = 3), and one whose corner count says 5.
    let mut els = two_patches(collapsed, y);
    els[1].n_vertices = 3;
    els[1].vertices = [p(0.5, y - 0.1), p(1., y), p(0.5, y + 0.1), p(0.5, y + 0.1)];
    check("triangle touching a seam", &els, &[1, 3, 4]);
    els[1].n_vertices = 5;
    check("a corner count past four", &els, &[1, 3, 4]);
}

/// Seeded random tilings of two patches meeting along a seam (coplanar, or at a right angle as
/// a wall meets the floor): each patch cut into strips across the seam at positions drawn to
/// crowd each other — equal, 10⁻¹²…3·10⁻⁶ of the size apart, around the seam tolerance — with
/// some strips cut again away from the seam (T-vertices) and some corners collapsed.
#[test]
fn random_slivers_along_a_seam() {
    const GAPS: [f64; 9] = [0.0, 1e-12, 1e-9, 3e-7, 1e-6, 1.5e-6, 2e-6, 3e-6, 0.05];
    for seed in 0..300u64 {
        let mut rng = Pcg32::keyed(seed, 0x51d);
        let wall = rng.next_f64() < 0.5;
        let mut els: Vec<ElementView> = Vec::new();
        let mut leaves = Vec::new();
        for patch in 0..2u32 {
            // (u, y) on the patch, u running away from the seam x = 1: patch 0 on the floor
            // towards x = 0, patch 1 on the floor towards x = 2 or up the wall.
            let side = |u: f64, y: f64| match (patch, wall) {
                (0, _) => DVec3::new(1.0 - u, y, 0.0),
                (_, false) => DVec3::new(1.0 + u, y, 0.0),
                (_, true) => DVec3::new(1.0, y, u),
            };
            let root = els.len() as u32;
            els.push(quad(root, patch, None, [side(0., 0.), side(1., 0.), side(1., 1.), side(0., 1.)], 0.0));
            let mut cuts = vec![0.0];
            while *cuts.last().unwrap() < 1.0 {
                let last = *cuts.last().unwrap();
                let gap = if rng.next_f64() < 0.6 {
                    GAPS[(rng.next_u32() as usize) % GAPS.len()]
                } else {
                    0.3 * rng.next_f64()
                };
                cuts.push((last + gap).min(1.0));
            }
            for w in cuts.windows(2) {
                let (y0, y1) = (w[0], w[1]);
                let mut add = |u0: f64, u1: f64, rng: &mut Pcg32| {
                    let id = els.len() as u32;
                    let mut v = [side(u0, y0), side(u1, y0), side(u1, y1), side(u0, y1)];
                    if rng.next_f64() < 0.1 {
                        let k = (rng.next_u32() % 4) as usize;
                        v[k] = v[(k + 1) % 4]; // a collapsed corner: a zero-length edge
                    }
                    els.push(quad(id, patch, Some(root), v, rng.next_f64()));
                    leaves.push(id);
                };
                if rng.next_f64() < 0.3 {
                    let m = 0.2 + 0.6 * rng.next_f64();
                    add(0.0, m, &mut rng);
                    add(m, 1.0, &mut rng);
                } else {
                    add(0.0, 1.0, &mut rng);
                }
            }
        }
        check(&format!("random seam {seed} ({})", if wall { "wall" } else { "floor" }), &els, &leaves);
    }
}
