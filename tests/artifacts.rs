//! The five meshing artifacts ([`radlab::eval::artifacts`]) on cases built to have each and cases built
//! not to: shadow-narrow against its closed form, solved coarse (one element a patch, or 4 × 4 on
//! the floor) and on a discontinuity mesh; the furnace (B = 2 everywhere, nothing to see); and a
//! solution scored against its own reconstruction (every artifact of the comparison vanishes).
//!
//! Run with `--nocapture` to see the figures.

use radlab::eval::artifacts::{ArtifactParams, ArtifactReport, Gouraud, measure};
use radlab::eval::pointwise::PiecewiseConstant;
use radlab::geometry::accel::Accel;
use radlab::geometry::exact::SingleBounce;
use radlab::math::{DVec3, Rgb};
use radlab::scene::Scene;
use radlab::solver::Solution;
use radlab::solver::discontinuity::{self, DiscontinuityParams};
use radlab::solver::uniform::{self, COARSE_FF_TOLERANCE, UniformParams};

fn uniform_solve(scene: &Scene, element_size: f64) -> Solution {
    let accel = Accel::build(scene);
    let p = UniformParams { element_size, ff_tolerance: COARSE_FF_TOLERANCE, ..UniformParams::default() };
    uniform::solve(scene, &accel, &p, &mut |_, _| {}).unwrap()
}

fn against_exact(scene: &Scene, sol: &Solution) -> ArtifactReport {
    let sb = SingleBounce::new(scene).unwrap();
    let exact = |p: usize, x: DVec3| sb.patch_radiosity_at(p, x);
    let r = measure(scene, sol, &exact, &ArtifactParams::quick()).unwrap();
    println!("{} ({} elements): {r:?}", sol.method, sol.elements.len());
    r
}

/// One element a patch: a constant floor shows neither the shadow nor the bright spot under
/// the lamp (B: every feature missing), is all error in the penumbra (A), and its only element
/// holds every critical segment (E = 1); with no interior edge it can neither jump nor kink
/// (C = D = 0).
#[test]
fn one_element_a_patch_misses_every_feature() {
    let scene = Scene::load("builtin:shadow-narrow").unwrap();
    let r = against_exact(&scene, &uniform_solve(&scene, f64::INFINITY));
    let a = r.blocky_shadows.expect("shadow-narrow has a penumbra");
    assert!(a > 0.3, "A = {a}");
    let b = r.missing_features;
    assert!(b.features >= 2 && b.missing == b.features, "B: {b:?}");
    assert_eq!(r.shading_jumps.edge_length, 0.0);
    assert!(r.unresolved.segments > 0);
    assert!(r.unresolved.fraction() > 0.999, "E = {}", r.unresolved.fraction());
    assert!(r.unresolved.error_beside.unwrap() > 0.1);
    assert_eq!(r.mach_bands.edge_length, 0.0, "no interior edge: no Mach band");
}

/// A coarse uniform mesh jumps between its elements where the closed form is smooth (D), kinks
/// there when Gouraud-shaded (C), and its edges do not follow the shadow's boundaries (E); the discontinuity mesh follows them.
#[test]
fn coarse_mesh_jumps_and_leaves_discontinuities_inside_elements() {
    let scene = Scene::load("builtin:shadow-narrow").unwrap();
    let coarse = against_exact(&scene, &uniform_solve(&scene, 0.5));
    assert!(coarse.shading_jumps.edge_length > 0.0);
    assert!(coarse.shading_jumps.fraction() > 0.2, "D = {:?}", coarse.shading_jumps);
    assert!(coarse.unresolved.fraction() > 0.5, "E = {:?}", coarse.unresolved);
    assert!(coarse.mach_bands.fraction() > 0.2, "C = {:?}", coarse.mach_bands);

    let d = discontinuity::solve(&scene, &DiscontinuityParams::cdt(), &mut |_, _| {}).unwrap();
    let dm = against_exact(&scene, &d.solution);
    assert!(dm.unresolved.fraction() < 0.05, "D-mesh E = {:?}", dm.unresolved);
    assert!(dm.unresolved.fraction() < coarse.unresolved.fraction());
    assert!(dm.blocky_shadows.unwrap() < coarse.blocky_shadows.unwrap());
    assert!(dm.missing_features.fraction() <= coarse.missing_features.fraction());
}

