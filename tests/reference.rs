//! The independent reference against closed forms, within stated multiples of its own standard
//! error; determinism across thread counts; the on-disk cache (hit, corrupt entry recomputed).

use radlab::eval::reference::{
    Cache, CacheStatus, Control, Estimate, PointParams, RefElement, ReferenceParams, estimate_at,
    estimate_elements, estimate_points, reference_mesh, reference_points,
};
use radlab::geometry::accel::Accel;
use radlab::math::DVec3;
use radlab::studies::hard_cases::{self, HardCase};

/// A correct estimator lands within 4 standard errors of the truth (p ≈ 6e-5 per channel, and the
/// seeds are fixed, so the test is deterministic).
const Z_MAX: f64 = 4.0;
/// Small absolute slack for exact zeros and for the 1e-15 rounding of sums.
const ABS_SLACK: f64 = 1e-9;
/// The standard error must be small enough for the check to mean something: below 2 % of B.
const MAX_REL_STD_ERROR: f64 = 0.02;

fn whole_patches(case: &HardCase) -> Vec<RefElement> {
    case.scene
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| RefElement { patch: i, vertices: p.vertices.clone() })
        .collect()
}

fn params(samples: u32) -> ReferenceParams {
    ReferenceParams { samples, ..ReferenceParams::quick() }
}

fn check(case: &HardCase, est: &[Estimate]) {
    for e in &case.expected {
        let got = est[e.patch];
        for c in 0..3 {
            let (b, se, want) = (got.radiosity.0[c], got.std_error.0[c], e.radiosity.0[c]);
            assert!(
                (b - want).abs() <= Z_MAX * se + ABS_SLACK,
                "{} patch {} channel {c}: reference {b} ± {se}, closed form {want} ({})",
                case.name,
                e.patch,
                e.why
            );
            assert!(
                se <= MAX_REL_STD_ERROR * want.abs() + ABS_SLACK,
                "{}: std error {se} of {want}",
                case.name
            );
        }
    }
}

#[test]
fn white_furnace_b_equals_e_over_one_minus_rho() {
    let case = hard_cases::furnace(0.5);
    let acc = Accel::build(&case.scene);
    let est = estimate_elements(&case.scene, &acc, &whole_patches(&case), &params(2048)).unwrap();
    check(&case, &est);
}

#[test]
fn parallel_plates_direct_light_matches_catalog_form_factor() {
    // Open scene: the floor sees the lamp only; the lamp gets ρ_floor F² of its own light back.
    let case = hard_cases::open_scene();
    let acc = Accel::build(&case.scene);
    let est = estimate_elements(&case.scene, &acc, &whole_patches(&case), &params(4096)).unwrap();
    check(&case, &est);
}

#[test]
fn perpendicular_plates_sharing_an_edge_match_catalog_form_factor() {
    let case = hard_cases::shared_edge_perpendicular();
    let acc = Accel::build(&case.scene);
    let est = estimate_elements(&case.scene, &acc, &whole_patches(&case), &params(4096)).unwrap();
    check(&case, &est);
}

#[test]
fn point_estimate_under_a_square_matches_point_form_factor() {
    // Floor point under the centre of a unit lamp 1 above: B = ρ E F(point→square), Howell B-3.
    let case = hard_cases::close_parallel_plates(1.0);
    let acc = Accel::build(&case.scene);
    let p = ReferenceParams { samples: 20_000, ..ReferenceParams::quick() };
    let est = estimate_points(&case.scene, &acc, &[(DVec3::new(0.5, 0.5, 0.0), 0)], &p).unwrap();
    let want = 0.5 * 4.0 * hard_cases::ff_point_parallel_rectangle_corner(0.5, 0.5, 1.0);
    let (b, se) = (est[0].radiosity.r(), est[0].std_error.r());
    assert!((b - want).abs() <= Z_MAX * se, "point: {b} ± {se}, closed form {want}");
    assert!(se < MAX_REL_STD_ERROR * want);
}

