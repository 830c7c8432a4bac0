//! Hierarchical radiosity: physics and algorithm tests (HSA91).

mod common;

use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::hierarchy::StopReason;
use radlab::solver::params::{AreaEps, ErrorTail, HierarchicalParams, Oracle};
use std::sync::Arc;

/// Furnace: B = E/(1−ρ) exactly, to 1e-6 relative, without any normalisation.
const FURNACE_TOL: f64 = 1e-6;

fn solve(scene: radlab::scene::Scene, p: HierarchicalParams) -> HierarchicalSolver {
    let mut s = HierarchicalSolver::new(Arc::new(scene), p).unwrap();
    s.solve(&mut |_, _| {});
    s
}

/// The white furnace is exact at any threshold: its gathered radiosity is uniform over every
/// face, so the error oracle never splits it (one element per face, the exact 6×6 answer).
/// The Feps and BF oracles refine it for the light that flows, and its piecewise-constant
/// Galerkin answer is then no longer exact (a leaf's links sit at different levels, so its
/// total form factor is 1 only on average): measured and bounded in the second half.
#[test]
fn white_furnace_is_exact_at_any_threshold() {
    for error_tail in [ErrorTail::Linear, ErrorTail::Signed] {
        for rho in [0.5, 0.9] {
            for (bf_eps, aeps) in [(0.1, 0.1), (0.01, 0.01), (1e-3, 1e-3), (1e-4, 1e-4)] {
                let p = HierarchicalParams {
                    oracle: Oracle::Error,
                    aeps: AreaEps::Absolute(aeps),
                    bf_eps,
                    bf_relative: false,
                    tolerance: 1e-10,
                    max_iterations: 1000,
                    error_tail,
                    ..HierarchicalParams::quality()
                };
                let sol = solve(common::furnace(rho, 1.0), p).solution();
                let worst = common::furnace_error(&sol, rho);
                let what = format!("{error_tail:?} rho {rho} BFeps {bf_eps} Aeps {aeps}");
                assert_eq!(sol.elements.len(), 6, "{what}: the furnace needs no refinement");
                assert!(worst < FURNACE_TOL, "{what}: worst rel err {worst:e}");
            }
        }
    }
}

/// The Feps and BF oracles refine the furnace for the light that flows; a leaf then gathers
/// through links at several levels whose form factors are averages over different ancestors, and
/// its total form factor is 1 only on average over the face (measured, ρ 0.5, Feps 0.05 / Aeps
/// 0.01, link coefficients to 1e-7: 0.82 at the faces' centres, 1.55 in the corners, B off by
/// up to 39 %). That is the lesson of the furnace: the error oracle, which does not refine it,
/// is exact (above). What still holds when refined: the power balance closes (reciprocal links).
#[test]
fn a_refined_furnace_conserves_power() {
    for (oracle, feps, aeps) in [(Oracle::Feps, 0.05, 0.01), (Oracle::Bf, 0.05, 0.005)] {
        let p = HierarchicalParams {
            oracle,
            feps,
            aeps: AreaEps::Absolute(aeps),
            bf_eps: 0.05,
            bf_relative: false,
            tolerance: 1e-9,
            max_iterations: 1000,
            link_tol: 1e-7,
            ..HierarchicalParams::interactive()
        };
        let sol = solve(common::furnace(0.5, 1.0), p).solution();
        let worst =
            sol.elements.iter().map(|e| (e.radiosity.max_channel() / 2.0 - 1.0).abs()).fold(0.0, f64::max);
        let r = sol.energy.relative_residual();
        eprintln!("{oracle:?}: {} elements, worst rel err {worst:.2e}, residual {r:.2e}", sol.elements.len());
        assert!(sol.elements.len() > 6, "{oracle:?}: no refinement happened");
        assert!(r < 1e-6, "{oracle:?}: residual {r:e}");
    }
}

/// Direct light on the Cornell floor next to the short block, hierarchical against a Monte Carlo
/// estimate of the irradiance at every leaf's centroid (2 048 light samples each, so the
/// estimate's own error is ≈ 0.1 % on the area average). Measured: −0.1 % with the presets'
/// settings; the per-leaf normalisation, when it was on by default, made it −15 % (one ratio per
/// leaf mixed a dark block face with the light). 2 % leaves room for the centroid rule.
const DIRECT_FLOOR_TOL: f64 = 0.02;

#[test]
fn direct_light_is_not_biased_by_inherited_links() {
    use radlab::geometry::accel::Accel;
    use radlab::math::{Pcg32, Rgb};
    let full = radlab::scene::Scene::load("builtin:cornell").unwrap();
    let pick = |name: &str| full.patches.iter().find(|p| p.name.starts_with(name)).unwrap().clone();
    let mut patches = vec![pick("floor"), pick("light")];
    patches.extend(full.patches.iter().filter(|p| p.name.starts_with("short_block")).cloned());
    for p in patches.iter_mut().skip(1) {
        p.reflectance = Rgb::ZERO;
    }
    let scene = Arc::new(radlab::scene::Scene::new("floor-light-block", "test", patches));
    let p =
        HierarchicalParams { aeps: AreaEps::Relative(1e-4), bf_eps: 3e-4, ..HierarchicalParams::quality() };
    let mut s = HierarchicalSolver::new(Arc::clone(&scene), p).unwrap();
    s.solve(&mut |_, _| {});
    let accel = Accel::build(&scene);
    let light = &scene.patches[1];
    let mut rng = Pcg32::keyed(7, 7);
    let (mut h_sum, mut t_sum, mut area) = (0.0, 0.0, 0.0);
    let hier = s.hierarchy();
    for e in hier.elements.iter().filter(|e| e.is_leaf() && e.patch == 0) {
        let n = 2048;
        let mut acc = 0.0;
        for _ in 0..n {
            let y = radlab::geometry::visibility::point_on_polygon(
                &light.vertices,
                rng.next_f64(),
                rng.next_f64(),
            );
            let d = y - e.centroid;
            let r2 = d.length_squared();
            let (c1, c2) = (e.normal.dot(d) / r2.sqrt(), -light.normal.dot(d) / r2.sqrt());
            if c1 > 0.0 && c2 > 0.0 && !accel.occluded(e.centroid, y, [0, 1]) {
                acc += c1 * c2 / (std::f64::consts::PI * r2);
            }
        }
        let truth = light.emission.r() * light.area * acc / f64::from(n);
        h_sum += e.radiosity.r() / e.reflectance.r() * e.area;
        t_sum += truth * e.area;
        area += e.area;
    }
    let rel = h_sum / t_sum - 1.0;
    eprintln!(
        "floor irradiance: hierarchical {:.4}, Monte Carlo {:.4} ({:+.2} %)",
        h_sum / area,
        t_sum / area,
        100.0 * rel
    );
    assert!(hier.len() > 500, "the floor must be refined for this test to mean anything");
    assert!(rel.abs() < DIRECT_FLOOR_TOL, "direct floor irradiance off by {:+.2} %", 100.0 * rel);
}

