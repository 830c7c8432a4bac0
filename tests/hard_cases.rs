//! The hard-case suite: every solver on every generated hard case (src/studies/hard_cases.rs).
//!
//! Each (case, solver) asserts: every B finite and ≥ 0; the energy balance within the solver's
//! stated tolerance; per-patch agreement with the closed form (where the case has one) or with
//! the independent reference; refinement within an element/link budget. Translation and uniform
//! scaling are tested as invariances. A failure names the case, the solver and the figure.

use radlab::eval::reference::{Estimate, RefElement, ReferenceParams, estimate_elements};
use radlab::geometry::accel::Accel;
use radlab::math::{DVec3, Rgb};
use radlab::scene::Scene;
use radlab::solver::Solution;
use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::params::AreaEps;
use radlab::solver::params::HierarchicalParams;
use radlab::solver::progressive::{self, ProgressiveParams};
use radlab::solver::uniform::{self, UniformParams};
use radlab::studies::hard_cases::{self, HardCase};
use std::sync::atomic::Ordering;
use std::sync::{Arc, mpsc};
use std::time::Duration;

/// The hierarchical presets run with this minimum element area (fraction of the scene's area)
/// so the suite stays fast in CI; everything else is the preset's.
const CI_AEPS: f64 = 1e-3;
/// Wall-clock budget of one hierarchical solve (dev profile, 2 cores): refinement that does not
/// terminate by then fails the test.
const SOLVE_BUDGET_S: f64 = 20.0;

/// The solvers under test, each with settings small enough for CI.
#[derive(Copy, Clone, Debug)]
enum Solver {
    Uniform,
    Progressive,
    /// A hierarchical preset by name.
    Hierarchical(&'static str),
}

const SOLVERS: [Solver; 4] = [
    Solver::Uniform,
    Solver::Progressive,
    Solver::Hierarchical("interactive"),
    Solver::Hierarchical("lecture"),
];

impl Solver {
    fn label(self) -> String {
        match self {
            Solver::Uniform => "uniform".into(),
            Solver::Progressive => "progressive".into(),
            Solver::Hierarchical(p) => format!("hierarchical/{p}"),
        }
    }

