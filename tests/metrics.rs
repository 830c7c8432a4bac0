//! Error metrics: exact values on constructed solutions, resampling, and how well the
//! hierarchical solver's own error estimate ranks its true error (Spearman) on rooms.

use radlab::eval::metrics::{self, compare_resampled, compare_solution, resample};
use radlab::eval::pointwise::{self, PiecewiseConstant, Reconstruction};
use radlab::eval::reference::{
    Cell, Control, Estimate, PointParams, PointSet, RefElement, RefPoint, ReferenceParams, estimate_at,
    estimate_elements, reference_mesh, reference_points,
};
use radlab::geometry::accel::Accel;
use radlab::math::DVec3;
use radlab::math::{Rgb, polygon_area, polygon_centroid};
use radlab::scene::Scene;
use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::params::{AreaEps, HierarchicalParams};
use radlab::solver::uniform::{self, UniformParams};
use radlab::solver::{Solution, SolvedElement};
use radlab::studies::hard_cases;
use std::sync::Arc;

/// Sums of a few hundred terms: rounding stays far below this.
const EXACT: f64 = 1e-12;

fn solution_on(scene: &Scene, mesh: &[RefElement], values: &[Rgb]) -> Solution {
    let elements = mesh
        .iter()
        .zip(values)
        .map(|(e, b)| SolvedElement::constant(e.patch, e.vertices.clone(), polygon_area(&e.vertices), *b))
        .collect();
    Solution::of_elements("test", scene.patches.len(), elements)
}

/// A synthetic reference: smooth radiosity over the box-room, with a noise level.
fn synthetic(scene: &Scene, mesh: &[RefElement]) -> Vec<Estimate> {
    mesh.iter()
        .map(|e| {
            let c = polygon_centroid(&e.vertices);
            let p = &scene.patches[e.patch];
            let refl = Rgb::new(0.2 + 0.1 * c.x, 0.3 + 0.05 * c.y, 0.1 + 0.02 * c.z);
            Estimate {
                radiosity: p.emission + refl.mul_rgb(p.reflectance) * 2.0,
                std_error: Rgb::splat(0.001),
            }
        })
        .collect()
}

#[test]
fn a_solution_equal_to_the_reference_has_zero_error_and_reports_the_noise() {
    let scene = hard_cases::boxes_on_floor().scene;
    let mesh = reference_mesh(&scene, 0.5).unwrap();
    let reference = synthetic(&scene, &mesh);
    let values: Vec<Rgb> = reference.iter().map(|e| e.radiosity).collect();
    let r = compare_solution(&scene, &solution_on(&scene, &mesh, &values), &reference).unwrap();
    assert!(r.scene.l1 == 0.0 && r.scene.l2 == 0.0 && r.scene.linf == 0.0 && r.scene.l2_debiased == 0.0);
    assert!(r.scene.linf_debiased == 0.0 && r.scene.p95 == 0.0 && r.scene.p99 == 0.0);
    assert!(r.scene.reference_noise > 0.0);
    assert!(r.per_element.iter().all(|&e| e == 0.0));
    assert_eq!(r.per_patch.len(), scene.patches.len());
}

#[test]
fn a_ten_percent_error_of_the_reflected_part_reads_as_ten_percent() {
    let scene = hard_cases::boxes_on_floor().scene;
    let mesh = reference_mesh(&scene, 0.5).unwrap();
    let mut reference = synthetic(&scene, &mesh);
    for r in &mut reference {
        r.std_error = Rgb::ZERO;
    }
    let values: Vec<Rgb> = mesh
        .iter()
        .zip(&reference)
        .map(|(m, r)| {
            let e = scene.patches[m.patch].emission;
            e + (r.radiosity - e) * 1.1
        })
        .collect();
    let r = compare_solution(&scene, &solution_on(&scene, &mesh, &values), &reference).unwrap();
    assert!((r.scene.l1 - 0.1).abs() < EXACT && (r.scene.l2 - 0.1).abs() < EXACT, "{:?}", r.scene);
    assert!((r.scene.l2_debiased - 0.1).abs() < EXACT);
    for p in &r.per_patch {
        if scene.patches[p.patch].reflectance.max_channel() > 0.0 {
            assert!((p.norms.l2 - 0.1).abs() < EXACT, "{}: {:?}", p.name, p.norms);
        }
    }
    // L∞ = 0.1 · max |B̂ − E| / RMS(B̂ − E) ≥ 0.1 (max ≥ RMS).
    assert!(r.scene.linf >= 0.1 - EXACT);
    // Lamp (black) elements have zero error.
    let lamp = scene.patches.iter().position(|p| p.name == "lamp").unwrap();
    for (m, e) in mesh.iter().zip(&r.per_element) {
        if m.patch == lamp {
            assert_eq!(*e, 0.0);
        }
    }
}

