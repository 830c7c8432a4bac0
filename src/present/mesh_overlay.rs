//! CPU-side lines of the meshing overlays (no wgpu: `render` uploads them like the links):
//!
//! - **Critical edges**: every reflecting receiver's critical segments
//!   ([`crate::mesh::discontinuity::scene_segments`]) drawn on it, coloured by how abrupt the
//!   radiosity is across them — D0 (a jump in value: surfaces touch), D1 (a jump in the
//!   derivative), D2 (in the second derivative) [Heckbert 1992; Lischinski, Tampieri & Greenberg
//!   1992]. Over any mesh they show where element edges should lie; over the quadtree, how its
//!   axis-aligned cuts miss them.
//!
//! - **Artifacts**: the samples behind each of the five artifacts of [`crate::eval::artifacts`]
//!   ([`ArtifactSamples`]) where they lie — A the penumbra band's grid points as small crosses
//!   coloured by their error, B the features' grid points (missing ones marked), C and D the
//!   interior element edges (Mach bands, inappropriate jumps marked), E the critical segments
//!   (the pieces inside elements marked); [`Artifact::All`] draws only what is marked, in five
//!   colours at once.
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

use crate::eval::artifacts::{ArtifactReport, ArtifactSamples, PointMark};
use crate::math::{DVec3, orthonormal_basis};
use crate::mesh::DEFAULT_SNAP;
use crate::mesh::discontinuity::{CriticalSegment, Discontinuity, SegmentCounts, scene_segments};
use crate::present::overlay::LineList;
use crate::present::overlay::Palette;
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

/// Which artifact overlay is drawn.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Artifact {
    /// A: the penumbra band's points, coloured by error.
    BlockyShadows,
    /// B: the reference's shadows and highlights, missing ones marked.
    MissingFeatures,
    /// C: interior element edges, Mach bands marked.
    MachBands,
    /// D: interior element edges, inappropriate value jumps marked.
    InappropriateDiscontinuities,
    /// E: critical segments, the pieces inside elements marked.
    UnresolvedDiscontinuities,
    /// The marked samples of all five, each artifact in its colour.
    All,
}

/// Colour of what each artifact marks (A uses the heat scale instead), in [`Artifact::ALL`]'s
/// order: B blue, C magenta, D orange, E lime — apart from each other and from the heat scale.
const MARKED: [[f32; 4]; 5] = [
    [1.0, 0.3, 0.1, 1.0],
    [0.25, 0.45, 1.0, 1.0],
    [1.0, 0.2, 1.0, 1.0],
    [1.0, 0.55, 0.0, 1.0],
    [0.55, 1.0, 0.1, 1.0],
];
/// What was examined and found fine (single-artifact overlays only).
const FINE: [f32; 4] = [0.55, 0.55, 0.55, 0.6];
/// A: the error (relative to the band's RMS reflected radiosity) at the top of the heat scale.
pub const BAND_ERROR_TOP: f64 = 1.0;

impl Artifact {
    /// The five, in the lecture's order.
    pub const ALL: [Artifact; 5] = [
        Artifact::BlockyShadows,
        Artifact::MissingFeatures,
        Artifact::MachBands,
        Artifact::InappropriateDiscontinuities,
        Artifact::UnresolvedDiscontinuities,
    ];

    /// "A blocky shadows", … (menus and legends).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Artifact::BlockyShadows => "A blocky shadows",
            Artifact::MissingFeatures => "B missing features",
            Artifact::MachBands => "C Mach bands",
            Artifact::InappropriateDiscontinuities => "D inappropriate discontinuities",
            Artifact::UnresolvedDiscontinuities => "E unresolved discontinuities",
            Artifact::All => "all five",
        }
    }

    /// What the overlay draws (tooltips).
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Artifact::BlockyShadows => {
                "The penumbra band's points as crosses coloured by |B − B_ref| relative to the band's                  RMS (heat scale, top at 100 %)"
            }
            Artifact::MissingFeatures => {
                "The reference's shadows and highlights (departing 25 % from the patch mean): blue                  where the solution does not show them, grey where it does"
            }
            Artifact::MachBands => {
                "Interior element edges: magenta where the Gouraud view's slope kinks visibly and                  the reference's does not"
            }
            Artifact::InappropriateDiscontinuities => {
                "Interior element edges: orange where the solution jumps visibly (2 % of the patch                  mean) and the reference is continuous"
            }
            Artifact::UnresolvedDiscontinuities => {
                "Critical segments: lime where they run inside an element instead of along an edge"
            }
            Artifact::All => "Every marked sample of A–E at once, each artifact in its colour",
        }
    }

    /// The colour of what this artifact marks (A: the top of its heat scale).
    #[must_use]
    pub fn color(self) -> [f32; 4] {
        let i = Artifact::ALL.iter().position(|a| *a == self).unwrap_or(0);
        MARKED[i]
    }

    /// The artifact's number in one line, from a report.
    #[must_use]
    pub fn summary(self, r: &ArtifactReport) -> String {
        let pct = |x: f64| format!("{:.1} %", 100.0 * x);
        match self {
            Artifact::BlockyShadows => match r.blocky_shadows {
                Some(a) => format!("A {} rel L2 in the penumbra band ({} points)", pct(a), r.band_points),
                None => "A no penumbra band".to_owned(),
            },
            Artifact::MissingFeatures => {
                let b = r.missing_features;
                format!(
                    "B {} of {} features missing ({} of their area)",
                    b.missing,
                    b.features,
                    pct(b.area_fraction)
                )
            }
            Artifact::MachBands => format!("C {} of interior edge length", pct(r.mach_bands.fraction())),
            Artifact::InappropriateDiscontinuities => {
                format!("D {} of interior edge length", pct(r.shading_jumps.fraction()))
            }
            Artifact::UnresolvedDiscontinuities => format!(
                "E {} of critical length inside elements{}",
                pct(r.unresolved.fraction()),
                r.unresolved.error_beside.map_or(String::new(), |e| format!(", error beside {}", pct(e)))
            ),
            Artifact::All => "A–E".to_owned(),
        }
    }
}

