//! The baked glTF (`radlab::bake`, `radlab solve --bake`): read back with the `gltf` crate and
//! checked value by value against the solution; the CLI's refusals; and the Khronos glTF
//! validator on the bake of every built-in scene (0 errors, 0 warnings), where Node and the
//! validator are installed (`RADLAB_GLTF_VALIDATOR`, see `validator_dir`).

use radlab::accel::Accel;
use radlab::bake::{self, BakeFormat, BakeOptions};
use radlab::image::{Camera, auto_exposure};
use radlab::scene::{Scene, builtin};
use radlab::solver::Solution;
use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::params::HierarchicalParams;
use radlab::solver::uniform::{self, UniformParams};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

/// Hierarchical solution at the interactive preset (the cheapest the CLI offers), with the
/// `--png` exposure of the default camera at 640×480, as `radlab solve --bake` picks it.
fn solve(name: &str) -> (Scene, Solution, f64) {
    let scene = builtin::load(name).unwrap();
    let arc = Arc::new(scene.clone());
    let mut solver = HierarchicalSolver::new(Arc::clone(&arc), HierarchicalParams::interactive()).unwrap();
    solver.solve(&mut |_, _| {});
    let solution = solver.solution();
    let accel = Accel::build(&scene);
    let exposure = auto_exposure(&scene, &accel, &solution.elements, &Camera::for_scene(&scene), 640, 480);
    (scene, solution, exposure)
}