#[test]
fn debiased_linf_ignores_errors_within_the_noise_and_percentiles_ignore_one_outlier() {
    let scene = hard_cases::boxes_on_floor().scene;
    let mesh = reference_mesh(&scene, 0.5).unwrap();
    let reference = synthetic(&scene, &mesh); // σ = 0.001 on every channel
    let sigma = 0.001;
    // Every element off by 2σ (noise level): raw L∞ sees it, the debiased one does not.
    let mut values: Vec<Rgb> = reference.iter().map(|e| e.radiosity + Rgb::splat(2.0 * sigma)).collect();
    let r = compare_solution(&scene, &solution_on(&scene, &mesh, &values), &reference).unwrap();
    assert!(r.scene.linf > 0.0 && r.scene.linf_debiased == 0.0, "{:?}", r.scene);
    assert!((r.scene.p95 - r.scene.linf).abs() < EXACT && (r.scene.p99 - r.scene.linf).abs() < EXACT);
    // One element off by 102σ: the debiased L∞ reads (102 − k)σ / R, the percentiles stay at 2σ / R
    // (the element holds far less than 1 % of the area).
    let outlier = mesh.iter().position(|m| scene.patches[m.patch].name.starts_with("room")).unwrap();
    let share = polygon_area(&mesh[outlier].vertices) / scene.total_area();
    assert!(share < 0.01, "outlier area share {share}");
    values[outlier] += Rgb::splat(100.0 * sigma);
    let r = compare_solution(&scene, &solution_on(&scene, &mesh, &values), &reference).unwrap();
    let k = metrics::linf_sigmas(mesh.len());
    assert!(k > 4.0 && k < 6.0, "k = {k} for {} regions", mesh.len());
    let unit = r.scene.linf / 102.0; // σ / R
    assert!((r.scene.linf_debiased - (102.0 - k) * unit).abs() < EXACT, "{:?}", r.scene);
    assert!(
        (r.scene.p95 - 2.0 * unit).abs() < EXACT && (r.scene.p99 - 2.0 * unit).abs() < EXACT,
        "{:?}",
        r.scene
    );
    // The outlier's patch carries it too, relative to that patch's own RMS reflected radiosity.
    let pe = r.per_patch.iter().find(|p| p.patch == mesh[outlier].patch).unwrap();
    assert!(pe.norms.linf_debiased > 0.0 && pe.norms.linf_debiased < pe.norms.linf);
}

#[test]
fn mismatched_inputs_are_errors() {
    let scene = hard_cases::open_scene().scene;
    let mesh = reference_mesh(&scene, 0.5).unwrap();
    let reference = synthetic(&scene, &mesh);
    let sol = solution_on(&scene, &mesh[1..], &vec![Rgb::ZERO; mesh.len() - 1]);
    assert!(compare_solution(&scene, &sol, &reference).is_err());
    let mut bad = mesh.clone();
    bad[0].patch = 99;
    assert!(resample(&scene, &sol.elements, &bad).is_err());
}