/// Links per element on `perpendicular` with Feps fixed while Aeps halves: measured 9.1–10.8
/// (Feps 0.02, Aeps 0.02 … 0.00125); the bound leaves 10 % headroom.
const PERPENDICULAR_LINKS_PER_ELEMENT_BOUND: f64 = 12.0;

#[test]
fn links_per_element_stay_bounded_as_aeps_halves() {
    let mut aeps = 0.02;
    let mut elements = Vec::new();
    for _ in 0..5 {
        let p = HierarchicalParams {
            oracle: Oracle::Feps,
            feps: 0.02,
            aeps: AreaEps::Absolute(aeps),
            max_depth: 20,
            ..HierarchicalParams::lecture()
        };
        let st = solve(common::perpendicular(), p).stats();
        assert!(
            st.links_per_element < PERPENDICULAR_LINKS_PER_ELEMENT_BOUND,
            "aeps {aeps}: {} links / {} elements = {:.2}",
            st.links,
            st.elements,
            st.links_per_element
        );
        elements.push(st.elements);
        aeps /= 2.0;
    }
    assert!(elements.last() > elements.first(), "refinement must follow Aeps: {elements:?}");
}

/// O(n), not O(n²): log-log slope of links against elements in an enclosure, Feps fixed and Aeps
/// shrinking. Measured 0.79 on cube-one-light (Feps 0.05); quadratic growth would give 2.
const ENCLOSURE_SLOPE_MAX: f64 = 1.15;

#[test]
fn links_grow_linearly_with_elements_in_an_enclosure() {
    let mut pts = Vec::new();
    let mut aeps = 0.02;
    for _ in 0..4 {
        let p = HierarchicalParams {
            oracle: Oracle::Feps,
            feps: 0.05,
            aeps: AreaEps::Absolute(aeps),
            max_depth: 20,
            ..HierarchicalParams::lecture()
        };
        let st = solve(common::cube_one_light(0.5), p).stats();
        pts.push(((st.elements as f64).ln(), (st.links as f64).ln()));
        aeps /= 4.0;
    }
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    assert!(pts[3].0 - pts[0].0 > 1.5, "elements must span a decade: {pts:?}");
    assert!(slope < ENCLOSURE_SLOPE_MAX, "links ~ elements^{slope:.2} ({pts:?})");
}

fn bits(s: &HierarchicalSolver) -> (usize, usize, Vec<u64>) {
    let snap = s.snapshot();
    let b = snap.elements.iter().flat_map(|e| e.radiosity.0.map(f64::to_bits)).collect();
    (snap.elements.len(), snap.links.len(), b)
}

#[test]
fn identical_results_for_one_and_two_threads() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let p = HierarchicalParams {
                bf_eps: 0.05,
                bf_relative: false,
                aeps: AreaEps::Absolute(4e-4),
                ..HierarchicalParams::interactive()
            };
            bits(&solve(common::table_room(), p))
        })
    };
    let one = run(1);
    let two = run(2);
    assert!(one.0 > 100, "the run must refine");
    assert_eq!((one.0, one.1), (two.0, two.1), "element and link counts differ");
    assert!(one.2 == two.2, "radiosity values differ between 1 and 2 threads");
    assert!(run(2).2 == two.2, "two runs differ");
}