fn options(label: &str, exposure: f64) -> BakeOptions {
    BakeOptions {
        exposure,
        exposure_rule: "test".into(),
        scene_label: label.into(),
        params: Some(serde_json::json!({"preset": "interactive"})),
    }
}

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("radlab-bake-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A tightly packed VEC3 f32 accessor's values, read from the GLB's binary chunk.
fn read_vec3(acc: &gltf::Accessor, bin: &[u8]) -> Vec<[f32; 3]> {
    assert_eq!(acc.data_type(), gltf::accessor::DataType::F32);
    assert_eq!(acc.dimensions(), gltf::accessor::Dimensions::Vec3);
    let view = acc.view().unwrap();
    assert_eq!(view.buffer().index(), 0);
    let stride = view.stride().unwrap_or(12);
    let start = view.offset() + acc.offset();
    (0..acc.count())
        .map(|i| {
            let at = start + i * stride;
            std::array::from_fn(|c| f32::from_le_bytes(bin[at + 4 * c..at + 4 * c + 4].try_into().unwrap()))
        })
        .collect()
}

fn read_u32(acc: &gltf::Accessor, bin: &[u8]) -> Vec<u32> {
    assert_eq!(acc.data_type(), gltf::accessor::DataType::U32);
    let view = acc.view().unwrap();
    let start = view.offset() + acc.offset();
    (0..acc.count())
        .map(|i| u32::from_le_bytes(bin[start + 4 * i..start + 4 * i + 4].try_into().unwrap()))
        .collect()
}

/// The JSON and binary chunks of a GLB.
fn chunks(bytes: &[u8]) -> (Value, Vec<u8>) {
    let glb = gltf::binary::Glb::from_slice(bytes).unwrap();
    (serde_json::from_slice(&glb.json).unwrap(), glb.bin.unwrap().into_owned())
}

#[test]
fn glb_reads_back_with_every_element_its_colour_and_the_extras() {
    let (scene, sol, exposure) = solve("cornell");
    let bytes = bake::glb(&scene, &sol, &options("builtin:cornell", exposure)).unwrap();
    let gltf = gltf::Gltf::from_slice(&bytes).expect("the gltf crate parses and validates the bake");
    let bin = gltf.blob.as_deref().unwrap();
    let (json, _) = chunks(&bytes);

    assert!(gltf.extensions_used().any(|e| e == "KHR_materials_unlit"));
    assert_eq!(gltf.materials().count(), 1);
    assert_eq!(json["materials"][0]["extensions"]["KHR_materials_unlit"], serde_json::json!({}));
    assert!(!gltf.materials().next().unwrap().double_sided(), "radlab's patches are one-sided");

    let info = &json["asset"]["extras"]["radlab"];
    assert_eq!(info["exposure"].as_f64(), Some(exposure));
    assert_eq!(info["units"].as_str(), Some(bake::UNITS));
    assert_eq!(info["scene"].as_str(), Some("builtin:cornell"));
    assert_eq!(info["method"].as_str(), Some(sol.method.as_str()));
    assert_eq!(info["elements"].as_u64(), Some(sol.elements.len() as u64));
    assert_eq!(&json["scenes"][0]["extras"]["radlab"], info);
    let clipped = info["clipped_elements"].as_u64().unwrap() as usize;
    // The --png exposure maps the 99th percentile of luminance to 1: the lamp, and the red
    // channel of surfaces lit by the warm lamp, go above 1 and are clipped (the PNG clips them too).
    assert!(clipped > 0, "the light is brighter than the 99th percentile: clipped to 1");
    assert!(clipped < sol.elements.len() / 2, "{clipped} of {} elements clipped", sol.elements.len());

    // One node and mesh per input mesh name, each with that mesh's elements in solution order.
    let mut vertices = 0;
    let mut triangles = 0;
    let mut checked = 0;
    for node in gltf.nodes() {
        let mesh = node.mesh().unwrap();
        let name = mesh.name().unwrap();
        assert_eq!(node.name(), Some(name));
        let elements: Vec<_> = sol.elements.iter().filter(|e| scene.patches[e.patch].mesh == name).collect();
        assert!(!elements.is_empty(), "mesh {name} has no elements");
        let prim = mesh.primitives().next().unwrap();
        assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
        let get = |s: gltf::Semantic| read_vec3(&prim.get(&s).unwrap(), bin);
        let positions = get(gltf::Semantic::Positions);
        let normals = get(gltf::Semantic::Normals);
        let colors = get(gltf::Semantic::Colors(0));
        let radiosity = get(gltf::Semantic::Extras("RADIOSITY".into()));
        let indices = read_u32(&prim.indices().unwrap(), bin);
        let mut v = 0;
        for e in &elements {
            let patch = &scene.patches[e.patch];
            let color = e.radiosity.0.map(|c| (c * exposure).clamp(0.0, 1.0) as f32);
            for p in &e.vertices {
                assert_eq!(positions[v], p.to_array().map(|c| c as f32));
                assert_eq!(colors[v], color, "COLOR_0 of an element of {name}");
                assert_eq!(radiosity[v], e.radiosity.0.map(|c| c as f32));
                let n = normals[v];
                assert!((n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0).abs() < 1e-6);
                assert!(patch.normal.dot(radlab::math::DVec3::from_array(n.map(f64::from))) > 1.0 - 1e-6);
                v += 1;
            }
            checked += 1;
        }
        assert_eq!(v, positions.len());
        assert_eq!(indices.len() % 3, 0);
        assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
        vertices += positions.len();
        triangles += indices.len() / 3;
    }
    assert_eq!(checked, sol.elements.len(), "every element is in exactly one mesh");
    assert_eq!(vertices, sol.elements.iter().map(|e| e.vertices.len()).sum::<usize>());
    assert_eq!(triangles, sol.elements.iter().map(|e| e.vertices.len() - 2).sum::<usize>());
    // Some colours lie strictly inside (0, 1): the exposure shows the walls, not just the lamp.
    assert!(sol.elements.iter().any(|e| {
        let l = e.radiosity.luminance() * exposure;
        l > 0.05 && l < 0.95
    }));
}

#[test]
fn gltf_and_glb_hold_the_same_document_and_buffer() {
    let scene = builtin::load("table-room").unwrap();
    let accel = Accel::build(&scene);
    let p = UniformParams {
        element_size: scene.bounds().diagonal() / 6.0,
        ff_tolerance: 1e-4,
        ..UniformParams::default()
    };
    let sol = uniform::solve(&scene, &accel, &p, &mut |_, _| {}).unwrap();
    let opts = options("builtin:table-room", 0.37);
    let (glb_json, glb_bin) = chunks(&bake::glb(&scene, &sol, &opts).unwrap());
    let text = bake::gltf(&scene, &sol, &opts).unwrap();
    assert_eq!(bake::bake(&scene, &sol, &opts, BakeFormat::Gltf).unwrap(), text.as_bytes());
    let mut json: Value = serde_json::from_str(&text).unwrap();
    let uri = json["buffers"][0]["uri"].take();
    json["buffers"][0].as_object_mut().unwrap().remove("uri");
    assert_eq!(json, glb_json);
    let b64 = uri.as_str().unwrap().strip_prefix("data:application/octet-stream;base64,").unwrap();
    use base64::Engine as _;
    assert_eq!(base64::engine::general_purpose::STANDARD.decode(b64).unwrap(), glb_bin);
    assert_eq!(json["asset"]["extras"]["radlab"]["method"].as_str(), Some("uniform"));
}

fn radlab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_radlab")).args(args).output().unwrap()
}

