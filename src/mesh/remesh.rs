//! A whole scene on a discontinuity mesh: every patch with critical segments replaced by the
//! pieces of its constrained Delaunay mesh ([`super::cdt`]) or BSP mesh ([`super::bsp`]), each
//! piece a new [`Patch`](crate::scene::Patch) with the original's material (ρ, E), mesh and material names. Any solver
//! then runs on the new scene; the uniform solver with `element_size = ∞` (one element per patch)
//! is the p = 0 Galerkin solve on the discontinuity mesh [Heckbert 1992; Lischinski et al. 1992].
//!
//! ```text
//! patch i ──scene_segments──▶ critical segments ──cdt / bsp──▶ pieces ──▶ patches i/dm0, i/dm1, …
//! ```
//!
//! Patches hold 3 or 4 vertices: BSP pieces with more are fanned into triangles (a convex
//! polygon's fan from its first vertex). Receivers are meshed in parallel, results kept in patch
//! order, so the scene is identical for any thread count.
//!
//! With [`RemeshParams::grade`] the pieces — and every patch left whole — are then split by
//! [`super::grade`] to a budget of patches for the whole scene: small inside the penumbrae,
//! larger elsewhere (a graded discontinuity mesh).

use super::bsp::partition;
use super::cdt::{CdtParams, triangulate};
use super::discontinuity::{SegmentCounts, scene_segments};
use super::grade::{GradeParams, GradeStats, Piece, grade};
use super::{DEFAULT_SNAP, MeshError, ReceiverPlane};
use crate::math::DVec3;
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// Which mesh replaces a receiver.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
pub enum MeshKind {
    /// Heckbert's constrained Delaunay triangulation.
    Cdt,
    /// Campbell & Fussell's BSP into convex pieces.
    Bsp,
}

/// Which critical segments constrain the mesh.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Events {
    /// D0 contacts and the EV/VE events of every emitter ([`scene_segments`]).
    #[default]
    All,
    /// The D0 contacts alone ([`super::discontinuity::scene_contacts`]): where objects touch or
    /// cross a receiver. What a quadtree cannot refine away; the penumbrae are left to the
    /// hierarchical solver's oracle.
    Contacts,
}

/// Settings of [`discontinuity_scene`].
/// The most pieces [`crate::solver::discontinuity::solve_hierarchical`]'s callers let a discontinuity mesh have (the CLI's cap
/// for the hierarchical top level): the hierarchical solver clusters a scene of more than 3 000
/// patches and links it in about linear memory (docs/scale.md), where the uniform solver's n²
/// couplings keep [`RemeshParams::cdt`]'s 10 000.
pub const HIERARCHICAL_MAX_PIECES: usize = 100_000;

#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct RemeshParams {
    pub kind: MeshKind,
    /// Refinement of the constrained Delaunay mesh (unused by BSP).
    pub cdt: CdtParams,
    /// Snapping length relative to each receiver's diameter ([`super::ReceiverPlane`]).
    pub snap: f64,
    /// Refuse scenes with more patches than this after meshing (the uniform solver's default cap).
    pub max_patches: usize,
    /// Grade the mesh to a budget of patches ([`super::grade`]); `None`: the pieces as they are.
    pub grade: Option<GradeParams>,
    /// Which critical segments constrain the mesh.
    pub events: Events,
}

impl RemeshParams {
    /// Constrained Delaunay with 20° refinement ([`CdtParams::quality`]).
    #[must_use]
    pub const fn cdt() -> RemeshParams {
        RemeshParams {
            kind: MeshKind::Cdt,
            cdt: CdtParams::quality(),
            snap: DEFAULT_SNAP,
            max_patches: 10_000,
            grade: None,
            events: Events::All,
        }
    }

    /// The BSP mesh.
    #[must_use]
    pub const fn bsp() -> RemeshParams {
        RemeshParams { kind: MeshKind::Bsp, ..RemeshParams::cdt() }
    }