#[test]
fn resampling_a_finer_mesh_gives_area_averages() {
    let scene = hard_cases::boxes_on_floor().scene;
    // Coarse cells of 1.0 contain 2×2 fine cells of 0.5 on every side of length 1, 2, 3, 4
    // (the boxes' sides 0.9, 1.3, 1.8 split unevenly, so look only at the room and lamp).
    let fine = reference_mesh(&scene, 0.5).unwrap();
    let coarse = reference_mesh(&scene, 1.0).unwrap();
    let f = |e: &RefElement| {
        let c = polygon_centroid(&e.vertices);
        Rgb::new(c.x, c.y + 2.0 * c.z, 1.0)
    };
    let values: Vec<Rgb> = fine.iter().map(f).collect();
    let sol = solution_on(&scene, &fine, &values);
    let got = resample(&scene, &sol.elements, &coarse).unwrap();
    let mut checked = 0;
    for (c, g) in coarse.iter().zip(&got) {
        if !scene.patches[c.patch].name.starts_with("room") {
            continue;
        }
        // A linear field's piecewise-constant samples average to its value at the centroid.
        let want = f(c);
        // 6×6 points split 3×3 into each of the 2×2 children: the average is exact up to rounding.
        const RESAMPLE_EXACT: f64 = 1e-9;
        assert!(g.abs_diff_max(want) < RESAMPLE_EXACT, "patch {}: {g:?} vs {want:?}", c.patch);
        checked += 1;
    }
    assert!(checked > 40);
}

#[test]
fn spearman_detects_rank_agreement() {
    let x = [0.1, 0.5, 0.2, 0.9, 0.7];
    let y = [1.0, 3.0, 2.0, 7.0, 4.0];
    assert!((metrics::spearman(&x, &y) - 1.0).abs() < EXACT);
    let y2 = [1.0, 3.0, 2.0, 4.0, 7.0]; // one swap of neighbours: 1 − 6·2/(5·24) = 0.9
    assert!((metrics::spearman(&x, &y2) - 0.9).abs() < EXACT);
}

/// Paths per reference point of the ranking: each leaf holds its `WITHIN_POINTS` (9) sample
/// points, 4 608 paths a leaf (the element-average ranking before it used 4 096 per leaf; its
/// noise caps the measurable Spearman: at 512 paths a leaf the table room's |ΔB| against two
/// independent references agreed only to 0.5, at 4096 to 0.82).
const RANKING_PATHS: u32 = 512;

/// How well the hierarchical solver's own error estimate ranks its true error on the solution's
/// own leaves: Spearman against each leaf's own pointwise error (the RMS over its 3 × 3 sample
/// points of the reconstruction's error, debiased by the points' noise,
/// [`pointwise::per_element_pointwise`]), the quantity the per-element estimate estimates.
/// Returns (Spearman, leaves ranked, pointwise rel L2, estimate / measured).
fn estimate_correlation(scene: &Arc<Scene>, p: HierarchicalParams) -> (f64, usize, f64, f64) {
    let mut s = HierarchicalSolver::new(scene.clone(), p).unwrap();
    s.solve(&mut |_, _| {});
    solution_estimate_correlation(scene, &s.solution())
}

/// [`estimate_correlation`] of a solved solution carrying per-element estimates.
fn solution_estimate_correlation(scene: &Arc<Scene>, sol: &Solution) -> (f64, usize, f64, f64) {
    use radlab::solver::hierarchical::estimate::sample_points;
    let acc = Accel::build(scene);
    let points: Vec<RefPoint> = sol
        .elements
        .iter()
        .flat_map(|e| {
            let area = e.area / 9.0;
            sample_points(&e.vertices).map(|x| RefPoint {
                patch: e.patch,
                position: x,
                area,
                cell: Cell { patch: e.patch as u32, level: 0, i: 0, j: 0 },
            })
        })
        .collect();
    let set = PointSet { grids: vec![(1, 1); scene.patches.len()], points };
    let reference = estimate_at(
        scene,
        &acc,
        &set,
        &ReferenceParams { samples: RANKING_PATHS, ..ReferenceParams::quick() },
        &Control::default(),
    )
    .unwrap();
    let check = pointwise::check_estimate(scene, sol, &set.points, &reference).unwrap().unwrap();
    let l2 =
        pointwise::compare_solution_points(scene, sol, &set.points, &reference).unwrap().scene.l2_debiased;
    (check.spearman, check.elements, l2, check.global_estimate / l2)
}

