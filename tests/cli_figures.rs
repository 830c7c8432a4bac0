//! `radlab figures`: the list, its JSON, and the one-line error for a figure that does not exist.

use std::process::Command;

fn radlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_radlab")).args(args).output().unwrap()
}

#[test]
fn figures_json_lists_every_figure_with_its_scene_settings_and_caption() {
    let out = radlab(&["figures", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let figs = v.as_array().expect("an array");
    assert_eq!(figs.len(), radlab::present::figures::FIGURES.len());
    assert!(figs.len() >= 10);
    for (f, want) in figs.iter().zip(radlab::present::figures::FIGURES) {
        assert_eq!(f["name"], want.name);
        assert_eq!(f["slide"], want.slide);
        assert_eq!(f["scene"], want.scene);
        // The caption is a template: every name in braces is listed and is one the viewer fills.
        let template = f["caption_template"].as_str().expect("the caption template");
        assert!(template.len() > 80, "{f}");
        assert!(f.get("caption").is_none(), "no unfilled caption posing as text: {f}");
        let fills: Vec<&str> =
            f["caption_fills"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
        assert_eq!(fills, radlab::present::figures::placeholders(template));
        for name in &fills {
            assert!(radlab::present::figures::PLACEHOLDERS.contains(name), "{} quotes {{{name}}}", want.name);
        }
        assert!(f["params"]["feps"].is_number(), "the solver settings are in the JSON: {f}");
        assert!(f["overlays"]["quadtree"].is_boolean());
    }
    // The table: one row per figure, name and slide title.
    let out = radlab(&["figures"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for f in radlab::present::figures::FIGURES {
        assert!(text.lines().any(|l| l.starts_with(f.name) && l.contains(f.slide)), "{}:\n{text}", f.name);
    }
}

#[test]
fn an_unknown_figure_is_one_line_listing_the_valid_names() {
    for args in [
        &["view", "--figure", "no-such-figure"][..],
        &["figures", "--screenshots", "/nonexistent-radlab-dir", "no-such-figure"][..],
    ] {
        let out = radlab(args);
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains("\"no-such-figure\""), "{err}");
        assert!(
            err.contains("adaptive-meshing") && err.contains("hsa91-room"),
            "lists the valid names: {err}"
        );
    }
}

/// `radlab view`'s mesh flags: what cannot be drawn is refused in one line before any window.
#[test]
fn view_mesh_flags_that_do_not_fit_are_one_line_errors() {
    for (args, says) in [
        (&["view", "builtin:cornell", "--order", "1"][..], "--mesh"),
        (&["view", "builtin:cornell", "--mesh", "uniform", "--continuous"][..], "order 1"),
        (&["view", "builtin:cornell", "--mesh", "discontinuity-bsp", "--order", "2"][..], "--order 2"),
        (&["view", "builtin:cornell", "--mesh", "voronoi"][..], "voronoi"),
        (
            &["view", "builtin:cornell", "--bench-thresholds", "0.1,0"][..],
            "--bench-thresholds: 0 is not a threshold",
        ),
        (&["view", "builtin:cornell", "--bench-thresholds", "NaN"][..], "--bench-thresholds: NaN"),
    ] {
        let out = radlab(args);
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        if says != "voronoi" {
            // (an unknown value is clap's message, with the valid ones listed)
            assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        }
    }
}