    /// The **contact mesh**: every patch cut along where other patches touch it, or run within
    /// [`super::discontinuity::NEAR_CONTACT_GAP`] of it ([`Events::Contacts`]), by the BSP, and
    /// not graded: the top level that the hierarchical solver refines
    /// ([`crate::solver::discontinuity::solve_hierarchical`], `radlab solve --mesh contact`).
    /// A quadtree cannot refine a contact line away — an element straddling it holds the lit
    /// and the hidden side's average, and its error falls only as √h — while the penumbrae,
    /// which its oracle does refine, are left to it. The contact mesh's error keeps falling as
    /// the threshold is halved where the quadtree's stalls (docs/meshing.md#the-contact-mesh,
    /// docs/bench).
    #[must_use]
    pub const fn contacts() -> RemeshParams {
        RemeshParams { events: Events::Contacts, max_patches: HIERARCHICAL_MAX_PIECES, ..RemeshParams::bsp() }
    }

    /// The discontinuity mesh of a solve — the one construction behind `radlab solve|artifacts
    /// --mesh discontinuity-*`, `radlab reference --compare --mesh discontinuity-*` and the viewer's Mesh menu:
    /// `kind`; the CDT refined to `min_angle_deg` (`None`: 20° ungraded, unrefined when graded,
    /// since grading sizes the elements) and `max_area` (`None`: no limit); graded by `grade`;
    /// at most `max_patches` patches, raised to a fixed budget.
    pub fn for_solve(
        kind: MeshKind,
        min_angle_deg: Option<f64>,
        max_area: Option<f64>,
        grade: Option<GradeParams>,
        max_patches: usize,
    ) -> Result<RemeshParams, MeshError> {
        let mut p = RemeshParams { kind, max_patches, grade, ..RemeshParams::cdt() };
        p.cdt.min_angle_deg =
            min_angle_deg.unwrap_or(if grade.is_some() { 0.0 } else { p.cdt.min_angle_deg });
        if let Some(area) = max_area {
            p.cdt.max_area = area;
        }
        p.cdt.validate()?;
        if let Some(g) = grade {
            g.validate()?;
            if let super::grade::Budget::Patches(n) = g.budget {
                p.max_patches = p.max_patches.max(n);
            }
        }
        Ok(p)
    }
}

/// What [`discontinuity_scene`] did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RemeshStats {
    pub input_patches: usize,
    pub output_patches: usize,
    /// Receivers with at least one critical segment inside them (the ones replaced).
    pub receivers_meshed: usize,
    /// Critical segments found, summed over receivers.
    pub segments: SegmentCounts,
    /// Segments inserted into the meshes after clipping, snapping and deduplication.
    pub constraints: usize,
    /// Receivers whose CDT refinement stopped at the Steiner point cap.
    pub refinement_incomplete: usize,
    /// Pieces dropped because `Patch::new` rejected them (zero area), and their total area.
    pub pieces_dropped: usize,
    pub area_dropped: f64,
    /// What grading did, when it ran.
    pub graded: Option<GradeStats>,
    /// Wall time: finding segments, meshing, total (s).
    pub segments_s: f64,
    pub mesh_s: f64,
    pub total_s: f64,
}

impl RemeshStats {
    /// One line for logs: segments, constraints, receivers, patch counts and meshing time.
    #[must_use]
    pub fn describe(&self) -> String {
        let graded = self.graded.as_ref().map_or_else(String::new, |g| {
            let auto = if g.auto { " (auto)" } else { "" };
            format!(" (graded to a budget of {}{auto}: {} splits, {:.4} s)", g.budget, g.splits, g.grade_s)
        });
        format!(
            "{} critical segments, {} constraints on {} receivers, {} → {} patches{graded}; meshing {:.4} s",
            self.segments.total(),
            self.constraints,
            self.receivers_meshed,
            self.input_patches,
            self.output_patches,
            self.total_s
        )
    }
}

/// A scene on a discontinuity mesh, with each new patch's original.
#[derive(Clone, Debug)]
pub struct RemeshedScene {
    pub scene: Scene,
    /// `origin[i]`: the input patch new patch `i` was cut from.
    pub origin: Vec<usize>,
    pub stats: RemeshStats,
}

/// One receiver's result: pieces (polygons) or `None` (kept whole), counts, constraint count,
/// refinement complete, seconds finding segments and meshing.
type ReceiverResult = (Option<Vec<Vec<DVec3>>>, SegmentCounts, usize, bool, f64, f64);