/// A failed run: non-zero exit, one line on stderr containing `needle`.
fn fails_with(args: &[&str], needle: &str) {
    let out = radlab(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
    assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
}

#[test]
fn cli_bakes_and_refuses_bad_paths_with_one_line() {
    let dir = temp_dir("cli");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let glb = dir.join("cornell.glb");
    let out = radlab(&["solve", "builtin:cornell", "--preset", "interactive", "--bake", &s(&glb)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("baked "));
    let gltf = gltf::Gltf::from_slice(&std::fs::read(&glb).unwrap()).unwrap();
    assert!(gltf.meshes().count() > 0);
    let (json, _) = chunks(&std::fs::read(&glb).unwrap());
    let rule = json["asset"]["extras"]["radlab"]["exposure_rule"].as_str().unwrap();
    assert!(rule.starts_with("auto"), "{rule}");
    assert!(json["asset"]["extras"]["radlab"]["params"].is_object(), "the solver's parameters");

    // The exposure flag, and a .gltf through the CLI.
    let text = dir.join("cornell.GLTF");
    let out = radlab(&[
        "solve",
        "builtin:cornell",
        "--method",
        "uniform",
        "--ff-tol",
        "1e-4",
        "--bake",
        &s(&text),
        "--bake-exposure",
        "0.5",
        "-q",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: Value = serde_json::from_slice(&std::fs::read(&text).unwrap()).unwrap();
    assert_eq!(json["asset"]["extras"]["radlab"]["exposure"].as_f64(), Some(0.5));
    assert_eq!(json["asset"]["extras"]["radlab"]["exposure_rule"].as_str(), Some("--bake-exposure"));

    fn solve(bake: &str) -> Vec<&str> {
        vec!["solve", "builtin:furnace", "--preset", "interactive", "--bake", bake]
    }
    let png = s(&dir.join("out.png"));
    fails_with(&solve(&png), ".glb or .gltf");
    assert!(!dir.join("out.png").exists());
    fails_with(&solve(&s(&dir.join("no/such/folder/x.glb"))), "does not exist");
    std::fs::create_dir(dir.join("taken.glb")).unwrap();
    fails_with(&solve(&s(&dir.join("taken.glb"))), "writing");
    let glb_path = s(&glb);
    let mut zero = solve(&glb_path);
    zero.extend(["--bake-exposure", "0"]);
    fails_with(&zero, "--bake-exposure");
    let no_bake = radlab(&["solve", "builtin:furnace", "--bake-exposure", "1"]);
    assert!(!no_bake.status.success(), "--bake-exposure needs --bake");

    // Never the input scene: not by its own path, not through a symbolic link to it.
    let scene = dir.join("scene.gltf");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/furnace.gltf"), &scene).unwrap();
    let before = std::fs::read(&scene).unwrap();
    let base = ["solve", "--preset", "interactive", "--bake"];
    let refuse = |input: &Path, out: &Path| {
        let mut args: Vec<String> = base.iter().map(|a| (*a).to_string()).collect();
        args.extend([s(out), s(input)]);
        fails_with(&args.iter().map(String::as_str).collect::<Vec<_>>(), "input scene");
    };
    refuse(&scene, &scene);
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&scene, dir.join("link.gltf")).unwrap();
        refuse(&scene, &dir.join("link.gltf"));
        std::fs::hard_link(&scene, dir.join("hard.gltf")).unwrap();
        refuse(&dir.join("hard.gltf"), &scene);
    }
    assert_eq!(std::fs::read(&scene).unwrap(), before, "the input scene was written");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The installed `gltf-validator` npm package (the folder holding its `package.json`), from
/// `RADLAB_GLTF_VALIDATOR` (that folder, or an `npm install --prefix` folder holding
/// `node_modules/gltf-validator`). `.ci/run` installs it and sets the variable; a set variable
/// that does not lead to the package, or no `node`, fails the test instead of skipping it.
fn validator_dir() -> Option<PathBuf> {
    let Some(var) = std::env::var_os("RADLAB_GLTF_VALIDATOR") else {
        eprintln!(
            "SKIPPED: RADLAB_GLTF_VALIDATOR is not set (npm install --prefix DIR gltf-validator; \
             RADLAB_GLTF_VALIDATOR=DIR); the Khronos validator did not run"
        );
        return None;
    };
    let root = PathBuf::from(var);
    // An `npm install --prefix` folder has a package.json of its own: look inside it first.
    let dir = [root.join("node_modules/gltf-validator"), root.clone()]
        .into_iter()
        .find(|d| d.join("package.json").is_file())
        .unwrap_or_else(|| {
            panic!("RADLAB_GLTF_VALIDATOR={}: no gltf-validator package there", root.display())
        });
    let node = Command::new("node").arg("--version").output();
    assert!(node.is_ok_and(|o| o.status.success()), "RADLAB_GLTF_VALIDATOR is set but `node` does not run");
    Some(dir)
}

/// Runs the validator on every file; for each, (errors, warnings, infos, messages).
fn validate(validator: &Path, files: &[PathBuf]) -> Vec<(u64, u64, u64, String)> {
    const SCRIPT: &str = r"
        const fs = require('fs');
        const v = require(process.argv[1]);
        (async () => {
          for (const f of process.argv.slice(2)) {
            const r = await v.validateBytes(new Uint8Array(fs.readFileSync(f)), { maxIssues: 0 });
            const msgs = r.issues.messages.map(m => `${m.code} ${m.pointer || ''} ${m.message}`).join('; ');
            console.log(JSON.stringify([r.issues.numErrors, r.issues.numWarnings, r.issues.numInfos, msgs]));
          }
        })().catch(e => { console.error(String(e)); process.exit(1); });";
    let out =
        Command::new("node").arg("-e").arg(SCRIPT).arg(validator).args(files).output().expect("running node");
    assert!(out.status.success(), "validator failed: {}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<_> = String::from_utf8(out.stdout).unwrap().lines().map(String::from).collect();
    assert_eq!(lines.len(), files.len());
    lines.iter().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn khronos_validator_reports_nothing_on_the_bake_of_every_builtin_scene() {
    let Some(validator) = validator_dir() else { return };
    let dir = temp_dir("validator");
    let mut files = Vec::new();
    for (name, _) in builtin::BUILTINS {
        let (scene, sol, exposure) = solve(name);
        let label = format!("builtin:{name}");
        let glb = dir.join(format!("{name}.glb"));
        std::fs::write(&glb, bake::glb(&scene, &sol, &options(&label, exposure)).unwrap()).unwrap();
        files.push(glb);
        if *name == "cornell" {
            let text = dir.join(format!("{name}.gltf"));
            std::fs::write(&text, bake::gltf(&scene, &sol, &options(&label, exposure)).unwrap()).unwrap();
            files.push(text);
        }
    }
    // A control: the validator, as called here, does report a broken file (POSITION's max off).
    let mut broken: Value =
        serde_json::from_slice(&std::fs::read(dir.join("cornell.gltf")).unwrap()).unwrap();
    broken["accessors"][0]["max"][0] = Value::from(1e9);
    let broken_file = dir.join("broken.gltf");
    std::fs::write(&broken_file, serde_json::to_vec(&broken).unwrap()).unwrap();
    let control = validate(&validator, std::slice::from_ref(&broken_file));
    assert!(control[0].0 > 0, "the validator found nothing wrong with a broken file: {:?}", control[0]);

    let reports = validate(&validator, &files);
    let mut bad = Vec::new();
    for (file, (errors, warnings, infos, msgs)) in files.iter().zip(&reports) {
        let name = file.file_name().unwrap().to_string_lossy();
        eprintln!("gltf-validator {name}: {errors} errors, {warnings} warnings, {infos} infos");
        if *errors > 0 || *warnings > 0 {
            bad.push(format!("{name}: {msgs}"));
        }
    }
    assert!(bad.is_empty(), "validator issues:\n{}", bad.join("\n"));
    let _ = std::fs::remove_dir_all(&dir);
}