    /// Solve; `Err` when a hierarchical solve does not finish within the budget.
    fn solve(self, scene: &Scene) -> Result<Solution, String> {
        let d = scene.bounds().diagonal();
        let scene = Arc::new(scene.clone());
        let accel = Accel::build(&scene);
        match self {
            Solver::Uniform => {
                let p = UniformParams {
                    element_size: d / 8.0,
                    rays: 16,
                    ff_tolerance: uniform::COARSE_FF_TOLERANCE,
                    ..UniformParams::default()
                };
                uniform::solve(&scene, &accel, &p, &mut |_, _| {})
            }
            Solver::Progressive => {
                let p = ProgressiveParams {
                    element_size: d / 8.0,
                    rays: 16,
                    tolerance: PROGRESSIVE_TOLERANCE,
                    ff_tolerance: uniform::COARSE_FF_TOLERANCE,
                    ..ProgressiveParams::default()
                };
                progressive::solve(&scene, &accel, &p, &mut |_, _| {})
            }
            Solver::Hierarchical(preset) => {
                let p = HierarchicalParams {
                    aeps: AreaEps::Relative(CI_AEPS),
                    ..HierarchicalParams::preset(preset).unwrap()
                };
                let mut s = HierarchicalSolver::new(scene, p)?;
                // Refinement must terminate within a time budget: a watchdog cancels the solve.
                let cancel = s.cancel_handle();
                let (tx, rx) = mpsc::channel::<()>();
                let watchdog = std::thread::spawn(move || {
                    if rx.recv_timeout(Duration::from_secs_f64(SOLVE_BUDGET_S))
                        == Err(mpsc::RecvTimeoutError::Timeout)
                    {
                        cancel.store(true, Ordering::Relaxed);
                    }
                });
                let report = s.solve(&mut |_, _| {});
                let _ = tx.send(());
                let _ = watchdog.join();
                if report.cancelled {
                    Err(format!("did not finish within {SOLVE_BUDGET_S} s ({} elements)", s.stats().elements))
                } else {
                    Ok(s.solution())
                }
            }
        }
    }
}

/// Progressive refinement stops when the unshot power is this fraction of the emitted power.
const PROGRESSIVE_TOLERANCE: f64 = 1e-4;

/// Energy-balance tolerance per solver (|emitted − absorbed − escaped| / emitted).
fn energy_tolerance(s: Solver) -> f64 {
    match s {
        // Gauss–Seidel to 1e-6 relative change; the matrix rows are exact sums of the same F·V.
        Solver::Uniform => 1e-4,
        // The balance misses exactly the unshot power, ≤ PROGRESSIVE_TOLERANCE.
        Solver::Progressive => 2.0 * PROGRESSIVE_TOLERANCE,
        // Link form factors are point-to-polygon estimates at the receiver's centroid, so the
        // leaving and arriving power differ by the discretisation error; measured ≤ 2.9e-2
        // (boxes_on_floor) on the cases that pass.
        Solver::Hierarchical(_) => 0.05,
    }
}

/// Element and link budget per solver: refinement must terminate below these on every case.
fn budget(s: Solver) -> (usize, usize) {
    match s {
        Solver::Uniform | Solver::Progressive => (10_000, 10_000 * 10_000),
        Solver::Hierarchical(_) => (200_000, 5_000_000),
    }
}

/// Per-patch agreement: |B − B_ref| ≤ Z·σ_ref + REL·max(|B_ref − E|, floor) (mean over channels).
const Z: f64 = 4.0;

/// Relative agreement of a patch average with the reference or closed form, per solver and case.
fn agreement(s: Solver, case: &str) -> f64 {
    if case == "occluded_emitter" {
        // The shell's ceiling is lit only through a 0.05-wide gap around the lamp, a quarter of an
        // element at h = d/8: uniform gives 0.0188, 0.0138, 0.0130 at h = d/8, d/16, d/32 against
        // the reference's 0.0125 ± 0.0002 — discretisation error that shrinks with h, not a bug.
        return 0.6;
    }
    match s {
        // Measured worst 0.121 (boxes_on_floor, h = d/8): piecewise-constant elements at contacts.
        Solver::Uniform | Solver::Progressive => 0.15,
        // Measured worst 0.21 (boxes_on_floor, interactive at CI_AEPS).
        Solver::Hierarchical(_) => 0.25,
    }
}

/// Known solver failures found by this suite (case, solver, what is wrong). They are still run
/// and printed; the test fails if one of them starts passing, so this list stays true. Remove an
/// entry when its solver is fixed.
///
/// None at present. The near-singular furnace (ρ = 0.999 amplifies a leaf's row error ~1000×)
/// meets its checks under the hierarchical presets because the rows of enclosed leaves are
/// closed (`HierarchicalParams::close_rows`).
const KNOWN_ISSUES: [(&str, &str, &str); 0] = [];

fn known_issue(case: &str, solver: Solver) -> Option<&'static str> {
    let label = solver.label();
    KNOWN_ISSUES.iter().find(|(c, s, _)| *c == case && *s == label).map(|(_, _, what)| *what)
}

/// ρ = 0.999 in a closed box converges like ρ^k: no solver reaches B = 1000 within its iteration
/// cap. There the suite checks honesty instead of agreement: no patch overshoots the exact value,
/// the energy residual reports the missing part (in the furnace the missing fraction of B equals
/// the missing fraction of absorbed power), and the solvers that iterate (not progressive) are at
/// most ρ^iterations from the answer (the Jacobi bound; Gauss–Seidel only does better).
const NEAR_SINGULAR: &str = "furnace_0999";
/// |missing fraction of B − energy residual|: measured ≤ 0.008 (uniform 0.141 vs 0.133).
const NEAR_SINGULAR_CONSISTENCY: f64 = 0.02;
/// Slack on the ρ^iterations bound and on "no overshoot" (relative).
const NEAR_SINGULAR_SLACK: f64 = 0.01;

