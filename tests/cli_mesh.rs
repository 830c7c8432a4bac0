//! `radlab solve --mesh quadtree|uniform|discontinuity-cdt|discontinuity-bsp --order 0|1`: every
//! mesh solves, `--dump-hierarchy` writes its elements with vertices and basis coefficients
//! (docs/meshing.md, "The element dump"), and the combinations that make no sense are refused
//! with one line.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Command;

fn radlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_radlab")).args(args).output().unwrap()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("radlab-cli-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Solve shadow-narrow with `flags`, dumping the elements; returns (solve JSON, dump).
fn solve_and_dump(flags: &[&str], tag: &str) -> (serde_json::Value, serde_json::Value) {
    let (json, dump) = (temp(&format!("{tag}.json")), temp(&format!("{tag}-dump.json")));
    let mut args = vec!["solve", "builtin:shadow-narrow", "-q", "--json"];
    args.push(json.to_str().unwrap());
    args.extend(["--dump-hierarchy", dump.to_str().unwrap()]);
    args.extend(flags);
    let out = radlab(&args);
    assert!(out.status.success(), "{flags:?}: {}", String::from_utf8_lossy(&out.stderr));
    let read = |p: &PathBuf| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    (read(&json), read(&dump))
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap()
}

#[test]
fn every_mesh_solves_and_dumps_its_elements_with_coefficients() {
    // shadow-narrow: receiver 2 × 2, lamp 0.2 × 0.2, occluder 0.6 × 0.6 (one-sided quads).
    let total_area = 4.0 + 0.04 + 0.36;
    for (mesh, method, extra) in [
        ("quadtree", "hierarchical", &["--preset", "interactive"][..]),
        ("uniform", "uniform", &["--element-size", "0.25"][..]),
        ("discontinuity-cdt", "discontinuity-cdt", &[][..]),
        ("discontinuity-bsp", "discontinuity-bsp", &[][..]),
    ] {
        let mut flags = vec!["--mesh", mesh];
        flags.extend(extra);
        let (doc, dump) = solve_and_dump(&flags, mesh);
        assert_eq!(doc["mesh"], mesh);
        assert_eq!(doc["method"], method);
        assert_eq!(dump["mesh"], mesh);
        // The hierarchical solver's leaves and the discontinuity meshes' gathered pieces carry
        // slopes (linear per element); the uniform mesh's classical solve gives none.
        let sloped_mesh = mesh != "uniform";
        assert_eq!(dump["basis"], if sloped_mesh { "p0-slope" } else { "p0" });
        assert_eq!(dump["format"], "radlab-elements-1");
        let elements = dump["elements"].as_array().unwrap();
        assert!(elements.len() > 3, "{mesh}: {} elements", elements.len());
        // Leaves (every element but the hierarchy's interior nodes) tile the scene.
        let leaves: Vec<_> = elements.iter().filter(|e| e["children"].is_null()).collect();
        let area: f64 = leaves.iter().map(|e| f(&e["area"])).sum();
        assert!((area - total_area).abs() < 1e-6, "{mesh}: leaves cover {area}, scene {total_area}");
        let mut sloped = 0;
        for e in elements {
            let c = e["coefficients"].as_array().unwrap();
            let n = e["vertices"].as_array().unwrap().len();
            assert!((3..=4).contains(&n), "{mesh}: {n} vertices");
            if e["slope"].is_null() {
                assert_eq!(c.len(), 1, "{mesh}: a constant element has one coefficient");
                assert_eq!(c[0], e["radiosity"], "{mesh}: the constant is the element's radiosity");
                continue;
            }
            // A leaf with a slope: its linear function's values at its vertices, whose mean is
            // its average (the value at the centroid of a triangle or parallelogram) unless a
            // corner was clamped at 0.
            sloped += 1;
            assert_eq!(c.len(), n, "{mesh}: one coefficient per vertex");
            for k in 0..3 {
                let values: Vec<f64> = c.iter().map(|v| f(&v[k])).collect();
                if values.iter().all(|&v| v > 0.0) {
                    let mean = values.iter().sum::<f64>() / n as f64;
                    let b = f(&e["radiosity"][k]);
                    assert!((mean - b).abs() <= 1e-9 * b.abs().max(1e-12), "{mesh}: mean {mean} against {b}");
                }
            }
        }
        assert_eq!(sloped > 0, sloped_mesh, "{mesh}: {sloped} elements with a slope");
        // The hierarchy's interior elements hold the area average of their children (push-pull).
        let interior: Vec<_> = elements.iter().filter(|e| !e["children"].is_null()).collect();
        assert_eq!(interior.is_empty(), mesh != "quadtree", "{mesh}: {} interior elements", interior.len());
        for e in interior {
            assert_eq!(e["id"], elements[e["id"].as_u64().unwrap() as usize]["id"], "ids are positions");
            let kids: Vec<&serde_json::Value> = e["children"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| &elements[c.as_u64().unwrap() as usize])
                .collect();
            let area: f64 = kids.iter().map(|k| f(&k["area"])).sum();
            let mean = kids.iter().map(|k| f(&k["area"]) * f(&k["radiosity"][1])).sum::<f64>() / area;
            let b = f(&e["radiosity"][1]);
            assert!(
                (mean - b).abs() <= 1e-9 * b.abs().max(1e-12),
                "{mesh}: element {}: {b} vs children {mean}",
                e["id"]
            );
        }
        let links = dump["links"].as_array().unwrap();
        assert_eq!(links.is_empty(), mesh != "quadtree", "{mesh}: links are the hierarchy's");
        if mesh.starts_with("discontinuity") {
            let m = &doc["meshing"];
            assert!(f(&m["meshing_s"]) >= 0.0 && f(&m["solve_s"]) > 0.0, "{m}");
            assert_eq!(m["stats"]["output_patches"].as_u64().unwrap() as usize, leaves.len());
        }
    }
}