#[test]
fn back_facing_and_occluded_receivers_are_exactly_dark() {
    for case in [hard_cases::receiver_from_behind(), hard_cases::occluded_emitter()] {
        let acc = Accel::build(&case.scene);
        let est = estimate_elements(&case.scene, &acc, &whole_patches(&case), &params(256)).unwrap();
        check(&case, &est);
    }
}

#[test]
fn standard_errors_are_honest_across_many_elements() {
    // Element averages must scatter about the truth as their standard errors say. On the furnace
    // every element's truth is 2, so the z-scores of 96 elements are known.
    let case = hard_cases::furnace(0.5);
    let acc = Accel::build(&case.scene);
    let mesh = reference_mesh(&case.scene, 0.25).unwrap();
    assert_eq!(mesh.len(), 6 * 16);
    let est = estimate_elements(&case.scene, &acc, &mesh, &params(1024)).unwrap();
    let z2: f64 = est.iter().map(|e| ((e.radiosity.r() - 2.0) / e.std_error.r()).powi(2)).sum::<f64>()
        / est.len() as f64;
    // Mean z² is 1 for exact standard errors (±0.3 at 4σ over 96 elements). The sample variance of
    // skewed path sums runs low at small counts: measured mean z² 2.0 at 64 paths, 1.36 at 1024,
    // 1.13 at 4096, 1.01 at 16384. At 1024 (the `standard` preset) accept up to 1.7, i.e. standard
    // errors optimistic by at most 30 %.
    const MEAN_Z2_RANGE: (f64, f64) = (0.6, 1.7);
    assert!(z2 > MEAN_Z2_RANGE.0 && z2 < MEAN_Z2_RANGE.1, "mean z² = {z2}");
}

#[test]
fn reference_mesh_tiles_every_patch() {
    for case in hard_cases::all() {
        if !case.scene.validate().is_empty() {
            continue; // the non-planar quad: a bilinear grid of a bent quad does not tile its plane area
        }
        let mesh = reference_mesh(&case.scene, 0.3).unwrap();
        for (i, p) in case.scene.patches.iter().enumerate() {
            let area: f64 =
                mesh.iter().filter(|e| e.patch == i).map(|e| radlab::math::polygon_area(&e.vertices)).sum();
            // Sub-quads of a planar quad tile it exactly up to rounding.
            const TILE_REL: f64 = 1e-9;
            assert!((area / p.area - 1.0).abs() < TILE_REL, "{} patch {i}: {area} vs {}", case.name, p.area);
        }
    }
    assert!(reference_mesh(&hard_cases::furnace(0.5).scene, 0.0).is_err());
    assert!(reference_mesh(&hard_cases::furnace(0.5).scene, f64::NAN).is_err());
}

#[test]
fn identical_for_any_thread_count() {
    let case = hard_cases::boxes_on_floor();
    let acc = Accel::build(&case.scene);
    let mesh = reference_mesh(&case.scene, 1.0).unwrap();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| estimate_elements(&case.scene, &acc, &mesh, &params(8)).unwrap())
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let case = hard_cases::open_scene();
    let acc = Accel::build(&case.scene);
    let bad_patch = [RefElement { patch: 99, vertices: case.scene.patches[0].vertices.clone() }];
    assert!(estimate_elements(&case.scene, &acc, &bad_patch, &params(4)).is_err());
    let degenerate = [RefElement { patch: 0, vertices: vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0] }];
    assert!(estimate_elements(&case.scene, &acc, &degenerate, &params(4)).is_err());
    assert!(estimate_elements(&case.scene, &acc, &whole_patches(&case), &params(0)).is_err());
}