/// A solution against its own reconstruction: every jump is the reference's own (D = 0), every
/// feature is shown (B = 0), no error anywhere (A = 0, E's error 0) — the segments still fall
/// inside elements (E's length is geometry, not error); against its own Gouraud reconstruction,
/// every kink is the reference's own (C = 0).
#[test]
fn a_solution_against_itself_has_no_artifacts() {
    let scene = Scene::load("builtin:shadow-narrow").unwrap();
    let sol = uniform_solve(&scene, 0.5);
    let own = PiecewiseConstant::new(&scene, &sol.elements).unwrap();
    let r = measure(&scene, &sol, &own, &ArtifactParams::quick()).unwrap();
    println!("against itself: {r:?}");
    assert!(r.blocky_shadows.unwrap_or(0.0) < 1e-12, "A = {:?}", r.blocky_shadows);
    assert!(r.missing_features.features > 0 && r.missing_features.missing == 0, "{:?}", r.missing_features);
    assert!(r.shading_jumps.edge_length > 0.0 && r.shading_jumps.inappropriate_length == 0.0);
    assert!(r.unresolved.fraction() > 0.0);
    // Against its own flat reconstruction G's kinks are G's alone: C counts them (it compares
    // what a viewer draws with the reference), so only the Gouraud reconstruction itself as the
    // reference has none.
    let gouraud = Gouraud::new(&scene, &sol).unwrap();
    let g = measure(&scene, &sol, &gouraud, &ArtifactParams::quick()).unwrap();
    assert!(g.mach_bands.edge_length > 0.0 && g.mach_bands.band_length == 0.0, "{:?}", g.mach_bands);
    assert!(r.unresolved.error_beside.unwrap_or(0.0) < 1e-12);
}

/// The furnace: B = E / (1 − ρ) = 2 on every face, no shadow, no highlight, no jump, no kink.
#[test]
fn furnace_has_no_artifacts() {
    let scene = Scene::load("builtin:furnace").unwrap();
    let sol = uniform_solve(&scene, 0.25);
    let two = |_: usize, _: DVec3| Rgb::splat(2.0);
    let r = measure(&scene, &sol, &two, &ArtifactParams::quick()).unwrap();
    println!("furnace: {r:?}");
    assert_eq!(r.blocky_shadows, None, "no penumbra");
    assert_eq!(r.missing_features.features, 0);
    assert!(r.shading_jumps.edge_length > 0.0);
    assert_eq!(r.shading_jumps.inappropriate_length, 0.0, "{:?}", r.shading_jumps);
    assert_eq!(r.unresolved.unresolved_length, 0.0, "{:?}", r.unresolved);
    assert_eq!(r.mach_bands.band_length, 0.0, "{:?}", r.mach_bands);
}

/// `radlab reference SCENE --exact --compare` prints the table; the D-mesh leaves no
/// critical segment inside an element.
#[test]
fn cli_prints_the_artifacts_table() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("artifacts-cli-cache");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
        .args([
            "reference",
            "builtin:shadow-narrow",
            "--samples",
            "16",
            "--exact",
            "--compare",
            "--mesh",
            "discontinuity-bsp",
        ])
        .arg("--cache-dir")
        .arg(&cache)
        .output()
        .unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{text}");
    for row in ["A blocky shadows", "B missing features", "C Mach bands"] {
        assert!(text.contains(row), "no row {row:?} in:\n{text}");
    }
    assert!(text.contains("D shading discontinuities"), "{text}");
    assert!(text.contains("E unresolved              0.0 %"), "{text}");
}