/// The two settings the ranking is measured at: the interactive preset with a coarse area floor
/// (Aeps 1e-3 of the scene) and the lecture's Feps oracle at the same floor.
fn ranking_presets() -> [(&'static str, HierarchicalParams); 2] {
    let aeps = AreaEps::Relative(1e-3);
    [
        ("interactive, Aeps 1e-3", HierarchicalParams { aeps, ..HierarchicalParams::interactive() }),
        ("lecture, Aeps 1e-3", HierarchicalParams { aeps, ..HierarchicalParams::lecture() }),
    ]
}

#[test]
fn hierarchical_error_estimate_ranks_the_true_error() {
    let mut failures = Vec::new();
    for (name, scene, floors) in [
        ("builtin:cornell", Scene::load("builtin:cornell").unwrap(), SPEARMAN_FLOOR_CORNELL),
        ("builtin:table-room", Scene::load("builtin:table-room").unwrap(), SPEARMAN_FLOOR_TABLE_ROOM),
        ("hard:boxes_on_floor", hard_cases::boxes_on_floor().scene, SPEARMAN_FLOOR_BOXES),
    ] {
        let scene = Arc::new(scene);
        for ((preset, p), floor) in ranking_presets().into_iter().zip(floors) {
            // The global estimate within a factor 2 of the measured (measured 0.61–0.94
            // here).
            judge(&format!("{name} [{preset}]"), estimate_correlation(&scene, p), floor, 2.0, &mut failures);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("; "));
}

/// Print one ranking ([`estimate_correlation`]'s tuple) and note where its Spearman is at or
/// below `floor` or its estimate / measured outside [1/2, `ratio_max`].
fn judge(
    label: &str,
    (rho, n, l2, ratio): (f64, usize, f64, f64),
    floor: f64,
    ratio_max: f64,
    failures: &mut Vec<String>,
) {
    eprintln!(
        "{label}: Spearman(error_estimate, own pointwise error) = {rho:.3} over {n} leaves (pointwise rel L2 {l2:.3}, estimate / measured {ratio:.2})"
    );
    if rho <= floor {
        failures.push(format!("{label}: Spearman {rho:.3} ≤ floor {floor} ({n} leaves)"));
    }
    if !(0.5..=ratio_max).contains(&ratio) {
        failures.push(format!("{label}: estimate / measured {ratio:.2}"));
    }
}

/// The error estimate on the solver's most accurate path: the `quality` preset's error oracle on the
/// contact mesh (`RemeshParams::contacts`, the area floor 6e-4 · X as `radlab bench`'s rows), at
/// X = 0.2 on cornell and table-room, ranked as above (9 points × RANKING_PATHS paths a leaf).
/// Against the 4-batch 65 537-point references (`radlab reference builtin:S --batches 4 --compare
/// --mesh contact --preset quality --bf-eps-rel X --aeps-rel A`) the nine settings X = 0.2 / 0.1 /
/// 0.05 on cornell, table-room and splash_room read measured/estimate 1.18–1.60 and Spearman
/// 0.507–0.758 (docs/accuracy.md). This test's per-leaf ruler (4 608 paths a leaf, every leaf) is
/// too noisy for those leaves, most of them small with errors near 1–3 %: it measured Spearman
/// 0.196 (cornell, 1 785 leaves) and 0.457 (table-room, 510 leaves), estimate / measured 0.73
/// and 0.88. At X = 0.1 it reads table-room's pointwise error as 0.2 %, inside its own noise,
/// where the standard ruler reads 1.62 %: the ranking there is of noise. It guards the ranking
/// and the ratio against solver changes; the figures to quote are the 4-batch ones.
#[test]
fn the_error_estimate_ranks_the_contact_meshs_error() {
    use radlab::mesh::remesh::RemeshParams;
    use radlab::solver::discontinuity::HierarchicalOnMesh;
    const X: f64 = 0.2;
    let mut failures = Vec::new();
    for (name, floor) in
        [("builtin:cornell", CONTACT_SPEARMAN_FLOOR[0]), ("builtin:table-room", CONTACT_SPEARMAN_FLOOR[1])]
    {
        let scene = Arc::new(Scene::load(name).unwrap());
        let p = HierarchicalParams {
            bf_eps: X,
            aeps: AreaEps::Relative(radlab::studies::bench::CONTACT_AEPS_PER_EPS * X),
            ..HierarchicalParams::quality()
        };
        let mut on_mesh = HierarchicalOnMesh::new(&scene, &RemeshParams::contacts(), p).unwrap();
        on_mesh.solver.solve(&mut |_, _| {});
        let sol = on_mesh.finish(true).solution;
        let label = format!("{name} [contact mesh, quality X = {X}]");
        judge(&label, solution_estimate_correlation(&scene, &sol), floor, CONTACT_RATIO_MAX, &mut failures);
    }
    assert!(failures.is_empty(), "{}", failures.join("; "));
}

/// The contact-mesh ranking's floors (cornell, table-room): measured 0.196 and 0.457 against
/// this test's ruler, less about 0.1.
const CONTACT_SPEARMAN_FLOOR: [f64; 2] = [0.09, 0.35];

/// The largest estimate / measured the contact-mesh test accepts: the factor 2 of the other
/// rankings.
const CONTACT_RATIO_MAX: f64 = 2.0;

// Floors: measured Spearman at each of `ranking_presets()` minus a margin of 0.1 for solver
// changes under them and for the reference's noise. The ranking is against each leaf's own
// *pointwise* error (9 points × RANKING_PATHS paths a leaf), the quantity the per-element
// estimate estimates (module docs of `estimate`: the mean error δ and the within-leaf
// variation w), not against the error of the leaf's average (|ΔB|, 4096 paths a leaf). The
// estimate against |ΔB|, for comparison: cornell 0.510 / 0.745, table room 0.369 / 0.630,
// boxes_on_floor 0.098 / 0.617 (w ranks the pointwise error, not the average's). The target
// is ≥ 0.7: met on cornell's and splash_room's settings against the cached 65 k-point
// references (see the closing note), not here on the table room and boxes_on_floor.

//
// With the rows closed (`HierarchicalParams::close_rows`, on in both presets) the rooms' leaves
// show their sources scaled to close their rows, which the estimate adds to each leaf's residual
// (module docs of `estimate`); the ranking is then lower on the table room and on
// boxes_on_floor's `interactive` (closed rows off: 0.423 / 0.519, 0.375 / 0.613; cornell 0.653 /
// 0.651), while the pointwise rel L2 it ranks is lower too (table room 3.7 → 3.5 % and
// 6.0 → 5.7 %, boxes_on_floor 7.8 → 7.5 % and 11.4 → 10.8 %). Why the per-leaf residual ranks
// the closed solution's error less well there is not established; the floors follow the
// measured ranking.

/// Cornell: measured 0.654 over 863 leaves and 0.640 over 1760.
const SPEARMAN_FLOOR_CORNELL: [f64; 2] = [0.55, 0.54];
/// Table room: measured 0.377 over 578 leaves and 0.402 over 1637.
const SPEARMAN_FLOOR_TABLE_ROOM: [f64; 2] = [0.27, 0.30];
/// boxes_on_floor: measured 0.283 over 1136 leaves and 0.584 over 1778.
const SPEARMAN_FLOOR_BOXES: [f64; 2] = [0.18, 0.48];

#[test]
fn resampled_comparison_of_a_real_solve_is_consistent() {
    // The same solve measured on its own leaves and on a coarse reference mesh: the coarse mesh
    // averages out error, so its L2 is the smaller, and both are finite and below 100 %.
    let scene = hard_cases::boxes_on_floor().scene;
    let scene = Arc::new(scene);
    let mut s = HierarchicalSolver::new(scene.clone(), HierarchicalParams::interactive()).unwrap();
    s.solve(&mut |_, _| {});
    let sol = s.solution();
    let acc = Accel::build(&scene);
    let mesh = reference_mesh(&scene, 0.75).unwrap();
    let est =
        estimate_elements(&scene, &acc, &mesh, &ReferenceParams { samples: 256, ..ReferenceParams::quick() })
            .unwrap();
    let r = compare_resampled(&scene, &sol, &mesh, &est).unwrap();
    assert!(r.scene.l2.is_finite() && r.scene.l2 < 1.0 && r.scene.l2 > 0.0, "{:?}", r.scene);
    assert!(r.scene.l2_debiased <= r.scene.l2 && r.scene.reference_noise < r.scene.l2);
    assert!((r.energy_residual - sol.energy.relative_residual()).abs() < EXACT);
}

#[test]
fn quick_bench_runs_every_method_and_writes_table_json_and_plot() {
    use radlab::studies::bench::{self, BenchConfig, Mode};
    let dir = std::env::temp_dir().join(format!("radlab-bench-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut config = BenchConfig::new(Mode::Quick);
    config.scenes = vec!["hard:shared_edge_perpendicular".into(), "hard:open_scene".into()];
    config.cache = radlab::eval::reference::Cache::at(dir.join("cache"));
    // An unreachable reference target: batches are added up to the cap.
    config.reference_target = Some(1e-9);
    config.reference_max_batches = 2;
    let mut lines = Vec::new();
    let report = bench::run(&config, &mut |l| lines.push(l.to_string())).unwrap();
    assert!(lines.iter().filter(|l| l.contains("reference batch 2/2")).count() == 2, "{lines:#?}");
    for sc in &report.scenes {
        // Two batches computed; the second alone is scored against (the first placed the points).
        assert_eq!((sc.reference_batches, sc.reference_samples), (2, config.reference.samples));
        assert!(sc.reference_points >= config.reference_points as usize, "{} points", sc.reference_points);
        // A target is resolved exactly when noise and resolution are both ≤ half of it.
        for &(target, ok) in &sc.resolved {
            let want = sc.reference_noise <= 0.5 * target && sc.resolution <= 0.5 * target;
            assert_eq!(
                ok, want,
                "{}: target {target}, noise {}, resolution {}",
                sc.scene, sc.reference_noise, sc.resolution
            );
        }
    }
    for scene in &config.scenes {
        for method in ["uniform", "progressive", "hierarchical"] {
            let rows: Vec<_> =
                report.rows.iter().filter(|r| &r.scene == scene && r.method == method).collect();
            assert!(rows.len() >= 2, "{scene} {method}: {} rows", rows.len());
            for r in rows.iter().filter(|r| r.status == "ok") {
                assert!(r.time_s > 0.0 && r.rel_l2.is_finite() && r.elements > 0, "{r:?}");
            }
        }
    }
    assert_eq!(report.scenes.len(), 2);
    let md = bench::markdown(&report);
    // The table says which ruler and how many points.
    let points = radlab::eval::pointwise::thousands(report.scenes[0].reference_points);
    assert!(md.contains("**Pointwise**") && md.contains(&format!("{points} points")), "{md}");
    assert!(
        md.contains("| shared_edge_perpendicular") || md.contains("| hard:shared_edge_perpendicular"),
        "{md}"
    );
    let png = dir.join("plot.png");
    bench::plot_png(&report, &png).unwrap();
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "{} bytes", bytes.len());
    let json = serde_json::to_string(&report).unwrap();
    assert!(json.contains("\"rows\""));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A solution equal to the reference at every point has zero pointwise error, and its noise is
/// reported; a closure reconstruction plugs in like the piecewise-constant one.
#[test]
fn pointwise_error_of_the_reference_itself_is_zero_and_closures_reconstruct() {
    let scene = hard_cases::boxes_on_floor().scene;
    let accel = Accel::build(&scene);
    let params = PointParams {
        points: 400,
        paths: ReferenceParams { samples: 8, ..ReferenceParams::quick() },
        ..PointParams::quick()
    };
    let (set, reference) = reference_points(&scene, &accel, &params, &Control::default()).unwrap();
    let values: Vec<Rgb> = reference.iter().map(|e| e.radiosity).collect();
    let r = pointwise::compare_points(&scene, &set.points, &values, &reference, 0.0).unwrap();
    assert_eq!(r.scene.l2, 0.0);
    assert_eq!(r.scene.l2_debiased, 0.0);
    assert!(r.scene.reference_noise > 0.0);
    // The reference as a piecewise-constant solution on its own cells reads itself back exactly.
    let cells = set.cell_regions(&scene);
    let sol = solution_on(&scene, &cells, &values);
    let pc = PiecewiseConstant::new(&scene, &sol.elements).unwrap();
    assert_eq!(pointwise::evaluate(&pc, &set.points), values);
    // A closure: twice the reference's value; the error is then exactly the reference's B.
    let twice = |patch: usize, x: DVec3| pc.radiosity_at(patch, x) * 2.0;
    let doubled = pointwise::evaluate(&twice, &set.points);
    let d = pointwise::compare_points(&scene, &set.points, &doubled, &reference, 0.0).unwrap();
    let b2: f64 = set
        .points
        .iter()
        .zip(&reference)
        .map(|(p, e)| p.area * e.radiosity.mul_rgb(e.radiosity).0.iter().sum::<f64>())
        .sum();
    let refl2: f64 = set
        .points
        .iter()
        .zip(&reference)
        .map(|(p, e)| {
            let r = e.radiosity - scene.patches[p.patch].emission;
            p.area * r.mul_rgb(r).0.iter().sum::<f64>()
        })
        .sum();
    assert!(
        (d.scene.l2 - (b2 / refl2).sqrt()).abs() < 1e-9 * d.scene.l2,
        "{} vs {}",
        d.scene.l2,
        (b2 / refl2).sqrt()
    );
    assert!(pointwise::compare_points(&scene, &set.points[1..], &values[1..], &reference, 0.0).is_err());
}

/// The pointwise ruler sees a shadow. On table-room, against a pointwise reference
/// of 8192 points × 256 paths (noise 4.6 %, resolution 1.2 %), measured (deterministic):
/// - a uniform solution at h = d/4 (72 elements) reads 18.0 % pointwise, at h = d/16 (614
///   elements) 6.7 %: ratio 2.69 (against the standard 65 537-point × 1024-path reference: 18.5 %
///   and 7.5 %). The element averages of the same two solutions are 2.8 % and 1.1 % off: a blocky
///   solution's averages are nearly right, its shadows are not;
/// - the exact answer displaced by half a penumbra width: the table's penumbra on the floor is
///   0.5 · 0.8 / 2.2 ≈ 0.18 wide (light 0.5 wide, 2.2 above the table top, floor 0.8 below it).
///   A second, independent reference batch on the same cells stands for the exact solution (the
///   noise of both batches taken out); shifted by 0.09 along x in each patch's plane, the floor
///   reads 7.5 % (resolution 2.1 %), unshifted 0.4 %; the whole scene 3.4 % (resolution 1.6 %)
///   against 0.0 %.
#[test]
fn pointwise_ruler_sees_the_table_rooms_shadow() {
    let scene = Scene::load("builtin:table-room").unwrap();
    let accel = Accel::build(&scene);
    let params = PointParams {
        points: 8192,
        paths: ReferenceParams { samples: 256, ..ReferenceParams::quick() },
        ..PointParams::quick()
    };
    let (set, reference) = reference_points(&scene, &accel, &params, &Control::default()).unwrap();
    assert!(set.points.len() >= 8192);
    let d = scene.bounds().diagonal();
    let solve = |h: f64| {
        uniform::solve(
            &scene,
            &accel,
            &UniformParams { element_size: h, ..UniformParams::default() },
            &mut |_, _| {},
        )
        .unwrap()
    };
    let (coarse, fine) = (solve(d / 4.0), solve(d / 16.0));
    let err = |sol: &Solution| {
        pointwise::compare_solution_points(&scene, sol, &set.points, &reference).unwrap().scene
    };
    let (ec, ef) = (err(&coarse), err(&fine));
    let avg = |sol: &Solution| {
        pointwise::compare_element_averages(&scene, sol, &set.points, &reference).unwrap().scene.l2_debiased
    };
    eprintln!(
        "table-room: {} points, noise {:.2} %, resolution {:.2} %; uniform d/4 {} elements {:.2} % (element averages {:.2} %), d/16 {} elements {:.2} % ({:.2} %): ratio {:.2}",
        set.points.len(),
        100.0 * ef.reference_noise,
        100.0 * ef.resolution,
        coarse.elements.len(),
        100.0 * ec.l2_debiased,
        100.0 * avg(&coarse),
        fine.elements.len(),
        100.0 * ef.l2_debiased,
        100.0 * avg(&fine),
        ec.l2_debiased / ef.l2_debiased
    );
    // Measured 2.69; the margin covers another seed's noise (resolution 1.2 % on 6.7 %).
    const COARSE_OVER_FINE: f64 = 2.0;
    assert!(ec.l2_debiased > COARSE_OVER_FINE * ef.l2_debiased, "{ec:?}\n{ef:?}");

    // The exact answer, displaced: batch 2 as a piecewise-constant field on the reference's cells.
    let batch =
        estimate_at(&scene, &accel, &set, &ReferenceParams { seed: 1, ..params.paths }, &Control::default())
            .unwrap();
    let cells = set.cell_regions(&scene);
    let exact = solution_on(&scene, &cells, &batch.iter().map(|e| e.radiosity).collect::<Vec<_>>());
    let locate = PiecewiseConstant::new(&scene, &exact.elements).unwrap();
    let displaced_error = |shift: DVec3| {
        // Each point reads the cell at x + shift (in its patch's plane); the noise of both batches
        // is taken out: σ² = σ₁²(x) + σ₂²(x + shift).
        let (values, reference): (Vec<Rgb>, Vec<Estimate>) = set
            .points
            .iter()
            .zip(&reference)
            .map(|(p, r)| {
                let n = scene.patches[p.patch].normal;
                let cell = locate.element_at(p.patch, p.position + shift - n * n.dot(shift)).unwrap();
                let s2 = batch[cell].std_error;
                let sigma = (r.std_error.mul_rgb(r.std_error) + s2.mul_rgb(s2)).map(f64::sqrt);
                (batch[cell].radiosity, Estimate { radiosity: r.radiosity, std_error: sigma })
            })
            .unzip();
        let r = pointwise::compare_points(&scene, &set.points, &values, &reference, 0.0).unwrap();
        let floor = r.per_patch.iter().find(|p| p.name.starts_with("floor")).expect("a floor").norms;
        (r.scene, floor)
    };
    let (still, still_floor) = displaced_error(DVec3::ZERO);
    let (moved, moved_floor) = displaced_error(DVec3::new(0.09, 0.0, 0.0));
    eprintln!(
        "exact answer (batch 2), floor: unshifted {:.2} %, shifted by half a penumbra {:.2} % (resolution {:.2} %); scene: {:.2} %, {:.2} % ({:.2} %)",
        100.0 * still_floor.l2_debiased,
        100.0 * moved_floor.l2_debiased,
        100.0 * moved_floor.resolution,
        100.0 * still.l2_debiased,
        100.0 * moved.l2_debiased,
        100.0 * moved.resolution
    );
    assert!(still_floor.l2_debiased <= still_floor.resolution, "{still_floor:?}");
    assert!(still.l2_debiased <= still.resolution, "{still:?}");
    // On the floor, where the shadow is, the displacement reads well above what the reference
    // resolves (measured 3.5 resolutions), and above the unshifted answer on the whole scene.
    const DISPLACED_OVER_RESOLUTION: f64 = 2.0;
    assert!(moved_floor.l2_debiased > DISPLACED_OVER_RESOLUTION * moved_floor.resolution, "{moved_floor:?}");
    assert!(moved.l2_debiased > still.l2_debiased + moved.resolution, "{moved:?}");
}