/// `iterate` runs gather and push-pull as one fused parallel sweep; the separate steps must give
/// the same bits, also with the snapshot's gathered irradiance and the energy balance.
#[test]
fn iterate_matches_separate_gather_and_push_pull_steps() {
    let p = HierarchicalParams { bf_eps: 0.05, bf_relative: false, ..HierarchicalParams::interactive() };
    let scene = Arc::new(common::table_room());
    let mut fused = HierarchicalSolver::new(Arc::clone(&scene), p).unwrap();
    let mut steps = HierarchicalSolver::new(scene, p).unwrap();
    for _ in 0..3 {
        fused.iterate();
        steps.refine_step();
        steps.gather_step();
        steps.push_pull_step();
        assert_eq!(bits(&fused), bits(&steps));
        let gathered = |s: &HierarchicalSolver| -> Vec<u64> {
            s.snapshot().elements.iter().flat_map(|e| e.gathered.0.map(f64::to_bits)).collect()
        };
        assert_eq!(gathered(&fused), gathered(&steps));
        let (a, b) = (fused.solution().energy, steps.solution().energy);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
}

/// Push-pull is area-weighted and exact: a gather followed by push-pull moves no
/// power between levels. After each step, every interior element holds the area average of its
/// children (pull: A B = Σ A_c B_c), and the power the leaves reflect is the power gathered at
/// every level, each element's own links' irradiance reflected over its area
/// (push: Σ_leaves A (B − E) = Σ_elements ρ A H_own; a slope moves light within an element's
/// leaves, about its centroid, and adds none). With slopes (`interactive`) and without
/// (`splash2`), on a closed box, on table-room and on trapezoids (whose children differ in area,
/// so that a plain average of them would fail), after refinements that leave links at many
/// levels.
#[test]
fn a_gather_and_push_pull_move_no_power_between_levels() {
    let trapezoids = radlab::scene::Scene::new(
        "trapezoids",
        "test:trapezoids",
        vec![
            common::quad([[0., 0., 0.], [2., 0., 0.], [1.5, 1., 0.], [0.2, 1., 0.]], 0.6, 0.0, "floor"),
            common::quad([[0., 0., 0.], [0.3, 0., 0.8], [1.2, 0., 0.8], [2., 0., 0.]], 0.4, 0.0, "wall"),
            common::quad([[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]], 0.5, 1.0, "light"),
        ],
    );
    for (scene, name) in [
        (common::cube_one_light(0.5), "cube-one-light"),
        (common::table_room(), "table-room"),
        (trapezoids, "trapezoids"),
    ] {
        let scene = Arc::new(scene);
        // Push-pull alone: the closed rows (`close_rows`) scale an enclosed leaf's pushed
        // irradiance by its balance factor, which this sum over the levels does not count.
        for (preset, p) in [
            (
                "interactive",
                HierarchicalParams {
                    bf_eps: 0.02,
                    bf_relative: false,
                    close_rows: false,
                    ..HierarchicalParams::interactive()
                },
            ),
            (
                "splash2",
                HierarchicalParams {
                    aeps: AreaEps::Relative(1e-4),
                    bf_eps: 0.005,
                    close_rows: false,
                    ..HierarchicalParams::splash2()
                },
            ),
        ] {
            let mut s = HierarchicalSolver::new(Arc::clone(&scene), p).unwrap();
            let (mut levels, mut interior) = (0, 0);
            for round in 0..3 {
                s.refine_step();
                s.gather_step();
                s.push_pull_step();
                let els = s.snapshot().elements;
                levels = els.iter().map(|e| e.depth).max().unwrap_or(0);
                // Elements above the leaves that gather through links of their own.
                interior =
                    els.iter().filter(|e| e.children.is_some() && e.gathered.max_channel() > 0.0).count();
                let (mut reflected, mut gathered) = ([0.0; 3], [0.0; 3]);
                for e in &els {
                    for (c, g) in gathered.iter_mut().enumerate() {
                        *g += e.reflectance.0[c] * e.area * e.gathered.0[c];
                    }
                    match e.children {
                        None => {
                            for (c, r) in reflected.iter_mut().enumerate() {
                                *r += e.area * (e.radiosity.0[c] - e.emission.0[c]);
                            }
                        }
                        Some(kids) => {
                            for c in 0..3 {
                                let own = e.area * e.radiosity.0[c];
                                let sum: f64 = kids
                                    .iter()
                                    .map(|&k| {
                                        let k = &els[k as usize];
                                        k.area * k.radiosity.0[c]
                                    })
                                    .sum();
                                assert!(
                                    (own - sum).abs() <= 1e-9 * own.abs().max(sum.abs()).max(1e-300),
                                    "{name} {preset} round {round}: element {} holds {own}, its children {sum}",
                                    e.id
                                );
                            }
                        }
                    }
                }
                for c in 0..3 {
                    assert!(gathered[c] > 0.0, "{name} {preset}: nothing gathered");
                    assert!(
                        (reflected[c] - gathered[c]).abs() <= 1e-9 * gathered[c],
                        "{name} {preset} round {round}, channel {c}: the leaves reflect {} of {} gathered",
                        reflected[c],
                        gathered[c]
                    );
                }
            }
            assert!(levels >= 3, "{name} {preset}: a deeper mesh wanted, it has {levels} levels");
            assert!(interior > 0, "{name} {preset}: no element above the leaves gathers: nothing is pushed");
            if name == "trapezoids" {
                let els = s.snapshot().elements;
                let unequal = els.iter().filter_map(|e| e.children).any(|k| {
                    let a = k.map(|c| els[c as usize].area);
                    a.iter().any(|x| (x / a[0] - 1.0).abs() > 0.05)
                });
                assert!(unequal, "trapezoids: children of unequal area wanted");
            }
        }
    }
}

/// The early exits of link visibility (stop at the first unblocked ray, or at the first mix of
/// unblocked and blocked rays, when that settles what the next pass does) cast fewer rays and
/// change nothing else: the same elements, links and radiosity bits as casting every ray.
#[test]
fn early_exits_cast_fewer_rays_and_change_nothing() {
    let p = HierarchicalParams {
        bf_eps: 0.02,
        bf_relative: false,
        aeps: AreaEps::Absolute(2e-4),
        ..HierarchicalParams::interactive()
    };
    let run = |early: bool| {
        let mut s = HierarchicalSolver::new(Arc::new(common::table_room()), p).unwrap();
        s.set_early_exit(early);
        s.solve(&mut |_, _| {});
        (bits(&s), s.stats().rays)
    };
    let (with, rays_with) = run(true);
    let (without, rays_without) = run(false);
    assert!(with.0 > 100, "the run must refine");
    assert_eq!((with.0, with.1), (without.0, without.1), "element and link counts differ");
    assert!(with.2 == without.2, "radiosity values differ with the early exits");
    assert!(rays_with < rays_without, "no ray saved: {rays_with} against {rays_without}");
}

/// Energy balance at convergence, |emitted − absorbed − escaped| / emitted. It measures the
/// reciprocity error of one-directional links (A_i F_ij V_ij ≠ A_j F_ji V_ji when the two
/// directions are refined to different levels), so it is a discretisation error, not round-off.
/// Measured with BFeps 0.05, 16 rays: cube-one-light 2.8 %, table-room 2.0 %.
const CONVERGED_ENERGY_TOL: f64 = 0.04;
/// While Jacobi iterates, power is still in flight: absorbed + escaped grows towards emitted and
/// may never exceed it by more than the discretisation error.
const IN_FLIGHT_OVERSHOOT_TOL: f64 = 0.04;

#[test]
fn every_step_is_finite_and_keeps_energy_balance() {
    for scene in [common::cube_one_light(0.5), common::table_room()] {
        let name = scene.name.clone();
        let p = HierarchicalParams {
            bf_eps: 0.05,
            bf_relative: false,
            aeps: AreaEps::Absolute(4e-4),
            rays: 16,
            ..HierarchicalParams::interactive()
        };
        let mut s = HierarchicalSolver::new(Arc::new(scene), p).unwrap();
        let check = |s: &HierarchicalSolver, step: &str| {
            let sol = s.solution();
            assert!(sol.is_physical(), "{name} after {step}: non-finite or negative radiosity");
            assert!(s.snapshot().links.iter().all(|l| l.ff.is_finite() && (0.0..=1.0).contains(&l.vis)));
            let e = sol.energy;
            let out = e.absorbed.mean() + e.escaped.mean();
            assert!(
                out.is_finite() && out <= e.emitted.mean() * (1.0 + IN_FLIGHT_OVERSHOOT_TOL),
                "{name} after {step}: {e:?}"
            );
            e.relative_residual()
        };
        check(&s, "new");
        s.refine_step();
        check(&s, "refine");
        let mut residuals = Vec::new();
        for _ in 0..30 {
            s.gather_step();
            check(&s, "gather");
            s.push_pull_step();
            residuals.push(check(&s, "push-pull"));
        }
        assert!(residuals[29] < residuals[0], "{name}: balance must converge: {residuals:?}");
        for _ in 0..3 {
            s.iterate();
            check(&s, "iterate");
        }
        s.solve(&mut |_, _| {});
        let r = check(&s, "solve");
        assert!(r < CONVERGED_ENERGY_TOL, "{name}: converged energy residual {r:.3e}");
    }
}

/// Link budget for the termination sweep: the presets' own budgets (0.5–4 M links) also bound
/// termination, but take minutes in a debug build on the big rooms; a pass may overshoot the
/// budget by what one pass creates, at most 4 links per link.
const SWEEP_MAX_LINKS: usize = 60_000;

#[test]
fn every_preset_terminates_within_budget_on_every_builtin_scene() {
    for &(scene_name, _) in radlab::scene::builtin::BUILTINS {
        let scene = radlab::scene::Scene::load(&format!("builtin:{scene_name}")).unwrap();
        for name in HierarchicalParams::PRESETS {
            let mut p = HierarchicalParams::preset(name).unwrap();
            p.max_links = SWEEP_MAX_LINKS;
            if let AreaEps::Absolute(_) = p.aeps {
                // splash2's absolute floor is in the SPLASH-2 room's units; keep its ratio elsewhere.
                if !scene_name.starts_with("splash") {
                    p.aeps = AreaEps::Relative(2000.0 / 1.6e7);
                }
            }
            let s = solve(scene.clone(), p);
            let st = s.stats();
            assert!(st.links <= 5 * SWEEP_MAX_LINKS, "{name} on {scene_name}: {} links", st.links);
            assert!(s.solution().is_physical(), "{name} on {scene_name}: unphysical");
            assert!(st.rounds <= p.max_rounds as usize);
        }
    }
}

#[test]
fn restart_with_new_parameters_reuses_and_matches_a_fresh_solver() {
    let p1 = HierarchicalParams { bf_eps: 0.1, bf_relative: false, ..HierarchicalParams::interactive() };
    let p2 = HierarchicalParams { bf_eps: 0.05, bf_relative: false, ..HierarchicalParams::interactive() };
    let mut s = solve(common::table_room(), p1);
    s.set_params(p2).unwrap();
    s.solve(&mut |_, _| {});
    let fresh = solve(common::table_room(), p2);
    assert!(bits(&s) == bits(&fresh), "restart must give the same result as a fresh solver");
    assert!(s.set_params(HierarchicalParams { rays: 0, ..p2 }).is_err());
}

#[test]
fn cancel_stops_a_step_and_leaves_a_consistent_state() {
    let p = HierarchicalParams {
        bf_eps: 0.01,
        bf_relative: false,
        aeps: AreaEps::Absolute(1e-4),
        ..HierarchicalParams::interactive()
    };
    let mut s = HierarchicalSolver::new(Arc::new(common::table_room()), p).unwrap();
    let flag = s.cancel_handle();
    let mut calls = 0;
    let r = s.solve(&mut |_, _| {
        calls += 1;
        if calls == 2 {
            flag.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    });
    assert!(r.cancelled);
    assert!(s.solution().is_physical());
    s.gather_step();
    s.push_pull_step();
    assert!(s.solution().is_physical());
}

/// Refinement stopped by the link budget mid-pass leaves every link measured: V in [0, 1] (links
/// the next pass would have replaced carry only "some ray passes" until then).
#[test]
fn a_budget_stop_leaves_every_visibility_measured() {
    for max_links in [500, 2_000, 8_000] {
        let p = HierarchicalParams {
            bf_eps: 0.002,
            bf_relative: false,
            aeps: AreaEps::Absolute(1e-5),
            max_links,
            ..HierarchicalParams::interactive()
        };
        let mut s = HierarchicalSolver::new(Arc::new(common::table_room()), p).unwrap();
        s.refine_step();
        s.gather_step();
        s.push_pull_step();
        s.refine_step();
        assert!(s.stats().budget_hit, "max_links {max_links}: the budget must stop refinement");
        let snap = s.snapshot();
        assert!(
            snap.links.iter().all(|l| (0.0..=1.0).contains(&l.vis)),
            "max_links {max_links}: a link left unmeasured"
        );
        assert!(s.solution().is_physical());
    }
}

/// Area-weighted relative L1 difference of per-patch radiosity (mean over channels), emitters excluded.
fn patch_l1(
    reference: &radlab::solver::Solution,
    s: &radlab::solver::Solution,
    scene: &radlab::scene::Scene,
) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, p) in scene.patches.iter().enumerate() {
        if p.is_emitter() {
            continue;
        }
        num += p.area * (reference.patch_radiosity[i].mean() - s.patch_radiosity[i].mean()).abs();
        den += p.area * reference.patch_radiosity[i].mean();
    }
    num / den
}