fn reference_per_patch(scene: &Scene, samples: u32) -> Vec<Estimate> {
    let acc = Accel::build(scene);
    let els: Vec<RefElement> = scene
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| RefElement { patch: i, vertices: p.vertices.clone() })
        .collect();
    estimate_elements(scene, &acc, &els, &ReferenceParams { samples, ..ReferenceParams::quick() }).unwrap()
}

/// Check one solution; returns the failures as lines (case, solver, figure).
fn check(case: &HardCase, solver: Solver, sol: &Solution, reference: &[Estimate], log: bool) -> Vec<String> {
    let name = format!("{} / {}", case.name, solver.label());
    let mut fails = Vec::new();
    for (i, e) in sol.elements.iter().enumerate() {
        if !(e.radiosity.is_finite() && e.radiosity.min_channel() >= 0.0) {
            fails.push(format!("{name}: element {i} (patch {}) has B = {:?}", e.patch, e.radiosity));
            break;
        }
    }
    let res = sol.energy.relative_residual();
    if case.name == NEAR_SINGULAR {
        check_near_singular(case, solver, sol, &name, &mut fails);
        if log {
            eprintln!(
                "{name:<48} elements {:>6} links {:>8} energy {res:>9.2e} iterations {}",
                sol.elements.len(),
                sol.stats.links,
                sol.stats.iterations
            );
        }
        return fails;
    }
    if !(res <= energy_tolerance(solver)) {
        fails.push(format!(
            "{name}: energy residual {res:.3e} > {:.1e} ({:?})",
            energy_tolerance(solver),
            sol.energy
        ));
    }
    let (max_el, max_links) = budget(solver);
    if sol.elements.len() > max_el || sol.stats.links > max_links {
        fails.push(format!(
            "{name}: {} elements, {} links over budget ({max_el}, {max_links})",
            sol.elements.len(),
            sol.stats.links
        ));
    }
    let scene = &case.scene;
    let floor = scene_floor(scene, reference);
    let mut worst = 0.0f64;
    for (p, patch) in scene.patches.iter().enumerate() {
        let b = sol.patch_radiosity[p];
        let (want, sigma, why) = match case.expected.iter().find(|e| e.patch == p) {
            Some(e) => (e.radiosity, Rgb::ZERO, e.why),
            None => (reference[p].radiosity, reference[p].std_error, "reference"),
        };
        let scale = (want - patch.emission).map(f64::abs).mean().max(floor);
        let d = (b - want).map(f64::abs).mean();
        let allowed = Z * sigma.mean() + agreement(solver, case.name) * scale;
        worst = worst.max(d / scale);
        if !(d <= allowed) {
            fails.push(format!(
                "{name}: patch {p} ({}) B = {:.5} vs {why} {:.5} ± {:.1e}: off by {:.3} of its reflected radiosity (allowed {:.3})",
                patch.name,
                b.mean(),
                want.mean(),
                sigma.mean(),
                d / scale,
                allowed / scale
            ));
        }
    }
    if log {
        eprintln!(
            "{name:<48} elements {:>6} links {:>8} energy {res:>9.2e} worst patch {:>6.3}",
            sol.elements.len(),
            sol.stats.links,
            worst
        );
    }
    fails
}

