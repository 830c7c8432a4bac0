//! Heckbert's discontinuity mesh: a constrained Delaunay triangulation of the receiver whose
//! constraints are its boundary and its critical segments [Heckbert 1992, "Discontinuity
//! meshing for radiosity", sec. 4; the lecture's "Heckbert constrained DT mesh"].
//!
//! A triangulation T of the receiver is *constrained Delaunay* for a set of segments S when
//! every segment of S is a union of edges of T and every triangle's circumcircle contains no
//! vertex visible from its interior (visibility blocked by S) [Chew 1989]. It is the Delaunay
//! triangulation "as close as the constraints allow": no element edge crosses a discontinuity,
//! and the elements are as round as possible. Delaunay refinement [Ruppert 1995; Shewchuk 2002]
//! then inserts Steiner points until every triangle's smallest angle is at least
//! [`CdtParams::min_angle_deg`] (except at small input angles between constraints) and its area
//! at most [`CdtParams::max_area`] × the receiver's area.
//!
//! ## How it works
//! ```text
//!   receiver boundary (split at every segment end point on it)  ┐
//!   critical segments, clipped and snapped (super::ReceiverPlane) ┼─ spade CDT ─ refine ─ keep the
//!   crossings: spade's add_constraint_and_split inserts them    ┘   faces inside the boundary
//! ```
//! Segments that cross, touch or overlap are split at their intersections first, the points
//! merged within the tolerance (so several lines through one point make one vertex); anything
//! rounding still makes cross is split by `spade` (`add_constraint_and_split`), so any set of
//! segments is accepted. The faces kept are those
//! not reachable from outside the convex hull without crossing a constraint (the boundary loop):
//! end points snapped onto the boundary may sit a rounding error outside it, which would make
//! slivers outside the boundary loop.

use super::{MeshError, ReceiverPlane, Segment2};
use crate::math::DVec3;
use glam::DVec2;
use serde::Serialize;
use spade::handles::FixedVertexHandle;
use spade::{AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation};

/// Settings of the constrained Delaunay mesh.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct CdtParams {
    /// Smallest angle refinement aims for, degrees (0: no refinement for angles; ≤ 30 terminates).
    pub min_angle_deg: f64,
    /// Largest triangle area as a fraction of the receiver's area (`f64::INFINITY`: no limit).
    pub max_area: f64,
    /// Triangles smaller than this fraction of the receiver's area are not refined further.
    pub min_area: f64,
    /// Cap on the Steiner points refinement may add, per receiver.
    pub max_steiner_points: usize,
}

impl CdtParams {
    /// The constrained Delaunay triangulation with no Steiner points.
    #[must_use]
    pub const fn unrefined() -> CdtParams {
        CdtParams { min_angle_deg: 0.0, max_area: f64::INFINITY, min_area: 0.0, max_steiner_points: 0 }
    }

    /// Ruppert's refinement to 20° (always terminates), no area limit; tiny triangles (below
    /// 1e-6 of the receiver) are left alone so thin penumbrae do not explode the count.
    #[must_use]
    pub const fn quality() -> CdtParams {
        CdtParams { min_angle_deg: 20.0, max_area: f64::INFINITY, min_area: 1e-6, max_steiner_points: 2000 }
    }

    /// Check the values.
    pub fn validate(&self) -> Result<(), MeshError> {
        if !(0.0..=34.0).contains(&self.min_angle_deg) {
            return Err(MeshError::Parameter(format!(
                "min-angle must be in [0, 34] degrees (got {})",
                self.min_angle_deg
            )));
        }
        if !(self.max_area > 0.0 && self.min_area >= 0.0 && self.min_area.is_finite()) {
            return Err(MeshError::Parameter(format!(
                "max-area must be > 0 and min-area ≥ 0 (got {} and {})",
                self.max_area, self.min_area
            )));
        }
        Ok(())
    }
}

impl Default for CdtParams {
    fn default() -> Self {
        CdtParams::quality()
    }
}

/// One triangle of the mesh, counter-clockwise seen from the receiver's front.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct MeshTriangle {
    pub vertices: [DVec3; 3],
    /// Whether edge k (vertex k to k + 1) lies on a constraint: the boundary or a critical segment.
    pub constrained: [bool; 3],
}

/// A receiver's constrained Delaunay mesh.
#[derive(Clone, Debug, Serialize)]
pub struct CdtMesh {
    pub triangles: Vec<MeshTriangle>,
    /// Constraint segments inserted (critical segments after clipping, snapping and deduplication).
    pub constraints: usize,
    /// Vertices of the triangulation (input, crossings and Steiner points).
    pub vertices: usize,
    /// False if refinement stopped at `max_steiner_points`.
    pub refinement_complete: bool,
}

