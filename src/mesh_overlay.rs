//! CPU-side lines of the meshing overlays (no wgpu: `render` uploads them like the links):
//!
//! - **Critical edges**: every reflecting receiver's critical segments
//!   ([`crate::mesh::discontinuity::scene_segments`]) drawn on it, coloured by how abrupt the
//!   radiosity is across them — D0 (a jump in value: surfaces touch), D1 (a jump in the
//!   derivative), D2 (in the second derivative) [Heckbert 1992; Lischinski, Tampieri & Greenberg
//!   1992]. Over any mesh they show where element edges should lie; over the quadtree, how its
//!   axis-aligned cuts miss them.
//!
//! Lines lie on surfaces, so each is lifted off its receiver along the normal by
//! [`LIFT`] × the scene's diagonal (the depth test then keeps them in front of their own surface
//! and hides them behind others), and drawn three times side by side, [`WIDTH`] × the diagonal
//! apart in the receiver's plane, so they read at a few pixels' width (the GPU draws 1-pixel
//! lines).
//!
//! ```text
//!      ─────────  +WIDTH      three parallel copies of segment a─b, in the receiver plane,
//!   a ═════════ b             each LIFT above it
//!      ─────────  −WIDTH
//! ```

use crate::math::DVec3;
use crate::mesh::DEFAULT_SNAP;
use crate::mesh::discontinuity::{CriticalSegment, Discontinuity, SegmentCounts, scene_segments};
use crate::overlay::LineList;
use crate::scene::Scene;

/// Height of overlay lines above their surface, × the scene's diagonal.
pub const LIFT: f64 = 1e-3;
/// Half the spacing of the three copies of a line, × the scene's diagonal.
pub const WIDTH: f64 = 6e-4;

/// Display colours (RGBA, display space) of D0, D1 and D2 segments: red, amber, cyan — apart in
/// hue and in lightness, and none of them the quadtree's depth colours at depth 0 (white).
pub const CRITICAL_COLORS: [[f32; 4]; 3] =
    [[1.0, 0.15, 0.15, 1.0], [1.0, 0.75, 0.0, 1.0], [0.1, 0.85, 1.0, 1.0]];

/// The colour of a segment's kind.
#[must_use]
pub fn critical_color(order: Discontinuity) -> [f32; 4] {
    CRITICAL_COLORS[match order {
        Discontinuity::D0 => 0,
        Discontinuity::D1 => 1,
        Discontinuity::D2 => 2,
    }]
}

/// The critical segments of a whole scene: (receiver patch, segment), and the counts summed
/// over receivers.
#[derive(Clone, Debug, Default)]
pub struct CriticalEdges {
    pub segments: Vec<(usize, CriticalSegment)>,
    pub counts: SegmentCounts,
    /// Receivers skipped because their polygon is degenerate (reported, never a panic).
    pub skipped: usize,
}

/// Find the critical segments on every reflecting patch (ρ̄ > 0: the others show B = E).
#[must_use]
pub fn critical_edges(scene: &Scene) -> CriticalEdges {
    let mut out = CriticalEdges::default();
    for p in (0..scene.patches.len()).filter(|&p| scene.patches[p].reflectance.mean() > 0.0) {
        match scene_segments(&scene.patches, p, DEFAULT_SNAP) {
            Ok(set) => {
                out.counts = out.counts.plus(set.counts);
                out.segments.extend(set.segments.into_iter().map(|s| (p, s)));
            }
            Err(_) => out.skipped += 1,
        }
    }
    out
}

/// Lift a segment off its receiver and draw it three times side by side (module docs).
pub fn push_thick(list: &mut LineList, scene: &Scene, patch: usize, a: DVec3, b: DVec3, color: [f32; 4]) {
    let diag = scene.bounds().diagonal();
    let normal = scene.patches[patch].normal;
    let lift = normal * (LIFT * diag);
    let side = (b - a).cross(normal).normalize_or_zero() * (WIDTH * diag);
    for k in [-1.0, 0.0, 1.0] {
        list.push(a + lift + side * k, b + lift + side * k, color);
    }
}

/// The critical edges as lines coloured by kind (D2 first, D0 last: where segments of two kinds
/// coincide, the more abrupt one shows).
#[must_use]
pub fn critical_lines(scene: &Scene, edges: &CriticalEdges) -> LineList {
    let mut list = LineList::default();
    let mut sorted: Vec<&(usize, CriticalSegment)> = edges.segments.iter().collect();
    sorted.sort_by_key(|(_, s)| std::cmp::Reverse(s.order));
    for (p, s) in sorted {
        push_thick(&mut list, scene, *p, s.a, s.b, critical_color(s.order));
    }
    list
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_room_has_all_three_kinds_drawn_in_their_colours() {
        let scene = Scene::load("builtin:table-room").unwrap();
        let e = critical_edges(&scene);
        assert!(e.counts.d0 > 0 && e.counts.d1 > 0 && e.counts.d2 > 0, "{:?}", e.counts);
        assert_eq!(e.segments.len(), e.counts.total());
        let lines = critical_lines(&scene, &e);
        assert_eq!(lines.segments(), 3 * e.segments.len(), "three copies a segment");
        for c in CRITICAL_COLORS {
            assert!(lines.colors.contains(&c), "{c:?} drawn");
        }
        // Lifted off the receiver, on its front side.
        let (p, s) = &e.segments[0];
        let patch = &scene.patches[*p];
        let lifted = lines.points.iter().find(|q| (**q - s.a).length() < 0.01 * scene.bounds().diagonal());
        let q = lifted.expect("a copy near the segment's end");
        assert!((*q - patch.vertices[0]).dot(patch.normal) > 0.0, "in front of the receiver");
    }

    #[test]
    fn a_scene_without_occluders_has_no_d1_or_d2() {
        let scene = Scene::load("builtin:parallel").unwrap();
        let e = critical_edges(&scene);
        assert_eq!((e.counts.d1, e.counts.d2), (0, 0), "{:?}", e.counts);
        assert_eq!(critical_lines(&scene, &e).segments(), 3 * e.segments.len());
    }
}
