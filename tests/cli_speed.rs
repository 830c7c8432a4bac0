//! `radlab speed`: the benchmark runs, writes its rows, and counts match across thread counts.

use std::process::Command;

#[test]
fn speed_benchmark_writes_rows_with_identical_counts_for_any_thread_count() {
    let dir = std::env::temp_dir().join(format!("radlab-speed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("speed.json");
    let out = Command::new(env!("CARGO_BIN_EXE_radlab"))
        .args(["speed", "builtin:cornell", "--preset", "bf", "--rays", "2,4", "--threads", "1,2"])
        .args(["--repeats", "2", "--seeds", "2", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| rays | threads |"), "no table:\n{stdout}");
    let rows: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 4);
    for pair in rows.chunks(2) {
        for key in ["elements", "links", "links_created", "rays_cast"] {
            assert_eq!(pair[0][key], pair[1][key], "{key} differs between 1 and 2 threads");
        }
        assert!(pair[0]["links"].as_u64().unwrap() > 100);
        assert!(pair[0]["total_s"].as_f64().unwrap() > 0.0);
        for row in pair {
            assert_eq!(row["seeds"], 2);
            let (lo, hi) = (row["links_min"].as_u64().unwrap(), row["links_max"].as_u64().unwrap());
            assert!(lo <= row["links"].as_u64().unwrap() && row["links"].as_u64().unwrap() <= hi);
        }
    }
    let bad = Command::new(env!("CARGO_BIN_EXE_radlab")).args(["speed", "--seeds", "0"]).output().unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--seeds"));
    let bad = Command::new(env!("CARGO_BIN_EXE_radlab")).args(["speed", "--repeats", "0"]).output().unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--repeats") && err.lines().count() == 1, "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A ladder preset is timed as `radlab solve` runs it: on the contact mesh, with the same
/// leaves, links and rays.
#[test]
fn speed_runs_a_ladder_preset_on_its_mesh_as_solve_does() {
    let dir = std::env::temp_dir().join(format!("radlab-speed-ladder-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (speed_json, solve_json) = (dir.join("speed.json"), dir.join("solve.json"));
    let run = |args: &[&str], json: &std::path::Path| {
        let out =
            Command::new(env!("CARGO_BIN_EXE_radlab")).args(args).arg("--json").arg(json).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(json).unwrap()).unwrap()
    };
    let speed = run(
        &["speed", "builtin:cornell", "--preset", "draft", "--rays", "4", "--threads", "1", "--repeats", "1"],
        &speed_json,
    );
    let solve = run(
        &["solve", "builtin:cornell", "--preset", "draft", "--rays", "4", "--threads", "1", "-q"],
        &solve_json,
    );
    assert!(solve["method"].as_str().unwrap().contains("contact mesh"), "{}", solve["method"]);
    for (key, in_solve) in [("leaves", "leaves"), ("links", "links"), ("rays_cast", "rays")] {
        assert_eq!(speed[0][key], solve["stats"][in_solve], "{key}: speed against solve");
    }
    std::fs::remove_dir_all(&dir).ok();
}