/// Insert a point, merging it with an existing vertex closer than the tolerance.
fn insert(
    cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>,
    pool: &mut Vec<(DVec2, FixedVertexHandle)>,
    p: DVec2,
    tol: f64,
) -> Result<FixedVertexHandle, MeshError> {
    if let Some(&(_, h)) = pool.iter().find(|(q, _)| q.distance(p) <= tol) {
        return Ok(h);
    }
    let h = cdt
        .insert(Point2::new(p.x, p.y))
        .map_err(|e| MeshError::Triangulation { cause: format!("{e:?} at ({}, {})", p.x, p.y) })?;
    pool.push((p, h));
    Ok(h)
}

/// The boundary split at every segment end point lying on it: for each edge, its points sorted
/// along it (start vertex first, end vertex excluded).
fn boundary_chain(plane: &ReceiverPlane, segments: &[Segment2]) -> Vec<DVec2> {
    let n = plane.polygon.len();
    let mut chain = Vec::new();
    for k in 0..n {
        let (a, b) = (plane.polygon[k], plane.polygon[(k + 1) % n]);
        let dir = b - a;
        let len2 = dir.length_squared();
        let mut on: Vec<(f64, DVec2)> = segments
            .iter()
            .flat_map(|s| [s.a, s.b])
            .filter(|p| plane.edge_distance(k, *p).abs() <= plane.tolerance)
            .map(|p| ((p - a).dot(dir) / len2, p))
            .filter(|(t, _)| *t > 0.0 && *t < 1.0)
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0));
        chain.push(a);
        chain.extend(on.into_iter().map(|(_, p)| p));
    }
    chain
}

/// Each segment's points in order along it: its end points and every point where another
/// segment crosses or touches it (within `tol`). Inserting these through the merging vertex pool
/// makes three segments through one point meet at one vertex, where letting `spade` split each
/// crossing separately leaves clusters of vertices a rounding error apart (and zero-area
/// triangles between them).
fn arrangement(segs: &[Segment2], tol: f64) -> Vec<Vec<DVec2>> {
    let mut points: Vec<Vec<(f64, DVec2)>> = segs.iter().map(|s| vec![(0.0, s.a), (1.0, s.b)]).collect();
    let param = |s: &Segment2, p: DVec2| (p - s.a).dot(s.b - s.a) / (s.b - s.a).length_squared();
    let near = |s: &Segment2, p: DVec2| {
        let t = param(s, p).clamp(0.0, 1.0);
        p.distance(s.a.lerp(s.b, t)) <= tol
    };
    for i in 0..segs.len() {
        for j in i + 1..segs.len() {
            let (si, sj) = (&segs[i], &segs[j]);
            let (di, dj) = (si.b - si.a, sj.b - sj.a);
            let denom = di.perp_dot(dj);
            let mut hits: Vec<DVec2> = Vec::new();
            if denom.abs() > 1e-12 * di.length() * dj.length() {
                let x = si.a + di * ((sj.a - si.a).perp_dot(dj) / denom);
                if near(si, x) && near(sj, x) {
                    hits.push(x);
                }
            }
            // End points of one on the other (T-junctions, collinear overlaps).
            hits.extend([sj.a, sj.b].into_iter().filter(|p| near(si, *p)));
            hits.extend([si.a, si.b].into_iter().filter(|p| near(sj, *p)));
            for x in hits {
                for (k, s) in [(i, si), (j, sj)] {
                    if near(s, x) {
                        points[k].push((param(s, x).clamp(0.0, 1.0), x));
                    }
                }
            }
        }
    }
    points
        .into_iter()
        .map(|mut p| {
            p.sort_by(|a, b| a.0.total_cmp(&b.0));
            p.into_iter().map(|(_, x)| x).collect()
        })
        .collect()
}

/// Triangulate a receiver (its [`ReceiverPlane`]) with critical segments (3-D end points on or
/// near its plane; clipped to it here) as constraints.
pub fn triangulate(
    plane: &ReceiverPlane,
    segments: &[[DVec3; 2]],
    params: &CdtParams,
) -> Result<CdtMesh, MeshError> {
    params.validate()?;
    let segs = plane.prepare(segments);
    let tol = plane.tolerance;
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
    let mut pool: Vec<(DVec2, FixedVertexHandle)> = Vec::new();

    // The boundary loop.
    let chain = boundary_chain(plane, &segs);
    let handles: Vec<FixedVertexHandle> =
        chain.iter().map(|p| insert(&mut cdt, &mut pool, *p, tol)).collect::<Result<_, _>>()?;
    for k in 0..handles.len() {
        let (a, b) = (handles[k], handles[(k + 1) % handles.len()]);
        if a != b {
            cdt.add_constraint_and_split(a, b, |p| p);
        }
    }
    // The critical segments, split at their crossings first.
    for points in arrangement(&segs, tol) {
        let mut previous = None;
        for p in points {
            let h = insert(&mut cdt, &mut pool, p, tol)?;
            if let Some(a) = previous
                && a != h
            {
                cdt.add_constraint_and_split(a, h, |p| p);
            }
            previous = Some(h);
        }
    }

    let area = plane.area();
    let mut refinement_complete = true;
    if params.min_angle_deg > 0.0 || params.max_area.is_finite() {
        let mut rp = RefinementParameters::<f64>::new()
            .exclude_outer_faces(false)
            .with_angle_limit(AngleLimit::from_deg(params.min_angle_deg))
            .with_max_additional_vertices(params.max_steiner_points);
        if params.max_area.is_finite() {
            rp = rp.with_max_allowed_area(params.max_area * area);
        }
        if params.min_area > 0.0 {
            rp = rp.with_min_required_area(params.min_area * area);
        }
        refinement_complete = cdt.refine(rp).refinement_complete;
    }

    let outside = outer_faces(&cdt);
    let triangles = cdt
        .inner_faces()
        .filter(|f| !outside[f.index()])
        .map(|f| {
            let edges = f.adjacent_edges();
            let vertices = edges.map(|e| {
                let p = e.from().position();
                plane.to_3d(DVec2::new(p.x, p.y))
            });
            MeshTriangle { vertices, constrained: edges.map(|e| e.is_constraint_edge()) }
        })
        .collect();
    Ok(CdtMesh { triangles, constraints: segs.len(), vertices: cdt.num_vertices(), refinement_complete })
}