/// Below this relative L1 the comparison with the uniform solution cannot rank two solutions:
/// halving the uniform solution's element size moves it by 0.05 % on cube-one-light (below).
const UNIFORM_FLOOR: f64 = 1e-3;

/// Hierarchical against the uniform-mesh solver at a fine element size, at a coarse and a fine
/// BFeps (`quality` preset otherwise, with the BF oracle). The uniform references are converged:
/// halving their element size changes them by 0.3 % (cornell, 60 → 35 units) and 0.05 % (cube,
/// 0.1 → 0.05). Measured since leaves gather their ancestors' links along the links' slopes
/// (`Link::slope`; tolerances ~25 % above): cornell 3.5 % → 1.6 % (BFeps 1e-2 → 2e-3),
/// cube-one-light 0.05 % and 0.07 % (1e-2, 1e-3: both within the uniform solution's own
/// accuracy, `UNIFORM_FLOOR`). Before, with constants pushed down: cornell 9.95 % → 7.1 %,
/// saturating near 7 % below BFeps 2e-3, and cube-one-light 3.7 % → 0.32 %.
#[test]
fn hierarchical_approaches_the_fine_uniform_solution_as_bf_eps_shrinks() {
    use radlab::solver::uniform::{COARSE_FF_TOLERANCE, UniformParams, solve as uniform};
    for (name, size, coarse, fine, tol_coarse, tol_fine) in
        [("cornell", 60.0, 1e-2, 2e-3, 0.045, 0.02), ("cube-one-light", 0.1, 1e-2, 1e-3, 0.002, 0.002)]
    {
        let scene = radlab::scene::Scene::load(&format!("builtin:{name}")).unwrap();
        let accel = radlab::geometry::accel::Accel::build(&scene);
        let up = UniformParams {
            element_size: size,
            rays: 16,
            ff_tolerance: COARSE_FF_TOLERANCE,
            ..UniformParams::default()
        };
        let reference = uniform(&scene, &accel, &up, &mut |_, _| {}).unwrap();
        let mut errs = Vec::new();
        for (bf, tol) in [(coarse, tol_coarse), (fine, tol_fine)] {
            // The BF oracle at the quality preset's former settings (the preset now uses the
            // error oracle, whose convergence tests/exact.rs checks against exact answers).
            let p = HierarchicalParams {
                oracle: Oracle::Bf,
                bf_eps: bf,
                bf_relative: true,
                aeps: AreaEps::Relative(5e-5),
                ..HierarchicalParams::quality()
            };
            let s = solve(scene.clone(), p);
            let e = patch_l1(&reference, &s.solution(), &scene);
            eprintln!("{name} BFeps {bf}: L1 {e:.4} (tol {tol})");
            assert!(e < tol, "{name} BFeps {bf}: L1 {e:.4} >= {tol}");
            errs.push(e);
        }
        // Below UNIFORM_FLOOR both solutions agree with the uniform one to its own accuracy and
        // the comparison cannot rank them.
        assert!(
            errs[1] < errs[0] || errs[0] < UNIFORM_FLOOR,
            "{name}: error must shrink with BFeps: {errs:?}"
        );
    }
}