fn check_near_singular(case: &HardCase, solver: Solver, sol: &Solution, name: &str, fails: &mut Vec<String>) {
    let res = sol.energy.relative_residual();
    let rho = case.scene.patches[0].reflectance.r();
    for e in &case.expected {
        let b = sol.patch_radiosity[e.patch].mean();
        let exact = e.radiosity.mean();
        let missing = 1.0 - b / exact;
        if missing < -NEAR_SINGULAR_SLACK {
            fails.push(format!("{name}: patch {} B = {b:.3} overshoots the exact {exact}", e.patch));
        }
        if !((missing - res).abs() <= NEAR_SINGULAR_CONSISTENCY) {
            fails.push(format!(
                "{name}: patch {} misses {missing:.4} of B but the energy residual says {res:.4}",
                e.patch
            ));
        }
        if !matches!(solver, Solver::Progressive) {
            let bound = rho.powf(sol.stats.iterations as f64) + NEAR_SINGULAR_SLACK;
            if !(missing <= bound) {
                fails.push(format!(
                    "{name}: patch {} misses {missing:.4} of B after {} iterations (Jacobi bound ρ^k = {bound:.4})",
                    e.patch, sol.stats.iterations
                ));
            }
        }
    }
}

/// Radiosity scale below which patch differences are judged absolutely: 1 % of the scene's
/// area-weighted mean reflected radiosity (so a dark patch is not held to a relative bound).
fn scene_floor(scene: &Scene, reference: &[Estimate]) -> f64 {
    let area = scene.total_area();
    let refl: f64 = scene
        .patches
        .iter()
        .zip(reference)
        .map(|(p, r)| (r.radiosity - p.emission).map(f64::abs).mean() * p.area)
        .sum::<f64>()
        / area;
    (0.01 * refl).max(1e-300)
}

/// Paths per patch for the reference of this suite.
const REFERENCE_SAMPLES: u32 = 4096;