#[test]
fn order_one_on_the_cdt_dumps_vertex_values_shared_when_continuous() {
    // Per vertex position (rounded), the spread of the coefficient values there.
    let spread = |dump: &serde_json::Value| {
        let mut at: HashMap<[i64; 3], (f64, f64)> = HashMap::new();
        for e in dump["elements"].as_array().unwrap() {
            let (vs, cs) = (e["vertices"].as_array().unwrap(), e["coefficients"].as_array().unwrap());
            assert_eq!(vs.len(), cs.len(), "one coefficient per vertex at p = 1");
            // A linear triangle's (a bilinear parallelogram's) average is its vertex values' mean.
            let mean: f64 = cs.iter().map(|c| f(&c[1])).sum::<f64>() / cs.len() as f64;
            let b = f(&e["radiosity"][1]);
            assert!((mean - b).abs() <= 1e-9 * b.abs().max(1e-9), "average {b} against vertex mean {mean}");
            for (v, c) in vs.iter().zip(cs) {
                let key = [0, 1, 2].map(|k| (f(&v[k]) * 1e7).round() as i64);
                let s = at.entry(key).or_insert((f64::INFINITY, f64::NEG_INFINITY));
                *s = (s.0.min(f(&c[1])), s.1.max(f(&c[1])));
            }
        }
        at.values().map(|(lo, hi)| hi - lo).fold(0.0, f64::max)
    };
    let (doc, cont) = solve_and_dump(&["--mesh", "discontinuity-cdt", "--order", "1", "--continuous"], "p1c");
    assert_eq!(doc["order"], 1);
    assert_eq!(cont["basis"], "p1-continuous");
    assert!(spread(&cont) < 1e-12, "continuous: one value per vertex, spread {}", spread(&cont));
    let (_, disc) = solve_and_dump(&["--mesh", "discontinuity-cdt", "--order", "1"], "p1d");
    assert_eq!(disc["basis"], "p1-discontinuous");
    assert!(spread(&disc) > 1e-4, "discontinuous: vertex values differ between elements");
}