/// Faces reachable from outside the convex hull without crossing a constraint, indexed by face
/// index (a flood fill; deterministic).
fn outer_faces(cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>) -> Vec<bool> {
    let mut outside = vec![false; cdt.num_all_faces()];
    let mut todo: Vec<_> = cdt.convex_hull().map(|e| e.rev()).collect();
    while let Some(edge) = todo.pop() {
        if edge.is_constraint_edge() {
            continue;
        }
        if let Some(face) = edge.face().as_inner()
            && !outside[face.index()]
        {
            outside[face.index()] = true;
            todo.push(edge.prev().rev());
            todo.push(edge.next().rev());
        }
    }
    outside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::polygon_area;

    fn square_plane() -> ReceiverPlane {
        let v = |x, z| DVec3::new(x, 0.0, z);
        ReceiverPlane::new(&[v(0.0, 0.0), v(0.0, 1.0), v(1.0, 1.0), v(1.0, 0.0)], 1e-9).unwrap()
    }

    fn total_area(m: &CdtMesh) -> f64 {
        m.triangles.iter().map(|t| polygon_area(&t.vertices)).sum()
    }

    #[test]
    fn empty_constraints_give_the_receiver() {
        let plane = square_plane();
        let m = triangulate(&plane, &[], &CdtParams::unrefined()).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert!((total_area(&m) - 1.0).abs() < 1e-12);
        assert!(m.triangles.iter().all(|t| t.constrained.iter().filter(|c| **c).count() == 2));
    }

    #[test]
    fn crossing_overlapping_tiny_and_outside_segments_do_not_panic() {
        let plane = square_plane();
        let p = |x, z| DVec3::new(x, 0.0, z);
        let segs = [
            [p(0.1, 0.1), p(0.9, 0.9)],
            [p(0.1, 0.9), p(0.9, 0.1)],         // crosses the first
            [p(0.2, 0.2), p(0.6, 0.6)],         // overlaps the first
            [p(0.5, 0.5), p(0.5, 0.5 + 1e-15)], // tiny
            [p(2.0, 2.0), p(3.0, 3.0)],         // outside
            [p(-1.0, 0.5), p(2.0, 0.5)],        // through, clipped to the boundary
            [p(0.0, 0.3), p(0.0, 0.7)],         // along the boundary
            [p(0.3, 0.3), p(0.3, 0.3)],         // zero length
        ];
        for params in [CdtParams::unrefined(), CdtParams::quality()] {
            let m = triangulate(&plane, &segs, &params).unwrap();
            assert!((total_area(&m) - 1.0).abs() < 1e-9, "area {}", total_area(&m));
            assert!(m.triangles.iter().all(|t| polygon_area(&t.vertices) > 0.0));
        }
    }

    /// A constraint that does not close a loop (a shadow edge ending inside the receiver) must not
    /// stop refinement around it: spade's `exclude_outer_faces` peels faces by the parity of the
    /// constraints crossed and skipped every face here (6 triangles for any max-area before).
    #[test]
    fn max_area_refines_around_a_dangling_constraint() {
        let plane = square_plane();
        let v = |x, z| DVec3::new(x, 0.0, z);
        let segs = [[v(0.2, 0.2), v(0.8, 0.7)]];
        let coarse = triangulate(&plane, &segs, &CdtParams::quality()).unwrap();
        let fine = triangulate(&plane, &segs, &CdtParams { max_area: 0.01, ..CdtParams::quality() }).unwrap();
        assert!(fine.refinement_complete);
        assert!(fine.triangles.len() >= 100, "{} triangles", fine.triangles.len());
        assert!(fine.triangles.iter().all(|t| polygon_area(&t.vertices) <= 0.01 + 1e-12));
        assert!(fine.triangles.len() > coarse.triangles.len());
        assert!((total_area(&fine) - 1.0).abs() < 1e-12);
    }
}