/// The thin occluder: on `builtin:thin-pole` the pole's shadow — a streak a few
/// hundredths wide from its foot outward — is a feature of the closed form (B: its points lie
/// far below the floor's mean). The hierarchical solver with the lecture's Feps oracle
/// (`lecture`: refine where much light flows) misses it: its links from the floor to the small
/// lamp see the pole with none of their rays, the floor is not subdivided there, and every point
/// of the streak belongs to a missing feature. The error oracle (`quality`, on the same
/// quadtree) refines where the floor's answer is wrong and shows it, and so does the
/// discontinuity mesh (CDT), which puts element edges on the pole's shadow boundaries.
#[test]
fn thin_pole_shadow_missed_by_the_feps_oracle_shown_by_the_error_oracle_and_the_cdt() {
    use radlab::eval::artifacts::measure_views;
    use radlab::solver::hierarchical::HierarchicalSolver;
    use radlab::solver::params::HierarchicalParams;
    let scene = Scene::load("builtin:thin-pole").unwrap();
    let sb = SingleBounce::new(&scene).unwrap();
    let exact = |p: usize, x: DVec3| sb.patch_radiosity_at(p, x);
    // Marks (+1 shown, −1 missing) of the grid points in the streak behind the pole: beyond the
    // pole (x > 0.37; it stands at 0.34…0.36, its shadow's tip near 0.9), near the axis
    // (|z| < 0.05), and darker than half the floor's mean in the closed form.
    let streak_marks = |sol: &Solution| {
        let pc = PiecewiseConstant::new(&scene, &sol.elements).unwrap();
        let gouraud = Gouraud::new(&scene, sol).unwrap();
        let (report, maps) =
            measure_views(&scene, sol, &pc, &gouraud, &exact, &ArtifactParams::standard()).unwrap();
        let marks: Vec<i8> = maps
            .points
            .iter()
            .zip(maps.features.iter().zip(&maps.reference))
            .filter(|(p, (_, r))| {
                p.position.x > 0.37 && p.position.z.abs() < 0.05 && r.mean() < 0.5 * maps.means[p.patch].0
            })
            .map(|(_, (&m, _))| m)
            .collect();
        println!(
            "{} ({} elements): streak marks {marks:?}, B {:?}",
            sol.method,
            sol.elements.len(),
            report.missing_features
        );
        marks
    };
    let quadtree = |preset: &str| {
        let params = HierarchicalParams::preset(preset).unwrap();
        let mut h = HierarchicalSolver::new(std::sync::Arc::new(scene.clone()), params).unwrap();
        h.solve(&mut |_, _| {});
        streak_marks(&h.solution())
    };
    // (0: a fragment of the streak too small to count as a feature — fewer than 4 grid points.)
    let count = |marks: &[i8], m: i8| marks.iter().filter(|&&x| x == m).count();
    let feps = quadtree("lecture");
    assert!(count(&feps, -1) >= 8, "the streak is a missing feature: {feps:?}");
    assert_eq!(count(&feps, 1), 0, "the Feps oracle shows (part of) the pole's shadow: {feps:?}");

    let error = quadtree("quality");
    assert_eq!(error.len(), feps.len(), "same grid");
    assert!(count(&error, 1) >= 8, "the streak is a feature the error oracle shows: {error:?}");
    assert_eq!(count(&error, -1), 0, "the error oracle misses (part of) the pole's shadow: {error:?}");

    let d = discontinuity::solve(&scene, &DiscontinuityParams::cdt(), &mut |_, _| {}).unwrap();
    let cdt = streak_marks(&d.solution);
    assert_eq!(cdt.len(), feps.len(), "same grid");
    assert!(count(&cdt, 1) >= 8, "the streak is a feature the CDT shows: {cdt:?}");
    assert_eq!(count(&cdt, -1), 0, "the CDT misses (part of) the pole's shadow: {cdt:?}");
}