/// `gap`: the near-contact gap of [`Events::Contacts`] in scene units (computed once per scene).
fn mesh_receiver(
    scene: &Scene,
    i: usize,
    params: &RemeshParams,
    accel: Option<&crate::geometry::accel::Accel>,
    gap: f64,
) -> Result<ReceiverResult, MeshError> {
    let t0 = Instant::now();
    let set = match params.events {
        Events::All => scene_segments(&scene.patches, i, params.snap)?,
        Events::Contacts => super::discontinuity::scene_contacts(&scene.patches, i, params.snap, gap)?,
    };
    // Graded: only the segments that bound a shadow the direct light shows.
    let ends = match (accel, &params.grade) {
        (Some(accel), Some(g)) => super::grade::shadow_segments(scene, accel, i, &set, g.side),
        _ => set.endpoints(),
    };
    let t_seg = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let plane = ReceiverPlane::new(&scene.patches[i].vertices, params.snap)?;
    let constraints = plane.prepare(&ends).len();
    if constraints == 0 {
        return Ok((None, set.counts, 0, true, t_seg, t1.elapsed().as_secs_f64()));
    }
    let (pieces, complete) = match params.kind {
        MeshKind::Cdt => {
            let m = triangulate(&plane, &ends, &params.cdt)?;
            (m.triangles.into_iter().map(|t| t.vertices.to_vec()).collect(), m.refinement_complete)
        }
        MeshKind::Bsp => (partition(&plane, &ends).pieces, true),
    };
    Ok((Some(pieces), set.counts, constraints, complete, t_seg, t1.elapsed().as_secs_f64()))
}

/// Polygons of at most 4 vertices: triangles and quads as they are, larger convex polygons
/// fanned from their first vertex.
fn patch_polygons(piece: Vec<DVec3>) -> Vec<Vec<DVec3>> {
    if piece.len() <= 4 {
        return vec![piece];
    }
    (1..piece.len() - 1).map(|k| vec![piece[0], piece[k], piece[k + 1]]).collect()
}

/// Remesh every receiver of `scene` that has critical segments (see the module docs).
pub fn discontinuity_scene(scene: &Scene, params: &RemeshParams) -> Result<RemeshedScene, MeshError> {
    params.cdt.validate()?;
    if let Some(g) = &params.grade {
        g.validate()?;
    }
    let t0 = Instant::now();
    let accel = params.grade.is_some().then(|| crate::geometry::accel::Accel::build(scene));
    let gap = match params.events {
        Events::All => 0.0,
        Events::Contacts => super::discontinuity::NEAR_CONTACT_GAP * scene.bounds().diagonal(),
    };
    let results: Vec<ReceiverResult> = (0..scene.patches.len())
        .into_par_iter()
        .map(|i| mesh_receiver(scene, i, params, accel.as_ref(), gap))
        .collect::<Result<_, _>>()?;
    let mut stats = RemeshStats { input_patches: scene.patches.len(), ..RemeshStats::default() };
    // Every input patch as convex pieces: its mesh's, or itself.
    let mut pieces: Vec<Piece> = Vec::new();
    for (i, (meshed, counts, constraints, complete, t_seg, t_mesh)) in results.into_iter().enumerate() {
        stats.segments = stats.segments.plus(counts);
        stats.constraints += constraints;
        stats.refinement_incomplete += usize::from(!complete);
        stats.segments_s += t_seg;
        stats.mesh_s += t_mesh;
        match meshed {
            Some(polygons) => {
                stats.receivers_meshed += 1;
                pieces.extend(polygons.into_iter().map(|vertices| Piece { patch: i, vertices }));
            }
            None => pieces.push(Piece { patch: i, vertices: scene.patches[i].vertices.clone() }),
        }
    }
    // Grading only adds patches: refuse a mesh already over the cap before spending its time
    // (splash_room's kept segments cross into 548 137 pieces).
    let count: usize = pieces.iter().map(|p| super::grade::patch_cost(p.vertices.len())).sum();
    if count > params.max_patches {
        return Err(MeshError::TooManyPatches { count, cap: params.max_patches });
    }
    if let (Some(g), Some(accel)) = (&params.grade, &accel) {
        let (graded, g_stats) = grade(scene, accel, pieces, g, params.max_patches);
        pieces = graded;
        stats.graded = Some(g_stats);
    }
    let (mut patches, mut origin) = (Vec::new(), Vec::new());
    let mut serial = vec![0usize; scene.patches.len()];
    for piece in pieces {
        let i = piece.patch;
        let p = &scene.patches[i];
        let whole = piece.vertices == p.vertices;
        for verts in patch_polygons(piece.vertices) {
            if whole {
                patches.push(p.clone());
                origin.push(i);
                continue;
            }
            let k = serial[i];
            serial[i] += 1;
            let area = crate::math::polygon_area(&verts);
            let name = format!("{}/dm{k}", p.name);
            match p.piece(verts, name) {
                Ok(piece) => {
                    patches.push(piece);
                    origin.push(i);
                }
                Err(_) => {
                    stats.pieces_dropped += 1;
                    stats.area_dropped += area;
                }
            }
        }
        if patches.len() > params.max_patches {
            return Err(MeshError::TooManyPatches { count: patches.len(), cap: params.max_patches });
        }
    }
    stats.output_patches = patches.len();
    stats.total_s = t0.elapsed().as_secs_f64();
    let mut out = Scene::new(scene.name.clone(), scene.source.clone(), patches);
    out.warnings.clone_from(&scene.warnings);
    out.camera = scene.camera;
    Ok(RemeshedScene { scene: out, origin, stats })
}