/// Gauss–Seidel and Jacobi solve the same linear system: on a mesh that does not depend on the
/// radiosity (the Feps oracle), both converge to the same B. Their difference is bounded by the
/// stopping tolerance (1e-9 relative change per sweep, ρ ≤ 0.8 on this scene), with room for
/// rounding.
const GS_JACOBI_TOL: f64 = 1e-6;

#[test]
fn gauss_seidel_converges_to_the_jacobi_solution_in_fewer_sweeps() {
    let run = |gauss_seidel: bool| {
        let p = HierarchicalParams {
            oracle: Oracle::Feps,
            feps: 0.02,
            aeps: AreaEps::Absolute(2e-3),
            tolerance: 1e-9,
            max_iterations: 2000,
            gauss_seidel,
            // Gauss–Seidel gathers without the closed rows; Jacobi likewise, to compare.
            close_rows: false,
            ..HierarchicalParams::interactive()
        };
        solve(common::table_room(), p)
    };
    let (j, g) = (run(false), run(true));
    let (sj, sg) = (j.solution(), g.solution());
    assert_eq!(sj.elements.len(), sg.elements.len(), "the Feps mesh must not depend on the sweep order");
    assert!(sg.is_physical());
    let scale = sj.elements.iter().map(|e| e.radiosity.max_channel()).fold(0.0, f64::max);
    let worst = sj
        .elements
        .iter()
        .zip(&sg.elements)
        .map(|(a, b)| a.radiosity.abs_diff_max(b.radiosity) / scale)
        .fold(0.0, f64::max);
    assert!(worst < GS_JACOBI_TOL, "Gauss–Seidel differs from Jacobi by {worst:e} (relative to max B)");
    let (ij, ig) = (j.stats().iterations, g.stats().iterations);
    assert!(ig < ij, "Gauss–Seidel took {ig} sweeps, Jacobi {ij}");
    let (ej, eg) = (sj.energy.relative_residual(), sg.energy.relative_residual());
    assert!(
        (ej - eg).abs() < GS_JACOBI_TOL * 10.0,
        "energy residuals differ: Jacobi {ej:e}, Gauss–Seidel {eg:e}"
    );
}

/// Refining after a few gathers instead of after convergence (`round_iterations`), and ending
/// refinement once a refinement of the converged solution adds at most `settle` of the links,
/// change the mesh a little and the solution very little. Measured on cornell (interactive):
/// per-patch L1 difference 0.13 %, links −0.07 %, 12 instead of 20 gathers; against the
/// independent reference the relative L2 error moves by under 0.1 points on cornell and
/// splash_room for every preset (README). Tolerances: about four times the L1 measured, and
/// twice the spread of link counts over visibility seeds 0–4 on splash_room (0.7 %), rounded up.
const SCHEDULE_L1_TOL: f64 = 0.005;
const SCHEDULE_LINKS_TOL: f64 = 0.02;