/// A small cross at a grid point, in its patch's plane, lifted (nothing for a patch the scene
/// does not have: samples of another scene).
fn push_cross(list: &mut LineList, scene: &Scene, m: &PointMark, color: [f32; 4]) {
    let Some(normal) = scene.patches.get(m.patch).map(|p| p.normal) else { return };
    let (u, v) = orthonormal_basis(normal);
    let lift = normal * (LIFT * scene.bounds().diagonal());
    let r = 0.35 * m.size;
    for d in [u + v, u - v] {
        let d = d.normalize_or_zero() * r;
        list.push(m.x + lift - d, m.x + lift + d, color);
    }
}

/// The lines of an artifact overlay (module docs).
#[must_use]
pub fn artifact_lines(scene: &Scene, samples: &ArtifactSamples, which: Artifact) -> LineList {
    let mut list = LineList::default();
    let all = which == Artifact::All;
    let show = |a: Artifact| all || which == a;
    if show(Artifact::BlockyShadows) {
        for m in &samples.band {
            let [r, g, b] = Palette::Heat.at(m.value / BAND_ERROR_TOP);
            push_cross(&mut list, scene, m, [r, g, b, 1.0]);
        }
    }
    if show(Artifact::MissingFeatures) {
        for m in samples.features.iter().filter(|m| m.flagged || !all) {
            let c = if m.flagged { Artifact::MissingFeatures.color() } else { FINE };
            push_cross(&mut list, scene, m, c);
        }
    }
    for (a, flag) in [
        (Artifact::MachBands, (|e: &crate::eval::artifacts::EdgeMark| e.mach_band) as fn(&_) -> bool),
        (Artifact::InappropriateDiscontinuities, |e| e.jump),
    ] {
        if show(a) {
            for e in samples.edges.iter().filter(|e| flag(e) || !all) {
                let c = if flag(e) { a.color() } else { FINE };
                let half = e.along * (0.5 * e.length);
                push_thick(&mut list, scene, e.patch, e.x - half, e.x + half, c);
            }
        }
    }
    if show(Artifact::UnresolvedDiscontinuities) {
        for m in samples.segments.iter().filter(|m| m.unresolved || !all) {
            let c = if m.unresolved { Artifact::UnresolvedDiscontinuities.color() } else { FINE };
            let half = m.along * (0.5 * m.length);
            push_thick(&mut list, scene, m.patch, m.x - half, m.x + half, c);
        }
    }
    list
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

/// Lift a segment off its receiver and draw it three times side by side (module docs; nothing
/// for a patch the scene does not have).
pub fn push_thick(list: &mut LineList, scene: &Scene, patch: usize, a: DVec3, b: DVec3, color: [f32; 4]) {
    let Some(normal) = scene.patches.get(patch).map(|p| p.normal) else { return };
    let diag = scene.bounds().diagonal();
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
    fn artifact_overlays_mark_what_the_report_counts() {
        use crate::eval::artifacts::{ArtifactParams, measure_samples};
        use crate::geometry::exact::SingleBounce;
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let accel = crate::geometry::accel::Accel::build(&scene);
        let p = crate::solver::uniform::UniformParams { element_size: 0.5, ..Default::default() };
        let sol = crate::solver::uniform::solve(&scene, &accel, &p, &mut |_, _| {}).unwrap();
        let sb = SingleBounce::new(&scene).unwrap();
        let exact = |patch: usize, x: DVec3| sb.patch_radiosity_at(patch, x);
        let (r, s) = measure_samples(&scene, &sol, &exact, &ArtifactParams::quick()).unwrap();
        let lines = |a| artifact_lines(&scene, &s, a);
        assert_eq!(lines(Artifact::BlockyShadows).segments(), 2 * r.band_points, "a cross a band point");
        assert_eq!(lines(Artifact::MachBands).segments(), 3 * s.edges.len(), "every interior edge sample");
        let marked = |a: Artifact| lines(a).colors.iter().filter(|c| **c == a.color()).count();
        assert!(marked(Artifact::InappropriateDiscontinuities) > 0, "D: {:?}", r.shading_jumps);
        assert!(marked(Artifact::UnresolvedDiscontinuities) > 0, "E: {:?}", r.unresolved);
        // All five: only what is marked, nothing grey.
        let all = lines(Artifact::All);
        assert!(!all.colors.contains(&FINE));
        for a in &Artifact::ALL[2..] {
            assert_eq!(all.colors.iter().filter(|c| **c == a.color()).count(), marked(*a), "{}", a.name());
        }
        assert!(Artifact::BlockyShadows.summary(&r).contains("penumbra band"));
    }

    #[test]
    fn a_scene_without_occluders_has_no_d1_or_d2() {
        let scene = Scene::load("builtin:parallel").unwrap();
        let e = critical_edges(&scene);
        assert_eq!((e.counts.d1, e.counts.d2), (0, 0), "{:?}", e.counts);
        assert_eq!(critical_lines(&scene, &e).segments(), 3 * e.segments.len());
    }
}
