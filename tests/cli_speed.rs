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