#[test]
fn gathering_between_refinements_matches_converging_every_round() {
    let scene = radlab::scene::Scene::load("builtin:cornell").unwrap();
    let base = HierarchicalParams::interactive();
    let strict = HierarchicalParams { round_iterations: base.max_iterations, settle: 0.0, ..base };
    let (a, b) = (solve(scene.clone(), strict), solve(scene.clone(), base));
    for (name, s, p) in [("strict", &a, strict), ("scheduled", &b, base)] {
        assert!(s.is_converged(), "{name}: the solve must end converged");
        assert!(s.solution().is_physical(), "{name}: unphysical");
        assert!(s.stats().rounds <= p.max_rounds as usize);
    }
    let l1 = patch_l1(&a.solution(), &b.solution(), &scene);
    let (la, lb) = (a.stats().links as f64, b.stats().links as f64);
    let (ia, ib) = (a.stats().iterations, b.stats().iterations);
    eprintln!("patch L1 {l1:.4}, links {la} → {lb}, gathers {ia} → {ib}");
    assert!(l1 < SCHEDULE_L1_TOL, "patch L1 difference {l1:.4}");
    assert!((lb / la - 1.0).abs() < SCHEDULE_LINKS_TOL, "links {la} → {lb}");
    assert!(ib < ia, "the schedule must save gathers: {ia} → {ib}");
}

#[test]
fn absurd_schedule_parameters_are_refused_with_their_names() {
    for name in HierarchicalParams::PRESETS {
        assert_eq!(HierarchicalParams::preset(name).unwrap().validate(), Ok(()), "preset {name}");
    }
    let p = HierarchicalParams::interactive();
    let e = HierarchicalParams { round_iterations: 0, ..p }.validate().unwrap_err();
    assert!(e.contains("round-iterations"), "{e}");
    for settle in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
        let e = HierarchicalParams { settle, ..p }.validate().unwrap_err();
        assert!(e.contains("settle"), "{settle}: {e}");
    }
    assert_eq!(HierarchicalParams { settle: 0.0, round_iterations: 1, ..p }.validate(), Ok(()));
    for partial_bf_factor in [0.0, -0.5, 1.5, f64::NAN] {
        let e = HierarchicalParams { partial_bf_factor, ..p }.validate().unwrap_err();
        assert!(e.contains("partial-bf-factor"), "{partial_bf_factor}: {e}");
    }
}

/// Area-weighted mean radiosity of the patches that emit nothing (their reflected light).
fn mean_reflected(s: &HierarchicalSolver) -> f64 {
    let sol = s.solution();
    let scene = s.scene();
    let (mut sum, mut area) = (0.0, 0.0);
    for e in &sol.elements {
        if scene.patches[e.patch].emission.max_channel() == 0.0 {
            sum += e.radiosity.mean() * e.area;
            area += e.area;
        }
    }
    sum / area
}

/// splash_room at the `splash2` preset with 2 rays per link: the mean reflected radiosity within
/// this of the 8-ray solution's. Measured 3.3 % (2 rays, lower); without re-testing zero
/// estimates 16 % lower.
const FEW_RAYS_MEAN_TOL: f64 = 0.05;

#[test]
fn confirming_zero_estimates_removes_the_dark_bias_of_few_rays() {
    // A link the oracle refines at any visibility but 0 stops refining only on a zero estimate;
    // a noisy zero then drops the light of the pair, at every level of refinement.
    let scene = radlab::scene::Scene::load("builtin:splash_room").unwrap();
    let p = HierarchicalParams { rays: 2, ..HierarchicalParams::splash2() };
    assert!(p.zero_confirm > 0, "the splash2 preset confirms zeros");
    let fine = mean_reflected(&solve(scene.clone(), HierarchicalParams { rays: 8, ..p }));
    let few = mean_reflected(&solve(scene.clone(), p));
    let unconfirmed = mean_reflected(&solve(scene, HierarchicalParams { zero_confirm: 0, ..p }));
    eprintln!("mean reflected B: 8 rays {fine:.5}, 2 rays {few:.5}, 2 rays unconfirmed {unconfirmed:.5}");
    assert!((few / fine - 1.0).abs() < FEW_RAYS_MEAN_TOL, "2 rays {few} against 8 rays {fine}");
    // The bias the test removes is real: without it the same run is clearly darker.
    assert!(unconfirmed / fine < 1.0 - 2.0 * FEW_RAYS_MEAN_TOL, "unconfirmed {unconfirmed} against {fine}");
}

/// Links are mirror images with one Galerkin coupling: for every link r ← s there
/// is a link s ← r with the same visibility and A_r F_rs = A_s F_sr. The form factors are
/// stored as f32, so the products agree to f32 rounding (6e-8 relative; 1e-6 allows for the
/// division by two different areas).
const MIRROR_REL: f64 = 1e-6;

#[test]
fn links_are_mirror_images_with_reciprocal_form_factors() {
    for (scene, p) in [
        (radlab::scene::Scene::load("builtin:cornell").unwrap(), HierarchicalParams::interactive()),
        (radlab::scene::Scene::load("builtin:cornell").unwrap(), HierarchicalParams::splash2()),
        (common::table_room(), HierarchicalParams::quality()),
    ] {
        let name = scene.name.clone();
        let s = solve(scene, p);
        let snap = s.snapshot();
        assert!(snap.links.len() > 200, "{name}: the run must refine");
        assert_mirror_images(&name, &snap);
    }
}

/// Every link r ← s has a mirror s ← r with the same visibility and A_r F_rs = A_s F_sr.
fn assert_mirror_images(name: &str, snap: &radlab::solver::hierarchical::Snapshot) {
    let mut by_pair = std::collections::HashMap::new();
    for l in &snap.links {
        assert!(by_pair.insert((l.receiver, l.source), *l).is_none(), "{name}: duplicate link");
    }
    let area = |i: u32| snap.elements[i as usize].area;
    for l in &snap.links {
        let m = by_pair.get(&(l.source, l.receiver)).unwrap_or_else(|| panic!("{name}: no mirror of {l:?}"));
        assert_eq!(m.vis.to_bits(), l.vis.to_bits(), "{name}: {l:?} against {m:?}");
        let (a, b) = (area(l.receiver) * f64::from(l.ff), area(l.source) * f64::from(m.ff));
        assert!((a - b).abs() <= MIRROR_REL * a.max(b), "{name}: A F {a} against {b}");
    }
}