#[test]
fn samples_add_up_to_the_report() {
    use radlab::eval::artifacts::{EdgeMark, measure_samples};
    let scene = Scene::load("builtin:shadow-narrow").unwrap();
    let accel = Accel::build(&scene);
    let p = UniformParams { element_size: 0.5, ..Default::default() };
    let sol = uniform::solve(&scene, &accel, &p, &mut |_, _| {}).unwrap();
    let sb = SingleBounce::new(&scene).unwrap();
    let exact = |patch: usize, x: DVec3| sb.patch_radiosity_at(patch, x);
    let params = ArtifactParams::quick();
    let (r, s) = measure_samples(&scene, &sol, &exact, &params).unwrap();
    assert_eq!(r.blocky_shadows, measure(&scene, &sol, &exact, &params).unwrap().blocky_shadows);
    assert_eq!(s.band.len(), r.band_points);
    assert!(s.band.iter().any(|m| m.value > 0.1), "the coarse mesh errs in the penumbra");
    assert!(!s.features.is_empty() && s.features.iter().all(|m| m.patch == sb.receiver));
    // Each interior edge is sampled from both of its elements: half its length each time.
    let length = |pick: &dyn Fn(&EdgeMark) -> bool| -> f64 {
        s.edges.iter().filter(|e| pick(e)).map(|e| e.length / 2.0).sum()
    };
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.max(1.0);
    assert!(
        close(length(&|_| true), r.shading_jumps.edge_length),
        "{} vs {:?}",
        length(&|_| true),
        r.shading_jumps
    );
    assert!(close(length(&|e| e.jump), r.shading_jumps.inappropriate_length));
    assert!(close(length(&|e| e.mach_band), r.mach_bands.band_length));
    let unresolved: f64 = s.segments.iter().filter(|m| m.unresolved).map(|m| m.length).sum();
    assert!(close(unresolved, r.unresolved.unresolved_length), "{unresolved} vs {:?}", r.unresolved);
    assert!(s.segments.iter().any(|m| m.unresolved), "a 0.5 mesh leaves segments inside elements");
}