/// Make the pieces of every input patch meet corner to corner: each corner of a piece that lies
/// inside another piece's edge of the same input patch (a T-vertex: Campbell & Fussell's BSP cuts
/// one cell at a time, so its neighbours' edges run past the cut's end) is inserted into that
/// edge, and a piece that gained corners is replaced by the fan of triangles from its centroid
/// to each of its edges (one triangle per edge, corners inserted included). The CDT is
/// conforming already; graded meshes are not made so (grading refuses a continuous basis). Used
/// by the continuous p = 1 solve on the BSP mesh, whose vertex values are shared by position.
/// Returns the T-vertices inserted.
pub fn conform(meshed: &mut RemeshedScene, input: &Scene) -> usize {
    let n = meshed.scene.patches.len();
    let mut by_origin = vec![Vec::new(); input.patches.len()];
    for q in 0..n {
        by_origin[meshed.origin[q]].push(q);
    }
    let mut inserted = 0;
    let (mut patches, mut origin) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut serial = vec![0usize; input.patches.len()];
    for q in 0..n {
        let o = meshed.origin[q];
        let tol = 1e-9 * input.patches[o].diameter();
        let own = &meshed.scene.patches[q].vertices;
        let mut verts = Vec::with_capacity(own.len());
        for k in 0..own.len() {
            let (a, b) = (own[k], own[(k + 1) % own.len()]);
            verts.push(a);
            let d = b - a;
            let mut hanging: Vec<(f64, DVec3)> = by_origin[o]
                .iter()
                .filter(|&&r| r != q)
                .flat_map(|&r| meshed.scene.patches[r].vertices.iter().copied())
                .filter_map(|v| {
                    let s = (v - a).dot(d) / d.length_squared();
                    (s > 1e-9 && s < 1.0 - 1e-9 && (a + d * s).distance(v) <= tol).then_some((s, v))
                })
                .collect();
            hanging.sort_by(|x, y| x.0.total_cmp(&y.0));
            hanging.dedup_by(|x, y| x.1.distance(y.1) <= tol);
            inserted += hanging.len();
            verts.extend(hanging.into_iter().map(|(_, v)| v));
        }
        if verts.len() == own.len() {
            patches.push(meshed.scene.patches[q].clone());
            origin.push(o);
            continue;
        }
        // A fan from the centre: a fan from a corner would leave out the zero-area triangles
        // along an edge that gained corners, and the triangle beside them would keep them hanging.
        let c = crate::math::polygon_centroid(own);
        for k in 0..verts.len() {
            let tri = vec![c, verts[k], verts[(k + 1) % verts.len()]];
            let name = format!("{}/conformed{}", input.patches[o].name, serial[o]);
            serial[o] += 1;
            if let Ok(p) = input.patches[o].piece(tri, name) {
                patches.push(p);
                origin.push(o);
            }
        }
    }
    meshed.stats.output_patches = patches.len();
    let mut scene = Scene::new(meshed.scene.name.clone(), meshed.scene.source.clone(), patches);
    scene.warnings.clone_from(&meshed.scene.warnings);
    scene.camera = meshed.scene.camera;
    meshed.scene = scene;
    meshed.origin = origin;
    inserted
}