#[test]
fn cache_hits_and_recomputes_a_corrupt_entry() {
    let dir = std::env::temp_dir().join(format!("radlab-ref-cache-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cache = Cache::at(&dir);
    let case = hard_cases::open_scene();
    let acc = Accel::build(&case.scene);
    let els = whole_patches(&case);
    let p = params(16);
    let (first, s1) = cache.get_or_compute(&case.scene, &acc, &els, &p).unwrap();
    let CacheStatus::Computed(file) = s1 else { panic!("expected a fresh computation, got {s1:?}") };
    let (second, s2) = cache.get_or_compute(&case.scene, &acc, &els, &p).unwrap();
    assert_eq!(s2, CacheStatus::Hit(file.clone()));
    assert_eq!(first.estimates, second.estimates);

    // Change one estimate in the file: the checksum catches it.
    let text = std::fs::read_to_string(&file).unwrap();
    let i = text.find("\"radiosity\":[").unwrap() + "\"radiosity\":[".len();
    let corrupt = format!("{}9{}", &text[..i], &text[i..]);
    std::fs::write(&file, corrupt).unwrap();
    let (third, s3) = cache.get_or_compute(&case.scene, &acc, &els, &p).unwrap();
    assert!(matches!(&s3, CacheStatus::Recomputed { why, .. } if why.contains("checksum")), "{s3:?}");
    assert_eq!(third.estimates, first.estimates);

    // Truncated file: caught, recomputed.
    std::fs::write(&file, &text[..text.len() / 2]).unwrap();
    let (_, s4) = cache.get_or_compute(&case.scene, &acc, &els, &p).unwrap();
    assert!(matches!(&s4, CacheStatus::Recomputed { .. }), "{s4:?}");
    // A garbage file with a valid checksum but no JSON: a parse error.
    let body = "not json";
    let sum = radlab::eval::reference::Hasher64::default().bytes(body.as_bytes()).finish();
    std::fs::write(&file, format!("radlab-reference {sum:016x}\n{body}")).unwrap();
    let (_, s5) = cache.get_or_compute(&case.scene, &acc, &els, &p).unwrap();
    assert!(matches!(&s5, CacheStatus::Recomputed { why, .. } if why.contains("parse")), "{s5:?}");

    // Different settings or scene: a different key.
    let other = radlab::eval::reference::cache_key(&case.scene, &els, &params(17));
    assert_ne!(other, radlab::eval::reference::cache_key(&case.scene, &els, &p));
    let moved = hard_cases::transformed(&case.scene, DVec3::X, 1.0);
    assert_ne!(
        radlab::eval::reference::cache_key(&moved, &els, &p),
        radlab::eval::reference::cache_key(&case.scene, &els, &p)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn point_params(points: u32, samples: u32) -> PointParams {
    PointParams { points, paths: params(samples), ..PointParams::quick() }
}

#[test]
fn point_reference_is_identical_for_any_thread_count_and_has_its_points() {
    let case = hard_cases::boxes_on_floor();
    let acc = Accel::build(&case.scene);
    let p = point_params(600, 8);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| reference_points(&case.scene, &acc, &p, &Control::default()).unwrap())
    };
    let (set, est) = run(1);
    assert_eq!((set.clone(), est.clone()), run(3));
    assert!(set.points.len() >= 600, "{} points", set.points.len());
    // The cells tile the scene: their areas sum to the scene's area.
    let area: f64 = case.scene.patches.iter().map(|p| p.area).sum();
    let cells: f64 = set.points.iter().map(|p| p.area).sum();
    assert!((cells - area).abs() < 1e-9 * area, "{cells} vs {area}");
    // Refinement happened (boxes on a floor under a light have edges and shadows).
    assert!(set.points.iter().any(|p| p.cell.level > 0));
    // Re-estimating at the layout's own seed reproduces the layout's estimates bit for bit.
    let again = estimate_at(&case.scene, &acc, &set, &p.paths, &Control::default()).unwrap();
    assert_eq!(again, est);
    assert!(
        reference_points(&case.scene, &acc, &PointParams { points: 0, ..p }, &Control::default()).is_err()
    );
}

#[test]
fn point_cache_hits_and_batches_reuse_the_layout() {
    let dir = std::env::temp_dir().join(format!("radlab-ref-points-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cache = Cache::at(&dir);
    let case = hard_cases::open_scene();
    let acc = Accel::build(&case.scene);
    let p = point_params(200, 8);
    let (first, s1) = cache.get_or_compute_points(&case.scene, &acc, &p, &Control::default()).unwrap();
    assert!(matches!(s1, CacheStatus::Computed(_)), "{s1:?}");
    let (second, s2) = cache.get_or_compute_points(&case.scene, &acc, &p, &Control::default()).unwrap();
    assert!(matches!(s2, CacheStatus::Hit(_)), "{s2:?}");
    assert_eq!(first.estimates, second.estimates);
    // A second batch: the same points, other estimates.
    let (b1, sb) = cache.get_or_compute_points(&case.scene, &acc, &p.batch(1), &Control::default()).unwrap();
    let CacheStatus::Computed(batch_file) = sb else { panic!("expected a fresh batch, got {sb:?}") };
    assert_eq!(b1.set, first.set);
    assert_ne!(b1.estimates, first.estimates);
    // Its file holds only the estimates; read back, it carries the layout's points again.
    let CacheStatus::Hit(layout_file) = s2 else { unreachable!() };
    let size = |f: &std::path::Path| std::fs::metadata(f).unwrap().len();
    assert!(size(&batch_file) < size(&layout_file), "{} vs {}", size(&batch_file), size(&layout_file));
    let (again, s3) =
        cache.get_or_compute_points(&case.scene, &acc, &p.batch(1), &Control::default()).unwrap();
    assert!(matches!(s3, CacheStatus::Hit(_)), "{s3:?}");
    assert_eq!((again.set, again.estimates), (b1.set, b1.estimates));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `radlab reference SCENE --compare --method hierarchical --mesh discontinuity-cdt`: the discontinuity mesh as the
/// hierarchical solver's top level, graded to the budget asked (`auto` by default, `off`: the
/// ungraded mesh), scored like any method; the grading flags without grading are refused.
#[test]
fn compare_solves_the_dmesh_top_level_with_its_grading() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("reference-dmesh-cache");
    let run = |flags: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
            .args(["reference", "builtin:shadow-narrow", "--samples", "16", "--exact"])
            .args(["--compare", "--method", "hierarchical", "--mesh", "discontinuity-cdt"])
            .args(flags)
            .arg("--cache-dir")
            .arg(&cache)
            .output()
            .unwrap();
        let text =
            format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        (out.status.success(), text)
    };
    let (ok, text) = run(&["--dmesh-budget", "150"]);
    assert!(ok, "{text}");
    assert!(text.contains("→ 150 patches (graded to a budget of 150:"), "{text}");
    assert!(text.contains("pointwise rel L2"), "{text}");
    let (ok, text) = run(&[]);
    assert!(ok, "{text}");
    assert!(text.contains("(auto)"), "the hierarchical top level grades by default: {text}");
    let (ok, text) = run(&["--dmesh-budget", "off"]);
    assert!(ok && !text.contains("graded"), "{text}");
    let (ok, text) = run(&["--dmesh-budget", "off", "--dmesh-smooth", "2"]);
    assert!(!ok && text.contains("--dmesh-smooth"), "{text}");
}

/// `radlab reference --batches N` computes N cached batches on batch 1's points and scores
/// against batches 2 … N (the noise falls as 1/√(N − 1)); `--compare --mesh contact` solves on the contact mesh (cornell: the blocks'
/// 8 footprint edges on the floor) with the solver's own estimate; `--point-errors` writes one
/// CSV row per point; `radlab solve --mesh contact` refuses a solver other than hierarchical.
#[test]
fn batches_merge_and_the_contact_mesh_compares_with_point_errors() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("reference-batches");
    let _ = std::fs::create_dir_all(&dir);
    let csv = dir.join("points.csv");
    let run = |args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
            .args(args)
            .arg("--cache-dir")
            .arg(dir.join("cache"))
            .output()
            .unwrap();
        let text =
            format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        (out.status.success(), text)
    };
    let noise = |text: &str| -> f64 {
        let at = text.find("; noise ").expect("a noise figure") + "; noise ".len();
        text[at..].split_whitespace().next().unwrap().parse().unwrap()
    };
    let base = ["reference", "builtin:cornell", "--points", "2048", "--samples", "16"];
    let (ok, one) = run(&base);
    assert!(ok, "{one}");
    let csv_arg = csv.to_str().unwrap();
    let mut args = base.to_vec();
    args.extend([
        "--batches",
        "4",
        "--compare",
        "--mesh",
        "contact",
        "--preset",
        "interactive",
        "--point-errors",
        csv_arg,
    ]);
    let (ok, four) = run(&args);
    assert!(ok, "{four}");
    assert!(four.contains("batch 4/4 (seed 3)"), "{four}");
    let (n1, n4) = (noise(&one), noise(&four));
    // Scored against batches 2–4 (batch 1 placed the points): √3 less noise than one batch.
    assert!(n4 < 0.7 * n1, "4 batches: noise {n4} % against {n1} % with one");
    assert!(four.contains("scored against batches 2–4 merged"), "{four}");
    assert!(four.contains("mesh: 8 critical segments"), "{four}");
    assert!(
        four.contains("pointwise rel L2") && four.contains("own error estimate (no reference)"),
        "{four}"
    );
    let rows = std::fs::read_to_string(&csv).unwrap();
    let mut lines = rows.lines();
    assert!(lines.next().unwrap().starts_with("patch,x,y,z,area,ref_r"), "{rows}");
    // Every point but the enclosed ones, which the scores leave out and the run counts.
    let enclosed: usize = four
        .lines()
        .find(|l| l.contains("points enclosed in solids"))
        .map_or(0, |l| l[..l.find(" points enclosed").unwrap()].replace(' ', "").parse().unwrap());
    assert!(lines.count() + enclosed >= 2048, "{enclosed} enclosed: {four}");
    // `radlab solve --mesh contact --estimate --json`: the method, the contact mesh's stats and
    // the solver's own estimate in the JSON, the solution on the input patches.
    let json = dir.join("contact.json");
    // `radlab solve builtin:cornell --mesh contact ARGS --json`, its JSON.
    let solve_contact = |extra: &[&str]| -> serde_json::Value {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
            .args(["solve", "builtin:cornell", "--mesh", "contact", "-q"])
            .args(extra)
            .arg("--json")
            .arg(&json)
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
    };
    let v = solve_contact(&["--preset", "interactive", "--estimate"]);
    assert_eq!(v["method"], "hierarchical on contact mesh", "{}", v["method"]);
    let global = v["error_estimate"]["global_rel_l2"].as_f64().expect("an estimate");
    assert!(global > 0.0 && global < 1.0, "{global}");
    assert_eq!(v["patches"].as_array().unwrap().len(), 20, "the input patches, not the pieces");
    // With the error oracle the contact mesh's area floor follows the threshold (6e-4 · X)
    // unless an Aeps is given.
    let aeps_of = |extra: &[&str]| -> f64 {
        let v = solve_contact(&[&["--preset", "quality"], extra].concat());
        v["params"]["solve"]["aeps"]["value"].as_f64().expect("a relative Aeps")
    };
    assert!((aeps_of(&["--bf-eps-rel", "0.2"]) - 1.2e-4).abs() < 1e-12);
    assert!((aeps_of(&["--bf-eps-rel", "0.2", "--aeps-rel", "3e-4"]) - 3e-4).abs() < 1e-12);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
        .args(["solve", "builtin:cornell", "--mesh", "contact", "--method", "uniform"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--mesh contact"), "{out:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