/// Under the error oracle, the pass that would overrun the link budget splits only the pairs
/// of the largest receiver errors: the links end near the budget (within the estimate of what a
/// split adds; finishing the pass overran it: builtin:table-room on its patches at 20 000 ended at
/// 24 760 links), every link keeps its mirror,
/// the balance closes and the leaves left unsplit say that the budget stopped them.
#[test]
fn an_error_oracle_budget_stop_keeps_the_budget_and_the_mirrors() {
    let max_links = 20_000;
    let s = solve(common::table_room(), HierarchicalParams { max_links, ..HierarchicalParams::quality() });
    let stats = s.stats();
    assert!(stats.budget_hit, "the budget must stop refinement ({} links)", stats.links);
    assert!(
        stats.links <= max_links + max_links / 10,
        "{} links against a budget of {max_links}",
        stats.links
    );
    let snap = s.snapshot();
    assert_mirror_images("table-room", &snap);
    assert!(
        snap.elements.iter().any(|e| e.children.is_none() && e.stop == StopReason::LinkBudget),
        "no leaf says the budget stopped it"
    );
    let e = s.solution().energy;
    assert!(e.relative_residual() <= BALANCE_TOL, "residual {:.2e}", e.relative_residual());
}

/// Energy balance of converged solves: mirror links make what a source sends
/// through a pair exactly what the receiver gathers, so `relative_residual` is left only with the
/// last gather's change, which every solve iterates below `ENERGY_TOLERANCE` (1e-3).
const BALANCE_TOL: f64 = 1e-3;
/// Light created (−escaped / emitted, and absorbed beyond emitted), to the balance's own 1e-3: a
/// leaf's total form factor over links at several levels is 1 only on average (see
/// `a_refined_furnace_conserves_power`), and the row check (`row_tol`) pushes down the links of
/// leaves whose rows exceed 1. Measured (release): the furnace at `lecture`, whose
/// Feps oracle runs without the row check, −7.5e-4; cube-one-light at `lecture` −2.7e-4, at
/// `interactive` −5.8e-6 (−0.45 % while its link budget stopped it half-way, see
/// `HierarchicalParams::interactive`); every other scene and preset ≥ −6e-8 (the exact
/// furnace's rounding).
const CREATED_TOL: f64 = 1e-3;

/// Every built-in scene at every preset, as the presets are: the balance closes to 1e-3 and no
/// light is created beyond it.
#[test]
fn every_preset_conserves_energy() {
    for &(scene_name, _) in radlab::scene::builtin::BUILTINS {
        let scene = radlab::scene::Scene::load(&format!("builtin:{scene_name}")).unwrap();
        for preset in HierarchicalParams::PRESETS {
            let s = solve(scene.clone(), HierarchicalParams::preset(preset).unwrap());
            let e = s.solution().energy;
            let r = e.relative_residual();
            assert!(r <= BALANCE_TOL, "{preset} on {scene_name}: residual {r:.2e} ({e:?})");
            for c in 0..3 {
                let emitted = e.emitted.0[c];
                assert!(
                    e.escaped.0[c] >= -CREATED_TOL * emitted,
                    "{preset} on {scene_name}: light created, channel {c}: escaped {:.2e} of the emitted ({e:?})",
                    e.escaped.0[c] / emitted
                );
                assert!(
                    e.absorbed.0[c] <= emitted * (1.0 + CREATED_TOL),
                    "{preset} on {scene_name}: absorbed more than emitted ({e:?})"
                );
            }
        }
    }
}

/// The error oracle models only what the scene needs: the white furnace, whose
/// total gathered radiosity is uniform across every face (Σ_q F(x → q) = 1 at every point),
/// is not refined at all and is exact; cube-one-light, whose faces' irradiance varies, is.
#[test]
fn the_error_oracle_leaves_the_furnace_alone_and_refines_a_lit_box() {
    // Iterated to 1e-10, so that what is left is the links' error, not the iteration's.
    let p = HierarchicalParams {
        oracle: Oracle::Error,
        bf_eps: 0.01,
        tolerance: 1e-10,
        ..HierarchicalParams::quality()
    };
    let s = solve(common::furnace(0.5, 1.0), p);
    let sol = s.solution();
    assert_eq!(sol.elements.len(), 6, "the furnace needs one element per face");
    for e in &sol.elements {
        let rel = (e.radiosity.mean() - 2.0).abs() / 2.0;
        assert!(rel < FURNACE_TOL, "furnace B {:?} (rel {rel:.2e})", e.radiosity);
    }
    let s = solve(common::cube_one_light(0.5), p);
    let sol = s.solution();
    assert!(sol.elements.len() > 50, "cube-one-light must refine: {}", sol.elements.len());
    assert!(sol.is_physical());
    let r = sol.energy.relative_residual();
    assert!(r <= BALANCE_TOL, "cube-one-light residual {r:.2e}");
}

/// The error oracle's field is updated pass by pass only where links changed; recomputing it
/// everywhere every pass must give the very same mesh and answer.
#[test]
fn the_error_oracle_update_changes_nothing() {
    // cube-one-light: BFeps 0.01 absolute (882 elements); table-room: 20 % of the mean reflected
    // radiosity (about 270 elements). Both cheap enough for a debug build.
    for (scene, bf_eps, bf_relative) in
        [(common::cube_one_light(0.5), 0.01, false), (common::table_room(), 0.2, true)]
    {
        let name = scene.name.clone();
        let p = HierarchicalParams {
            oracle: Oracle::Error,
            bf_eps,
            bf_relative,
            ..HierarchicalParams::interactive()
        };
        let scene = Arc::new(scene);
        let mut fast = HierarchicalSolver::new(Arc::clone(&scene), p).unwrap();
        fast.solve(&mut |_, _| {});
        let mut full = HierarchicalSolver::new(scene, p).unwrap();
        full.set_full_error_passes(true);
        full.solve(&mut |_, _| {});
        let (a, b) = (fast.solution(), full.solution());
        assert!(a.elements.len() > 20, "{name}: the run must refine ({} elements)", a.elements.len());
        assert_eq!(a.elements.len(), b.elements.len(), "{name}: elements");
        assert_eq!(fast.links().len(), full.links().len(), "{name}: links");
        for (x, y) in a.elements.iter().zip(&b.elements) {
            assert_eq!(x.radiosity, y.radiosity, "{name}");
        }
    }
}