fn run_cases(cases: &[HardCase]) {
    let mut fails = Vec::new();
    for case in cases {
        let reference = reference_per_patch(&case.scene, REFERENCE_SAMPLES);
        for solver in SOLVERS {
            let label = solver.label();
            let known = known_issue(case.name, solver);
            let mine = match solver.solve(&case.scene) {
                Ok(sol) => check(case, solver, &sol, &reference, true),
                Err(e) => vec![format!("{} / {label}: {e}", case.name)],
            };
            match known {
                Some(what) if mine.is_empty() => {
                    fails.push(format!(
                        "{} / {label}: known issue \"{what}\" now passes: remove it from KNOWN_ISSUES",
                        case.name
                    ));
                }
                Some(what) => {
                    eprintln!("KNOWN ISSUE {} / {label}: {what}\n  {}", case.name, mine.join("\n  "))
                }
                None => fails.extend(mine),
            }
        }
    }
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

#[test]
fn singular_kernels_shared_edge_and_contact() {
    run_cases(&[hard_cases::shared_edge_perpendicular(), hard_cases::emitter_touching_receiver()]);
}

#[test]
fn boxes_on_floor_do_not_leak() {
    run_cases(&[hard_cases::boxes_on_floor()]);
}

#[test]
fn coplanar_overlapping_polygons() {
    run_cases(&[hard_cases::coplanar_overlap()]);
}

#[test]
fn slivers_1000_to_1() {
    run_cases(&[hard_cases::slivers()]);
}

#[test]
fn tiny_bright_emitter_near_and_far() {
    run_cases(&[hard_cases::tiny_emitter(1e-3), hard_cases::tiny_emitter(1e3)]);
}

#[test]
fn near_singular_furnace_and_plain_furnace() {
    run_cases(&[hard_cases::furnace(0.5), hard_cases::furnace(0.999)]);
}

#[test]
fn one_sided_open_and_occluded() {
    run_cases(&[
        hard_cases::receiver_from_behind(),
        hard_cases::open_scene(),
        hard_cases::occluded_emitter(),
    ]);
}

#[test]
fn close_parallel_plates() {
    run_cases(&[hard_cases::close_parallel_plates(1e-3)]);
}

/// Translation by 1e6 and uniform scaling by 1e-4 and 1e4 leave radiosity unchanged (form factors
/// are scale-free; E and B are per unit area). Every solver, per-patch averages.
#[test]
fn translation_and_scale_invariance() {
    // f64 geometry at 1e6 keeps ~1e-10 relative; the BVH works in a normalised local frame, and
    // visibility jitter is keyed by ids, so the same rays are cast. What remains is rounding in the
    // kernels (exact point-to-polygon at offsets of 1e6 loses ~1e-10·1e6/size): allow 1e-6.
    const INVARIANCE_REL: f64 = 1e-6;
    // Hierarchical refinement compares areas and form factors with thresholds; after exact 1→4
    // splits some comparisons are ties that rounding at another scale flips (measured at ×1e4
    // with centroid links: 1370 vs 1376 elements on boxes_on_floor, B within 1.03e-4 relative).
    // Exact ties count within 1e-9 relative (`nearly_equal`), but the Galerkin link coefficients
    // have thresholds of their own (the Gauss order, adaptive termination) that rounding at
    // 1e6 × 1e-4 (coordinates good to ~1e-7 of the scene's size) can flip: 1109 vs 1079 elements
    // there (2.8 %), B still within HIER_INVARIANCE_REL; every other transform measured within 2 %.
    const HIER_INVARIANCE_REL: f64 = 1e-3;
    const HIER_ELEMENT_COUNT_REL: f64 = 0.035;
    let mut fails = Vec::new();
    for case in [hard_cases::boxes_on_floor(), hard_cases::emitter_touching_receiver()] {
        for solver in SOLVERS {
            if known_issue(case.name, solver).is_some() {
                continue; // wrong at the origin already; see KNOWN_ISSUES
            }
            let hier = matches!(solver, Solver::Hierarchical(_));
            let (tol, count_tol) =
                if hier { (HIER_INVARIANCE_REL, HIER_ELEMENT_COUNT_REL) } else { (INVARIANCE_REL, 0.0) };
            let base = solver.solve(&case.scene).unwrap();
            for (offset, scale) in [
                (DVec3::splat(1e6), 1.0),
                (DVec3::ZERO, 1e-4),
                (DVec3::ZERO, 1e4),
                (DVec3::new(1e6, -2e6, 3e5), 1e-4),
            ] {
                let moved = hard_cases::transformed(&case.scene, offset, scale);
                let sol = solver.solve(&moved).unwrap();
                let label = format!("{} / {} moved by {offset} scaled {scale:e}", case.name, solver.label());
                if (sol.elements.len() as f64 - base.elements.len() as f64).abs()
                    > count_tol * base.elements.len() as f64
                {
                    fails.push(format!(
                        "{label}: {} elements vs {}",
                        sol.elements.len(),
                        base.elements.len()
                    ));
                }
                let bmax = base.patch_radiosity.iter().map(|b| b.max_channel()).fold(0.0, f64::max);
                for (p, (a, b)) in base.patch_radiosity.iter().zip(&sol.patch_radiosity).enumerate() {
                    let d = a.abs_diff_max(*b) / bmax;
                    if !(d <= tol) {
                        fails.push(format!(
                            "{label}: patch {p} B {:.6} vs {:.6} (relative {d:.2e})",
                            b.mean(),
                            a.mean()
                        ));
                    }
                }
            }
        }
    }
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

/// Two unit plates 1e-3 apart: with the lecture's Feps oracle, links grow as Feps shrinks, but
/// refinement terminates (Aeps floor) and the link count stays within a stated budget.
#[test]
fn close_plates_link_growth_is_bounded() {
    let case = hard_cases::close_parallel_plates(1e-3);
    let scene = Arc::new(case.scene.clone());
    let mut links = Vec::new();
    // With Aeps = 1e-4 of the scene's area (2), leaves are ≥ 5e-5 in area: at most 4 · 2/2e-4 =
    // 40 000 leaves; every leaf of one plate links to at most a few of the other's neighbours
    // when the distance (1e-3) is below the leaf size (~7e-3), so links stay O(leaves).
    const LINK_BUDGET: usize = 400_000;
    for feps in [0.1, 0.03, 0.01, 0.003] {
        let p = HierarchicalParams { feps, aeps: AreaEps::Relative(1e-4), ..HierarchicalParams::lecture() };
        let mut s = HierarchicalSolver::new(scene.clone(), p).unwrap();
        let report = s.solve(&mut |_, _| {});
        let st = s.stats();
        let sol = s.solution();
        eprintln!(
            "feps {feps}: {} elements, {} links, energy residual {:.2e}",
            st.elements,
            st.links,
            sol.energy.relative_residual()
        );
        assert!(!report.cancelled);
        assert!(st.links <= LINK_BUDGET, "feps {feps}: {} links > budget {LINK_BUDGET}", st.links);
        assert!(sol.is_physical(), "feps {feps}: non-physical B");
        links.push(st.links);
    }
    assert!(links.windows(2).all(|w| w[0] <= w[1]), "links should not shrink as Feps shrinks: {links:?}");
}

/// A non-planar quad: `Scene::validate` reports it; written as glTF (two triangles, as every
/// glTF quad is) the loader keeps the two triangles apart (they are not coplanar, so they do not
/// merge back into a quad), and every solver handles the result.
#[test]
fn non_planar_quad_is_reported_and_split_by_the_loader() {
    let case = hard_cases::non_planar_quad();
    assert!(case.scene.validate().iter().any(|m| m.contains("not planar")), "{:?}", case.scene.validate());
    let dir = std::env::temp_dir().join(format!("radlab-hard-nonplanar-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("non_planar_quad.gltf");
    radlab::scene::gltf::write_gltf(&case.scene, &path).unwrap();
    let loaded = Scene::load(path.to_str().unwrap()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(
        loaded.patches.len(),
        3,
        "lamp quad + the bent quad's two triangles: {:?}",
        loaded.patches.iter().map(|p| &p.name).collect::<Vec<_>>()
    );
    assert!(loaded.validate().is_empty(), "{:?}", loaded.validate());
    let loaded_case = HardCase { scene: loaded, ..case };
    let reference = reference_per_patch(&loaded_case.scene, REFERENCE_SAMPLES);
    let mut fails = Vec::new();
    for solver in SOLVERS {
        match solver.solve(&loaded_case.scene) {
            Ok(sol) => fails.extend(check(&loaded_case, solver, &sol, &reference, true)),
            Err(e) => fails.push(format!("non_planar_quad / {}: {e}", solver.label())),
        }
    }
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

/// The generated scenes under assets/scenes/hard/ are exactly what the code generates (so the
/// files can be opened in the viewer and by other tools). `UPDATE_SNAPSHOTS=1` rewrites them.
#[test]
fn hard_assets_match_the_generators() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/hard");
    let update = std::env::var_os("UPDATE_SNAPSHOTS").is_some();
    for case in hard_cases::all() {
        let text = radlab::scene::gltf::gltf_string(&case.scene).unwrap();
        let path = dir.join(format!("{}.gltf", case.name));
        if update {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, &text).unwrap();
            continue;
        }
        let on_disk = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (run with UPDATE_SNAPSHOTS=1 to write it)", path.display()));
        assert!(
            on_disk == text,
            "{} differs from hard_cases::{}() (UPDATE_SNAPSHOTS=1 rewrites it)",
            path.display(),
            case.name
        );
        // And it loads back to the same number of patches, except the non-planar quad (split)
        // and the picture lying on a wall, around which the loader cuts the wall into four
        // pieces (`scene::decal`).
        if case.scene.validate().is_empty() {
            let loaded = Scene::load(path.to_str().unwrap()).unwrap();
            let cut = if case.name == "coplanar_overlap" { 3 } else { 0 };
            assert_eq!(loaded.patches.len(), case.scene.patches.len() + cut, "{}", case.name);
        }
    }
}
