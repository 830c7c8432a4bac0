//! `radlab solve`'s budgets: a time budget stops the hierarchical solver's refinement, gathers
//! to convergence on the mesh reached by the budget's end and says so (and says so when the
//! gathers stop before converging); absurd budgets and solvers that cannot be stopped are
//! one-line errors.

use std::process::Command;

fn radlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_radlab")).args(args).output().unwrap()
}

/// `radlab solve builtin:cornell --preset reference --time-budget SECONDS`, which succeeds: its
/// stderr and JSON document (written to `name` in the tests' scratch folder).
fn cornell_reference_within(seconds: &str, name: &str) -> (String, serde_json::Value) {
    let json = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let out = radlab(&[
        "solve",
        "builtin:cornell",
        "--preset",
        "reference",
        "--time-budget",
        seconds,
        "--json",
        json.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let doc = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (stderr, doc)
}

#[test]
fn a_time_budget_stops_the_solve_and_says_so() {
    // The finest ladder step on cornell takes tens of seconds; a fifth of a second stops it.
    let (stderr, doc) = cornell_reference_within("0.2", "time-budget.json");
    assert!(stderr.contains("time budget of 0.2 s"), "{stderr}");
    assert_eq!(doc["cancelled"], true, "{doc}");
    assert!(doc["notes"].as_array().is_some_and(|n| n.len() == 1), "{}", doc["notes"]);
    // The answer is the converged solution on the mesh reached: its power balance closes.
    assert!(doc["patches"].as_array().is_some_and(|p| !p.is_empty()));
    let residual = doc["energy"]["relative_residual"].as_f64().expect("a residual");
    assert!(residual < 1e-3, "the balance closes on the mesh reached: residual {residual}");

    // Without the budget a quick solve is not cancelled and has no note.
    let json = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("no-time-budget.json");
    let out = radlab(&["solve", "builtin:cornell", "--preset", "draft", "--json", json.to_str().unwrap()]);
    assert!(out.status.success());
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["cancelled"], false);
    assert_eq!(doc["notes"], serde_json::json!([]));
}

#[test]
fn the_gathers_stop_at_the_end_of_the_budget_and_say_so() {
    // Linking cornell's patches alone takes longer than a millisecond: the budget has ended
    // before the first refinement pass, and the solve gathers once, not to convergence.
    let (stderr, doc) = cornell_reference_within("0.001", "time-budget-gathers.json");
    assert!(stderr.contains("gathers stopped at its end before converging (residual"), "{stderr}");
    assert_eq!(doc["cancelled"], true, "{doc}");
    let notes = doc["notes"].as_array().expect("notes");
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].as_str().is_some_and(|n| n.contains("unconverged")), "{notes:?}");
    assert_eq!(doc["stats"]["iterations"], 1, "one gather, not the converging ones: {}", doc["stats"]);
}

#[test]
fn absurd_budgets_and_unstoppable_solvers_are_one_line_errors() {
    for (args, says) in [
        (&["--time-budget", "0"][..], "--time-budget 0"),
        (&["--time-budget=-3"][..], "--time-budget -3"),
        (&["--time-budget", "NaN"][..], "--time-budget NaN"),
        (&["--time-budget", "1e12"][..], "--time-budget 1000000000000"),
        (&["--time-budget", "5", "--mesh", "uniform"][..], "hierarchical solver only"),
    ] {
        let out = radlab(&[&["solve", "builtin:shadow-narrow"][..], args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
}