/// The `quality` preset creates no light in the closed rooms: escaped ≥ 0 in every channel, so
/// absorbed ≤ emitted. What it guards against: table-room escaped −0.8 % of its light with
/// all-visible estimates accepted unconfirmed by the error oracle and a visibility sampler
/// biased by one fixed pairing of strata, and splash_room −1.9 % with its poster, lying in the
/// plane of wall 1, receiving the same light as the wall under it (hence `scene::decal`).
#[test]
fn quality_creates_no_light_in_the_closed_rooms() {
    for name in ["table-room", "splash_room"] {
        let scene = radlab::scene::Scene::load(&format!("builtin:{name}")).unwrap();
        let mut s = HierarchicalSolver::new(Arc::new(scene), HierarchicalParams::quality()).unwrap();
        s.solve(&mut |_, _| {});
        let e = s.solution().energy;
        for c in 0..3 {
            assert!(e.escaped.0[c] >= 0.0, "{name}: light created, channel {c}: {e:?}");
            assert!(e.absorbed.0[c] <= e.emitted.0[c], "{name}: absorbed more than emitted: {e:?}");
        }
        assert!(e.relative_residual() < 1e-3, "{name}: {e:?}");
    }
}

/// The row check (`HierarchicalParams::row_tol`) stops the light that coarse inherited links
/// created where a leaf's row of F·V exceeded 1: without it, cube-one-light `quality` escaped
/// −0.33 % of its emitted power and table-room `interactive` −2.1 %; with it +0.11 % and +0.8 %.
/// Both halves are asserted, so the test fails if the check stops acting. The closed rows
/// (`close_rows`), which balance the rows of enclosed leaves whatever the links, are off in both.
#[test]
fn the_row_check_stops_light_creation() {
    let escaped = |name: &str, p: HierarchicalParams| {
        let scene = radlab::scene::Scene::load(&format!("builtin:{name}")).unwrap();
        let e = solve(scene, p).solution().energy;
        assert!(e.relative_residual() < 1e-3, "{name}: {e:?}");
        (0..3).map(|c| e.escaped.0[c] / e.emitted.0[c]).fold(f64::INFINITY, f64::min)
    };
    for (name, p) in [
        ("cube-one-light", HierarchicalParams { close_rows: false, ..HierarchicalParams::quality() }),
        ("table-room", HierarchicalParams { close_rows: false, ..HierarchicalParams::interactive() }),
    ] {
        assert!(p.row_tol > 0.0);
        let on = escaped(name, p);
        let off = escaped(name, HierarchicalParams { row_tol: 0.0, ..p });
        assert!(on >= 0.0, "{name}: the row check leaves {:.3} % of the light created", -100.0 * on);
        assert!(off < -1e-3, "{name}: without the row check escaped {:.3} % (no light created)", 100.0 * off);
    }
}

/// The signed tail (`ErrorTail::Signed`) counts a wrong receiver's unsplit links as they add to
/// its error (kernels with signs, penumbras in quadrature), not as the sum of their shares: at
/// the same threshold it leaves fewer links (table-room at ε 0.1: 44 316 linear, 17 002 signed,
/// measured in a release build), and the solve still closes its energy and creates no light.
#[test]
fn the_signed_tail_splits_fewer_links_and_creates_no_light() {
    let scene = || radlab::scene::Scene::load("builtin:table-room").unwrap();
    let base = HierarchicalParams { bf_eps: 0.1, bf_relative: true, ..HierarchicalParams::quality() };
    assert_eq!(base.error_tail, ErrorTail::Linear, "every preset takes the linear tail");
    let run = |error_tail: ErrorTail| {
        let s = solve(scene(), HierarchicalParams { error_tail, ..base });
        let e = s.solution().energy;
        assert!(e.relative_residual() < 1e-3, "{error_tail:?}: {e:?}");
        for c in 0..3 {
            assert!(e.escaped.0[c] >= 0.0, "{error_tail:?}: light created, channel {c}: {e:?}");
            assert!(e.absorbed.0[c] <= e.emitted.0[c], "{error_tail:?}: absorbed more than emitted: {e:?}");
        }
        s.stats().links
    };
    let (linear, signed) = (run(ErrorTail::Linear), run(ErrorTail::Signed));
    assert!((signed as f64) < 0.6 * linear as f64, "links: linear {linear}, signed {signed}");
}

/// The error oracle's tail share (`HierarchicalParams::cause_tail`) is a real knob: at the same
/// threshold a larger share splits fewer of a wrong receiver's links (fewer links in all), the
/// solve still conserves energy, and shares outside (0, 1] are refused.
#[test]
fn the_tail_share_trades_links_for_error() {
    let scene = || radlab::scene::Scene::load("builtin:table-room").unwrap();
    let base = HierarchicalParams { bf_eps: 0.1, bf_relative: true, ..HierarchicalParams::quality() };
    assert_eq!(base.oracle, Oracle::Error);
    assert_eq!(base.cause_tail, radlab::solver::params::DEFAULT_CAUSE_TAIL);
    let links = |tail: f64| {
        let s = solve(scene(), HierarchicalParams { cause_tail: tail, ..base });
        let e = s.solution().energy;
        assert!(e.relative_residual() < 1e-3, "tail {tail}: {e:?}");
        s.stats().links
    };
    let (quarter, half, whole) = (links(0.25), links(0.5), links(1.0));
    assert!(half < quarter && whole < half, "links {quarter} {half} {whole}");
    for bad in [0.0, -0.1, 1.5, f64::NAN] {
        assert!(HierarchicalParams { cause_tail: bad, ..base }.validate().is_err(), "{bad}");
    }
}