#[test]
fn nonsense_combinations_are_refused_with_one_line() {
    for (flags, needle) in [
        (&["--mesh", "quadtree", "--order", "1"][..], "--order 1"),
        (&["--mesh", "discontinuity-bsp", "--method", "progressive"][..], "--mesh discontinuity-bsp"),
        (&["--mesh", "discontinuity-cdt", "--method", "hierarchical", "--order", "1"][..], "--order 1"),
        (&["--mesh", "discontinuity-cdt", "--method", "hierarchical", "--ff-tol", "1e-4"][..], "--ff-tol"),
        (&["--mesh", "quadtree", "--dmesh-budget", "100"][..], "--dmesh-budget"),
        (&["--mesh", "uniform", "--dmesh-budget", "100"][..], "--dmesh-budget"),
        (
            &["--mesh", "discontinuity-cdt", "--dmesh-budget", "100", "--order", "1", "--continuous"][..],
            "--dmesh-budget",
        ),
        (&["--mesh", "discontinuity-cdt", "--dmesh-budget", "0"][..], "budget"),
        (&["--mesh", "discontinuity-cdt", "--dmesh-smooth", "2"][..], "--dmesh-smooth"),
        (
            &[
                "--mesh",
                "discontinuity-cdt",
                "--method",
                "hierarchical",
                "--dmesh-budget",
                "off",
                "--dmesh-smooth",
                "2",
            ][..],
            "--dmesh-smooth",
        ),
        (&["--mesh", "uniform", "--method", "hierarchical"][..], "--mesh uniform"),
        (&["--mesh", "quadtree", "--method", "progressive"][..], "--mesh quadtree"),
        (&["--mesh", "discontinuity-cdt", "--element-size", "0.1"][..], "--element-size"),
        (&["--mesh", "discontinuity-bsp", "--dmesh-min-angle", "10"][..], "--dmesh-min-angle"),
        (&["--mesh", "discontinuity-cdt", "--dmesh-min-angle", "80"][..], "min-angle"),
        (&["--mesh", "uniform", "--continuous"][..], "--continuous"),
        (&["--mesh", "discontinuity-cdt", "--order", "2"][..], "--order 2"),
        (&["--method", "progressive", "--order", "1"][..], "--order 1"),
        (&["--mesh", "discontinuity-cdt", "--order", "1", "--ff-tol", "1e-4"][..], "--ff-tol"),
    ] {
        let mut args = vec!["solve", "builtin:shadow-narrow", "-q"];
        args.extend(flags);
        let out = radlab(&args);
        assert!(!out.status.success(), "{flags:?} was accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle) && err.trim().lines().count() == 1, "{flags:?}: {err}");
    }
    // --method alone picks its mesh; without flags the default preset runs on its top level,
    // the contact mesh; the teaching presets on the quadtree.
    let out = radlab(&["solve", "builtin:parallel", "--method", "uniform", "--json", "-"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((doc["method"].as_str(), doc["mesh"].as_str()), (Some("uniform"), Some("uniform")));
    let out = radlab(&["solve", "builtin:parallel", "--json", "-"]);
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (doc["method"].as_str(), doc["mesh"].as_str()),
        (Some("hierarchical on contact mesh"), Some("contact"))
    );
    assert_eq!(doc["params"]["solve"]["oracle"], "error", "{}", doc["params"]);
    assert_eq!(doc["params"]["solve"]["bf_eps"], 0.05, "{}", doc["params"]);
    for preset in ["bf", "lecture", "splash2"] {
        let out = radlab(&["solve", "builtin:parallel", "--preset", preset, "--json", "-"]);
        let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!((doc["method"].as_str(), doc["mesh"].as_str()), (Some("hierarchical"), Some("quadtree")));
    }
    // One threshold whatever the oracle: --threshold sets the error oracle's ε (its area floor
    // following), the BF oracle's BFeps, Feps.
    for (flags, key, value) in [
        (&["--threshold", "0.2"][..], "bf_eps", 0.2),
        (&["--preset", "bf", "--threshold", "1e-3"][..], "bf_eps", 1e-3),
        (&["--preset", "lecture", "--threshold", "0.05"][..], "feps", 0.05),
    ] {
        let mut args = vec!["solve", "builtin:parallel", "--json", "-"];
        args.extend(flags);
        let out = radlab(&args);
        assert!(out.status.success(), "{flags:?}: {}", String::from_utf8_lossy(&out.stderr));
        let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let params =
            if doc["params"]["solve"].is_object() { &doc["params"]["solve"] } else { &doc["params"] };
        assert_eq!(params[key].as_f64(), Some(value), "{flags:?}: {params}");
    }
    let out = radlab(&["solve", "builtin:parallel", "--preset", "ultra"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("draft, interactive, quality, fine, reference"), "{err}");
}

/// `--dmesh-budget N` grades the discontinuity mesh to exactly N patches (every patch included:
/// the lamp and the occluder too), and the JSON reports what grading did.
#[test]
fn a_graded_discontinuity_mesh_has_the_budgeted_element_count() {
    for mesh in ["discontinuity-cdt", "discontinuity-bsp"] {
        let (doc, dump) =
            solve_and_dump(&["--mesh", mesh, "--dmesh-budget", "150"], &format!("{mesh}-graded"));
        assert_eq!(dump["elements"].as_array().unwrap().len(), 150, "{mesh}");
        let graded = &doc["meshing"]["stats"]["graded"];
        assert_eq!(graded["budget"], 150, "{mesh}: {graded}");
        assert_eq!(graded["patches_after"], 150, "{mesh}: {graded}");
        assert!(graded["splits"].as_u64().unwrap() > 0, "{mesh}: {graded}");
    }
}

/// `--mesh discontinuity-* --method hierarchical`: the pieces are the hierarchical solver's top
/// level; its leaves (more than the pieces) are dumped on the input patches.
#[test]
fn the_discontinuity_mesh_as_the_top_level_of_hierarchical_refinement() {
    let (plain, _) = solve_and_dump(&["--mesh", "discontinuity-bsp"], "bsp-flat");
    let pieces = plain["stats"]["elements"].as_u64().unwrap();
    let (doc, dump) =
        solve_and_dump(&["--mesh", "discontinuity-bsp", "--method", "hierarchical"], "bsp-hierarchical");
    assert_eq!(doc["method"], "hierarchical on discontinuity-bsp");
    assert_eq!(doc["mesh"], "discontinuity-bsp");
    assert!(doc["meshing"]["meshing_s"].as_f64().is_some(), "{}", doc["meshing"]);
    let elements = dump["elements"].as_array().unwrap();
    assert!(elements.len() as u64 > pieces, "{} leaves on {pieces} pieces", elements.len());
    // Pulled back: every element names an input patch of shadow-narrow (3 patches).
    assert!(elements.iter().all(|e| e["patch"].as_u64().unwrap() < 3));
    // Without --dmesh-budget the top level is graded to the automatic budget, the same on every
    // run; `--dmesh-budget off` keeps the ungraded pieces.
    let graded = &doc["meshing"]["stats"]["graded"];
    assert_eq!(graded["auto"], true, "{graded}");
    assert_eq!(graded["patches_after"], graded["budget"], "{graded}");
    assert!(graded["budget"].as_u64().unwrap() > graded["patches_before"].as_u64().unwrap(), "{graded}");
    let (again, _) = solve_and_dump(
        &["--mesh", "discontinuity-bsp", "--method", "hierarchical"],
        "bsp-hierarchical-again",
    );
    assert_eq!(again["meshing"]["stats"]["graded"]["budget"], graded["budget"]);
    let (off, _) = solve_and_dump(
        &["--mesh", "discontinuity-bsp", "--method", "hierarchical", "--dmesh-budget", "off"],
        "bsp-hierarchical-off",
    );
    assert!(off["meshing"]["stats"]["graded"].is_null(), "{}", off["meshing"]);
    // The hierarchical solver clusters large top levels: its cap is 100 000 pieces, the uniform
    // solver's 10 000 (splash_room's D-mesh has 46 845).
    assert_eq!(doc["params"]["mesh"]["max_patches"], 100_000, "{}", doc["params"]);
    assert_eq!(plain["params"]["mesh"]["max_patches"], 10_000, "{}", plain["params"]);
    assert_eq!(off["meshing"]["stats"]["output_patches"].as_u64(), Some(pieces));
}

/// `--dmesh-gather false` keeps the p = 0 solve's plain constants on a discontinuity mesh: the
/// receiver's radiosity then differs from the default's, which re-gathers the partly shadowed
/// pieces' direct light with more rays (`solver::discontinuity::gather`).
#[test]
fn dmesh_gather_can_be_turned_off() {
    let (on, _) = solve_and_dump(&["--mesh", "discontinuity-cdt"], "gather-on");
    let (off, _) = solve_and_dump(&["--mesh", "discontinuity-cdt", "--dmesh-gather", "false"], "gather-off");
    let receiver = |doc: &serde_json::Value| doc["patches"][0]["radiosity"].clone();
    assert_eq!(on["patches"].as_array().unwrap().len(), off["patches"].as_array().unwrap().len());
    assert_ne!(receiver(&on), receiver(&off), "the gather changed nothing on shadow-narrow's receiver");
    let out = radlab(&[
        "solve",
        "builtin:shadow-narrow",
        "-q",
        "--mesh",
        "discontinuity-cdt",
        "--dmesh-gather",
        "maybe",
    ]);
    assert!(!out.status.success());
}