/// E scores only the critical segments that bound a shadow (`mesh::grade::shadow_segments`), the
/// ones a graded D-mesh keeps: on table-room's floor the D1/D2 segments inside the table's umbra
/// bound nothing and are dropped. A floor meshed by the CDT of its kept segments alone leaves the
/// dropped ones inside its triangles (checked below) and must read E ≈ 0; the floor as one
/// element leaves the kept ones inside it and must read E ≈ 100 %, over the same segments.
#[test]
fn dropped_segments_inside_elements_do_not_count_kept_ones_do() {
    use radlab::mesh::cdt::{CdtParams, triangulate};
    use radlab::mesh::discontinuity::scene_segments;
    use radlab::mesh::grade::shadow_segments;
    use radlab::mesh::{DEFAULT_SNAP, ReceiverPlane};
    use radlab::solver::SolvedElement;
    let scene = Scene::load("builtin:table-room").unwrap();
    let accel = Accel::build(&scene);
    let floor = scene.patches.iter().position(|p| p.name == "floor/0/0").unwrap();
    let set = scene_segments(&scene.patches, floor, DEFAULT_SNAP).unwrap();
    let params = ArtifactParams { side: 16, ..ArtifactParams::quick() };
    let kept = shadow_segments(&scene, &accel, floor, &set, params.shadow_side);
    assert!(!kept.is_empty() && kept.len() < set.segments.len(), "{} of {}", kept.len(), set.segments.len());

    // One element a patch; then the floor's element replaced by the CDT of its kept segments.
    let whole = uniform_solve(&scene, f64::INFINITY);
    let plane = ReceiverPlane::new(&scene.patches[floor].vertices, DEFAULT_SNAP).unwrap();
    let cdt = triangulate(&plane, &kept, &CdtParams { min_angle_deg: 0.0, ..CdtParams::quality() }).unwrap();
    let value = whole.elements.iter().find(|e| e.patch == floor).unwrap().radiosity;
    let mut meshed = whole.clone();
    meshed.elements.retain(|e| e.patch != floor);
    meshed.elements.extend(cdt.triangles.iter().map(|t| {
        SolvedElement::constant(floor, t.vertices.to_vec(), radlab::math::polygon_area(&t.vertices), value)
    }));
    // The case is real: some dropped segment's midpoint lies inside a triangle, farther than
    // 10⁻³ of the floor's size from each of its edges (E's `on_edge` is 10⁻⁴).
    let normal = scene.patches[floor].normal;
    let margin = 1e-3 * scene.patches[floor].diameter();
    let inside_a_triangle = |x: DVec3| {
        cdt.triangles.iter().any(|t| {
            let v = &t.vertices;
            (0..3).all(|k| {
                let (a, b, opposite) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
                let n = (b - a).cross(normal).normalize();
                n.dot(x - a) * n.dot(opposite - a).signum() > margin
            })
        })
    };
    let dropped_inside = set
        .segments
        .iter()
        .filter(|s| !kept.contains(&[s.a, s.b]) && inside_a_triangle(s.a.lerp(s.b, 0.5)))
        .count();
    assert!(dropped_inside > 0, "no dropped segment lies inside a triangle");

    let reference = PiecewiseConstant::new(&scene, &whole.elements).unwrap();
    let e_meshed = measure(&scene, &meshed, &reference, &params).unwrap().unresolved;
    let e_whole = measure(&scene, &whole, &reference, &params).unwrap().unresolved;
    println!("floor on its kept segments: {e_meshed:?}; one element a patch: {e_whole:?}");
    assert_eq!(e_meshed.segments, e_whole.segments, "the same segments are scored");
    assert_eq!(e_meshed.dropped, e_whole.dropped);
    assert!(e_whole.dropped >= set.segments.len() - kept.len(), "{e_whole:?}");
    // One element a patch: every kept segment lies inside an element.
    assert!(e_whole.fraction() > 0.999, "kept segments inside elements not counted: {e_whole:?}");
    // The floor on its kept segments resolves exactly the floor's kept length (the other
    // patches' segments stay inside their single elements); its dropped ones add nothing.
    let floor_kept: f64 = kept.iter().map(|[a, b]| a.distance(*b)).sum();
    let resolved = e_whole.unresolved_length - e_meshed.unresolved_length;
    assert!(
        (resolved - floor_kept).abs() < 1e-6 * floor_kept,
        "resolved {resolved} of the floor's kept {floor_kept}: {e_meshed:?}"
    );
}

/// E on a non-conforming mesh: cornell's CDT graded to 600 pieces (cuts leave T-vertices) puts
/// every shadow-bounding segment on an element edge, but a few of E's samples on those edges lie
/// outside every element by a rounding error, where the point locator falls back to the nearest
/// centroid. Measured before they were caught: E 0.30 % (6 samples; 1.4 % at 1 448 pieces, the
/// figure docs/meshing.md reported); now 0. Values do not matter to E: a solve without shadow
/// rays, measured against itself.
#[test]
fn graded_mesh_resolves_its_segments_across_t_vertices() {
    use radlab::mesh::grade::GradeParams;
    let scene = Scene::load("builtin:cornell").unwrap();
    let mut params = DiscontinuityParams::cdt();
    params.mesh.cdt.min_angle_deg = 0.0;
    params.mesh.grade = Some(GradeParams::with_budget(600));
    params.solve.rays = 0;
    let d = discontinuity::solve(&scene, &params, &mut |_, _| {}).unwrap();
    assert_eq!(d.solution.elements.len(), 600);
    let own = PiecewiseConstant::new(&scene, &d.solution.elements).unwrap();
    let e = measure(&scene, &d.solution, &own, &ArtifactParams::quick()).unwrap().unresolved;
    println!("cornell, graded CDT (600): E {e:?}");
    assert!(e.segments > 100, "{e:?}");
    assert_eq!(e.unresolved_length, 0.0, "{e:?}");
}
