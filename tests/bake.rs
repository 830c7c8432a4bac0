//! The baked glTF (`radlab::present::bake`, `radlab solve --bake`): read back with the `gltf` crate and
//! checked value by value against the solution; the CLI's refusals; and the Khronos glTF
//! validator on the bake of every built-in scene (0 errors, 0 warnings), wherever Node and the
//! validator are installed (see `validator_dir`).

use radlab::eval::pointwise::{PiecewiseConstant, Reconstruction};
use radlab::geometry::accel::Accel;
use radlab::present::bake::{self, BakeForm, BakeFormat, BakeOptions, LightmapParams};
use radlab::present::image::{Camera, View};
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
    let camera = Camera::for_scene(&scene);
    let view =
        View { scene: &scene, accel: &accel, elements: &solution.elements, camera, width: 640, height: 480 };
    let exposure = view.auto_exposure();
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

    // The solve pushes slopes to its leaves: the vertex colours below vary across them.
    assert!(sol.elements.iter().any(|e| e.slope.is_some()), "no element has a slope");
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
            // Each vertex carries the element's own reconstruction there: its value with its slope.
            for p in &e.vertices {
                let b = e.radiosity_at(*p);
                assert_eq!(positions[v], p.to_array().map(|c| c as f32));
                assert_eq!(
                    colors[v],
                    b.0.map(|c| (c * exposure).clamp(0.0, 1.0) as f32),
                    "COLOR_0 of {name}"
                );
                assert_eq!(radiosity[v], b.0.map(|c| c as f32));
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

/// The installed `gltf-validator` npm package (the folder holding its `package.json`), or `None`
/// (with the reason printed) where the validator cannot run here.
///
/// With `RADLAB_GLTF_VALIDATOR` set (that folder, or an `npm install --prefix` folder holding
/// `node_modules/gltf-validator`; `.ci/run` installs it and sets the variable), a variable that
/// does not lead to the package, or no `node`, fails the test instead of skipping it. Without
/// it the test runs wherever `node` runs and the package is found: under a `gltf-validator`
/// folder in the cargo target folder or any folder above it (`.ci/run`'s
/// `npm install --prefix target/gltf-validator`), where Node's `require` finds it from the
/// repository, or in npm's global folder (`npm install -g`).
fn validator_dir() -> Option<PathBuf> {
    let node_runs = || Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    let package = |root: &Path| {
        [root.join("node_modules/gltf-validator"), root.to_path_buf()].into_iter().find(|d| {
            std::fs::read_to_string(d.join("package.json"))
                .ok()
                .and_then(|t| serde_json::from_str::<Value>(&t).ok())
                .is_some_and(|v| v["name"] == "gltf-validator")
        })
    };
    if let Some(var) = std::env::var_os("RADLAB_GLTF_VALIDATOR") {
        let root = PathBuf::from(var);
        let dir = package(&root).unwrap_or_else(|| {
            panic!("RADLAB_GLTF_VALIDATOR={}: no gltf-validator package there", root.display())
        });
        assert!(node_runs(), "RADLAB_GLTF_VALIDATOR is set but `node` does not run");
        return Some(dir);
    }
    if !node_runs() {
        eprintln!("SKIPPED: `node` does not run here; the Khronos validator did not run");
        return None;
    }
    let exe = std::env::current_exe().unwrap();
    let npm_global = Command::new("npm")
        .args(["root", "-g"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    let node_resolves = Command::new("node")
        .args(["-p", "require.resolve('gltf-validator/package.json')"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| {
            PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()).parent().map(Path::to_path_buf)
        });
    let found = exe
        .ancestors()
        .map(|a| a.join("gltf-validator"))
        .chain(node_resolves)
        .chain(npm_global)
        .find_map(|root| package(&root));
    if found.is_none() {
        eprintln!(
            "SKIPPED: `node` runs but no gltf-validator package was found (looked in a \
             gltf-validator folder above {}, with Node's require from the repository and in npm's \
             global folder; `npm install --prefix target/gltf-validator gltf-validator@2.0.0-dev.3.10` \
             or RADLAB_GLTF_VALIDATOR=DIR); the Khronos validator did not run",
            exe.display()
        );
    }
    found
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

type Baker = dyn Fn(&Scene, &Solution, &BakeOptions) -> Vec<u8>;

/// Every built-in scene solved as `solve` does and baked by `glb` into `dir`/NAME.glb, and
/// cornell also by `gltf` into cornell.gltf; the files, in that order.
fn bake_every_builtin(dir: &Path, glb: &Baker, gltf: &Baker) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for (name, _) in builtin::BUILTINS {
        let (scene, sol, exposure) = solve(name);
        let opts = options(&format!("builtin:{name}"), exposure);
        let path = dir.join(format!("{name}.glb"));
        std::fs::write(&path, glb(&scene, &sol, &opts)).unwrap();
        files.push(path);
        if *name == "cornell" {
            let text = dir.join(format!("{name}.gltf"));
            std::fs::write(&text, gltf(&scene, &sol, &opts)).unwrap();
            files.push(text);
        }
    }
    files
}

/// Runs the validator on `files` and asserts 0 errors and 0 warnings on each; each file's name
/// and messages (the infos), for further checks.
fn assert_valid(validator: &Path, files: &[PathBuf]) -> Vec<(String, String)> {
    let reports = validate(validator, files);
    let mut bad = Vec::new();
    let mut out = Vec::new();
    for (file, (errors, warnings, infos, msgs)) in files.iter().zip(reports) {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        eprintln!("gltf-validator {name}: {errors} errors, {warnings} warnings, {infos} infos");
        if errors > 0 || warnings > 0 {
            bad.push(format!("{name}: {msgs}"));
        }
        out.push((name, msgs));
    }
    assert!(bad.is_empty(), "validator issues:\n{}", bad.join("\n"));
    out
}

#[test]
fn khronos_validator_reports_nothing_on_the_bake_of_every_builtin_scene() {
    let Some(validator) = validator_dir() else { return };
    let dir = temp_dir("validator");
    let files = bake_every_builtin(
        &dir,
        &|scene, sol, opts| bake::glb(scene, sol, opts).unwrap(),
        &|scene, sol, opts| bake::gltf(scene, sol, opts).unwrap().into_bytes(),
    );
    // A control: the validator, as called here, does report a broken file (POSITION's max off).
    let mut broken: Value =
        serde_json::from_slice(&std::fs::read(dir.join("cornell.gltf")).unwrap()).unwrap();
    broken["accessors"][0]["max"][0] = Value::from(1e9);
    let broken_file = dir.join("broken.gltf");
    std::fs::write(&broken_file, serde_json::to_vec(&broken).unwrap()).unwrap();
    let control = validate(&validator, std::slice::from_ref(&broken_file));
    assert!(control[0].0 > 0, "the validator found nothing wrong with a broken file: {:?}", control[0]);

    assert_valid(&validator, &files);
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// The lightmap form (`bake::BakeForm::Lightmap`, `radlab solve --bake-lightmap SIZE`).

fn lightmap_bake(scene: &Scene, sol: &Solution, label: &str, exposure: f64, size: u32) -> Vec<u8> {
    let form = BakeForm::Lightmap(LightmapParams::new(size));
    bake::glb_as(scene, sol, &options(label, exposure), form).unwrap()
}

/// A tightly packed VEC2 f32 accessor's values.
fn read_vec2(acc: &gltf::Accessor, bin: &[u8]) -> Vec<[f32; 2]> {
    assert_eq!(acc.data_type(), gltf::accessor::DataType::F32);
    assert_eq!(acc.dimensions(), gltf::accessor::Dimensions::Vec2);
    let view = acc.view().unwrap();
    let start = view.offset() + acc.offset();
    (0..acc.count())
        .map(|i| {
            let at = start + 8 * i;
            std::array::from_fn(|c| f32::from_le_bytes(bin[at + 4 * c..at + 4 * c + 4].try_into().unwrap()))
        })
        .collect()
}

/// An 8-bit RGB PNG's size and texels; it must be tagged sRGB.
fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    assert!(reader.info().srgb.is_some(), "the lightmap PNG carries an sRGB chunk");
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut buf).unwrap();
    assert_eq!((frame.color_type, frame.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
    buf.truncate(frame.buffer_size());
    (frame.width, frame.height, buf)
}

/// 8-bit sRGB of a linear value: what a lightmap texel holds for B · exposure.
fn srgb8(linear: f64) -> u8 {
    (radlab::present::image::srgb_encode(linear.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// One input patch as the lightmap form wrote it: its vertices' TEXCOORD_1.
struct BakedPatch {
    patch: usize,
    uv: Vec<[f64; 2]>,
}

/// Reads a lightmap bake back: every patch's vertices (checked against the scene) and atlas
/// coordinates (checked to lie in [0, 1]), and the decoded image.
fn read_lightmap(scene: &Scene, bytes: &[u8], size: u32) -> (Vec<BakedPatch>, Vec<u8>, Value) {
    let gltf = gltf::Gltf::from_slice(bytes).expect("the gltf crate parses and validates the bake");
    let bin = gltf.blob.as_deref().unwrap();
    let (json, _) = chunks(bytes);
    assert_eq!(gltf.materials().count(), 1);
    let material = gltf.materials().next().unwrap();
    assert_eq!(json["materials"][0]["extensions"]["KHR_materials_unlit"], serde_json::json!({}));
    let info =
        material.pbr_metallic_roughness().base_color_texture().expect("the lightmap is the base colour");
    assert_eq!(info.tex_coord(), 1, "the lightmap is on the second UV set");
    let texture = info.texture();
    assert_eq!(texture.sampler().mag_filter(), Some(gltf::texture::MagFilter::Linear));
    assert_eq!(texture.sampler().min_filter(), Some(gltf::texture::MinFilter::Linear), "no mipmaps");
    let gltf::image::Source::View { view, mime_type } = texture.source().source() else {
        panic!("a .glb holds its lightmap in a buffer view")
    };
    assert_eq!(mime_type, "image/png");
    let png_bytes = &bin[view.offset()..view.offset() + view.length()];
    let (w, h, rgb) = decode_png(png_bytes);
    assert_eq!((w, h), (size, size));

    // The original meshes: one node per input mesh, each patch once, in patch order.
    let mut patches = Vec::new();
    for node in gltf.nodes() {
        let mesh = node.mesh().unwrap();
        let name = mesh.name().unwrap();
        let prim = mesh.primitives().next().unwrap();
        assert!(prim.get(&gltf::Semantic::Colors(0)).is_none(), "no COLOR_0: it would tint the lightmap");
        let positions = read_vec3(&prim.get(&gltf::Semantic::Positions).unwrap(), bin);
        let uv0 = read_vec2(&prim.get(&gltf::Semantic::TexCoords(0)).unwrap(), bin);
        let uv1 = read_vec2(&prim.get(&gltf::Semantic::TexCoords(1)).unwrap(), bin);
        let indices = read_u32(&prim.indices().unwrap(), bin);
        assert_eq!((uv0.len(), uv1.len()), (positions.len(), positions.len()));
        let mut v = 0;
        let mut triangles = 0;
        for (i, patch) in scene.patches.iter().enumerate().filter(|(_, p)| p.mesh == name) {
            let n = patch.vertices.len();
            for (k, p) in patch.vertices.iter().enumerate() {
                assert_eq!(positions[v + k], p.to_array().map(|c| c as f32), "patch {i}");
                let t = uv1[v + k];
                assert!(t.iter().all(|c| (0.0..=1.0).contains(c)), "TEXCOORD_1 {t:?} of patch {i}");
                // TEXCOORD_0 is the planar map in scene units: its edge lengths are the patch's.
                let k2 = (k + 1) % n;
                let planar = f64::from(uv0[v + k2][0] - uv0[v + k][0])
                    .hypot(f64::from(uv0[v + k2][1] - uv0[v + k][1]));
                let world = (patch.vertices[k2] - *p).length();
                assert!((planar - world).abs() <= 1e-5 * world.max(1.0), "TEXCOORD_0 of patch {i}");
            }
            patches
                .push(BakedPatch { patch: i, uv: uv1[v..v + n].iter().map(|t| t.map(f64::from)).collect() });
            v += n;
            triangles += n - 2;
        }
        assert_eq!(v, positions.len(), "mesh {name} holds exactly its patches");
        assert_eq!(indices.len(), 3 * triangles);
    }
    patches.sort_by_key(|p| p.patch);
    assert_eq!(patches.len(), scene.patches.len(), "every patch is in exactly one mesh");
    (patches, rgb, json)
}

/// The chart's interior texel rectangle [x0, x1) × [y0, y1): its vertices' coordinates span it.
fn chart_rect(p: &BakedPatch, size: u32) -> [usize; 4] {
    let s = f64::from(size);
    let lo = |c: usize| p.uv.iter().map(|t| t[c]).fold(f64::INFINITY, f64::min) * s;
    let hi = |c: usize| p.uv.iter().map(|t| t[c]).fold(f64::NEG_INFINITY, f64::max) * s;
    let r = [lo(0), lo(1), hi(0), hi(1)];
    for c in r {
        assert!((c - c.round()).abs() < 1e-2, "a chart spans whole texels: {c}");
    }
    r.map(|c| c.round() as usize)
}

/// The point of the patch at atlas coordinates `t`, through the affine map of its first three
/// vertices' coordinates (the chart is the patch laid flat, so one map holds for the whole patch).
fn point_at(patch: &radlab::scene::Patch, uv: &[[f64; 2]], t: [f64; 2]) -> radlab::math::DVec3 {
    let (a, b, c) = (uv[0], uv[1], uv[2]);
    let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    let beta = ((t[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (t[1] - a[1])) / det;
    let gamma = ((b[0] - a[0]) * (t[1] - a[1]) - (t[0] - a[0]) * (b[1] - a[1])) / det;
    let v = &patch.vertices;
    v[0] + (v[1] - v[0]) * beta + (v[2] - v[0]) * gamma
}

/// Is `x` inside the (convex, counter-clockwise) patch, at least `margin` from every edge?
fn inside(patch: &radlab::scene::Patch, x: radlab::math::DVec3, margin: f64) -> bool {
    let v = &patch.vertices;
    (0..v.len()).all(|k| {
        let edge = v[(k + 1) % v.len()] - v[k];
        patch.normal.cross(edge).normalize().dot(x - v[k]) >= margin
    })
}

/// Every texel of every chart whose centre lies inside its patch holds the solution's own
/// reconstruction there, exposed and sRGB-encoded (to one 8-bit step); the gutter repeats the
/// chart's edge; charts do not overlap; a chart's centre texel matches the value at that point.
fn check_lightmap_texels(name: &str, size: u32) {
    let (scene, sol, exposure) = solve(name);
    let bytes = lightmap_bake(&scene, &sol, &format!("builtin:{name}"), exposure, size);
    let (patches, rgb, json) = read_lightmap(&scene, &bytes, size);
    let info = &json["asset"]["extras"]["radlab"];
    assert_eq!(info["lightmap"]["size"].as_u64(), Some(u64::from(size)));
    assert_eq!(info["exposure"].as_f64(), Some(exposure));
    assert_eq!(info["color"].as_str(), Some(bake::TEXEL_RULE));
    assert_eq!(info["lightmap"]["charts"].as_u64(), Some(scene.patches.len() as u64));
    let texels_per_unit = info["lightmap"]["texels_per_unit"].as_f64().unwrap();

    let reconstruction = PiecewiseConstant::new(&scene, &sol.elements).unwrap();
    let s = size as usize;
    let texel =
        |x: usize, y: usize| -> [u8; 3] { rgb[3 * (y * s + x)..3 * (y * s + x) + 3].try_into().unwrap() };
    let expected = |patch: usize, x| reconstruction.radiosity_at(patch, x).0.map(|c| srgb8(c * exposure));
    let rects: Vec<[usize; 4]> = patches.iter().map(|p| chart_rect(p, size)).collect();
    let (mut checked, mut near_edge, mut centres) = (0usize, 0usize, 0usize);
    for (p, r) in patches.iter().zip(&rects) {
        let patch = &scene.patches[p.patch];
        let extent = patch.area.sqrt();
        let [x0, y0, x1, y1] = *r;
        assert!(x1 > x0 && y1 > y0, "patch {} has at least one texel", p.patch);
        // The chart's centre: the texel holding the patch's centroid (an affine map keeps it).
        let c = radlab::math::polygon_centroid(
            &p.uv.iter().map(|t| radlab::math::DVec3::new(t[0], t[1], 0.0)).collect::<Vec<_>>(),
        );
        let centre = ((c.x * size as f64) as usize, (c.y * size as f64) as usize);
        for y in y0..y1 {
            for x in x0..x1 {
                let t = [(x as f64 + 0.5) / size as f64, (y as f64 + 0.5) / size as f64];
                let point = point_at(patch, &p.uv, t);
                if !inside(patch, point, 1e-9 * extent) {
                    continue;
                }
                // A centre that falls on an element's edge (or corner) may read any of the
                // elements there, and the point found here from f32 coordinates is ~1e-4 texel
                // off the baker's: accept the values 1e-3 texel to each side.
                let h = 1e-3 / texels_per_unit;
                let (a, b) = (
                    patch.vertices[1] - patch.vertices[0],
                    patch.normal.cross(patch.vertices[1] - patch.vertices[0]),
                );
                let steps = [0.0, h, -h];
                let candidates: Vec<[u8; 3]> = steps
                    .iter()
                    .flat_map(|&du| steps.iter().map(move |&dv| (du, dv)))
                    .map(|(du, dv)| point + a.normalize() * du + b.normalize() * dv)
                    .filter(|&q| inside(patch, q, 0.0))
                    .map(|q| expected(p.patch, q))
                    .collect();
                let got = texel(x, y);
                let close = |e: &[u8; 3]| (0..3).all(|c| got[c].abs_diff(e[c]) <= 1);
                assert!(
                    candidates.iter().any(close),
                    "{name} patch {} texel ({x}, {y}): {got:?}, expected one of {candidates:?}",
                    p.patch
                );
                if candidates.len() > 1 && candidates.iter().any(|e| !close(e)) {
                    near_edge += 1;
                }
                if (x, y) == centre {
                    centres += 1;
                }
                checked += 1;
            }
        }
        // The gutter: each of the `padding` rings around the chart repeats the nearest interior
        // texel, so bilinear filtering at the chart's border reads only the chart.
        let pad = LightmapParams::new(size).padding as usize;
        for y in y0 - pad..y1 + pad {
            for x in x0 - pad..x1 + pad {
                let inner = (x.clamp(x0, x1 - 1), y.clamp(y0, y1 - 1));
                assert_eq!(
                    texel(x, y),
                    texel(inner.0, inner.1),
                    "{name} patch {} gutter ({x}, {y})",
                    p.patch
                );
            }
        }
    }
    // Charts (with their gutters) do not overlap.
    let pad = LightmapParams::new(size).padding as usize;
    for (i, a) in rects.iter().enumerate() {
        for b in &rects[i + 1..] {
            let apart = a[2] + pad <= b[0] - pad
                || b[2] + pad <= a[0] - pad
                || a[3] + pad <= b[1] - pad
                || b[3] + pad <= a[1] - pad;
            assert!(apart, "{name}: charts {a:?} and {b:?} overlap");
        }
    }
    eprintln!(
        "{name} @ {size}: {checked} texels checked ({near_edge} on an element edge), {centres} chart centres"
    );
    assert!(checked > (size as usize).pow(2) / 4, "{name}: only {checked} texels checked");
    assert!(
        centres * 10 >= patches.len() * 9,
        "{name}: {centres} of {} chart centres on their patch",
        patches.len()
    );
    // Texel centres fall on element edges where the chart's texel count and the element's
    // 2^-k subdivision line up (1.3 % of cornell's at 256): few enough that the tolerance above
    // does not make the check vacuous.
    assert!(near_edge * 20 < checked, "{name}: {near_edge} of {checked} texels on an element edge");
    // The exposure shows the walls: some texels strictly between black and white.
    assert!(rgb.chunks_exact(3).any(|t| t.iter().all(|&c| (20..235).contains(&c))));
}

#[test]
fn lightmap_texels_hold_the_solution_at_their_centres() {
    check_lightmap_texels("cornell", 256);
    // Triangles and many small patches; lamps brighter than the exposure.
    check_lightmap_texels("splash_room", 512);
}

#[test]
fn lightmap_gltf_embeds_the_same_png_as_a_data_uri_and_bakes_are_deterministic() {
    let (scene, sol, exposure) = solve("table-room");
    let form = BakeForm::Lightmap(LightmapParams::new(128));
    let opts = options("builtin:table-room", exposure);
    let glb = bake::glb_as(&scene, &sol, &opts, form).unwrap();
    assert_eq!(glb, bake::glb_as(&scene, &sol, &opts, form).unwrap(), "same solution, same bytes");
    assert_eq!(bake::bake_as(&scene, &sol, &opts, form, BakeFormat::Glb).unwrap(), glb);
    let text = bake::gltf_as(&scene, &sol, &opts, form).unwrap();
    let json: Value = serde_json::from_str(&text).unwrap();
    let uri = json["images"][0]["uri"].as_str().unwrap();
    let b64 = uri.strip_prefix("data:image/png;base64,").expect("a PNG data: URI");
    use base64::Engine as _;
    let png_gltf = base64::engine::general_purpose::STANDARD.decode(b64).unwrap();
    let (glb_json, glb_bin) = chunks(&glb);
    let view = &glb_json["bufferViews"][glb_json["images"][0]["bufferView"].as_u64().unwrap() as usize];
    let at = view["byteOffset"].as_u64().unwrap() as usize;
    assert_eq!(&glb_bin[at..at + view["byteLength"].as_u64().unwrap() as usize], png_gltf.as_slice());
    assert_eq!(decode_png(&png_gltf).0, 128);
    // The same meshes, accessors and material in both.
    for key in ["meshes", "accessors", "materials", "textures", "samplers", "nodes"] {
        assert_eq!(json[key], glb_json[key], "{key}");
    }
    // The element form of the same solution holds no texture.
    let (elements, _) = chunks(&bake::glb(&scene, &sol, &opts).unwrap());
    assert!(elements.get("images").is_none() && elements.get("textures").is_none());
    assert!(elements["asset"]["extras"]["radlab"].get("lightmap").is_none());
}

#[test]
fn lightmap_bad_sizes_and_full_atlases_are_errors() {
    let (scene, sol, exposure) = solve("splash_room");
    let opts = options("builtin:splash_room", exposure);
    for size in [0, 63, 100, 1000, 16384] {
        let form = BakeForm::Lightmap(LightmapParams::new(size));
        assert!(
            matches!(bake::glb_as(&scene, &sol, &opts, form), Err(bake::BakeError::BadLightmapSize(s)) if s == size)
        );
    }
    // 219 patches of at least 1 + 2·2 texels square do not fit in 64² (12 × 12 = 144 places).
    let form = BakeForm::Lightmap(LightmapParams::new(64));
    let err = bake::glb_as(&scene, &sol, &opts, form).unwrap_err();
    assert!(matches!(err, bake::BakeError::LightmapTooSmall { size: 64, .. }), "{err}");
}

#[test]
fn cli_bakes_a_lightmap_and_refuses_bad_sizes_with_one_line() {
    let dir = temp_dir("cli-lightmap");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let glb = dir.join("cornell.glb");
    let args =
        ["solve", "builtin:cornell", "--preset", "interactive", "--bake", &s(&glb), "--bake-lightmap", "128"];
    let out = radlab(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("baked 20 patches with a 128×128 lightmap"), "{stdout}");
    let scene = builtin::load("cornell").unwrap();
    let (_, _, json) = read_lightmap(&scene, &std::fs::read(&glb).unwrap(), 128);
    assert!(json["asset"]["extras"]["radlab"]["exposure_rule"].as_str().unwrap().starts_with("auto"));

    // The .gltf form through the CLI: the image as a data: URI.
    let text = dir.join("cornell.gltf");
    let text_path = s(&text);
    let mut args: Vec<&str> =
        "solve builtin:cornell --preset interactive --bake-lightmap 64 -q".split(' ').collect();
    args.extend(["--bake", &text_path]);
    let out = radlab(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: Value = serde_json::from_slice(&std::fs::read(&text).unwrap()).unwrap();
    assert!(json["images"][0]["uri"].as_str().unwrap().starts_with("data:image/png;base64,"));
    assert_eq!(json["asset"]["extras"]["radlab"]["lightmap"]["size"].as_u64(), Some(64));

    let bad = s(&dir.join("bad.glb"));
    let base =
        ["solve", "builtin:furnace", "--preset", "interactive", "--bake", bad.as_str(), "--bake-lightmap"];
    for size in ["100", "32", "16384", "0"] {
        let mut args = base.to_vec();
        args.push(size);
        fails_with(&args, "--bake-lightmap");
        fails_with(&args, "power of two from 64 to 8192");
    }
    // splash_room's 219 patches (216 polygons, one cut around a decal) need more than 64².
    let mut full = vec!["solve", "builtin:splash_room", "--preset", "interactive", "--bake", bad.as_str()];
    full.extend(["--bake-lightmap", "64", "-q"]);
    fails_with(&full, "a 64x64 lightmap cannot hold 219 charts");
    assert!(!dir.join("bad.glb").exists(), "nothing written on a refusal");
    let no_bake = radlab(&["solve", "builtin:furnace", "--bake-lightmap", "256"]);
    assert!(!no_bake.status.success(), "--bake-lightmap needs --bake");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn khronos_validator_reports_nothing_on_the_lightmap_bake_of_every_builtin_scene() {
    let Some(validator) = validator_dir() else { return };
    let dir = temp_dir("validator-lightmap");
    let bake_at = |size: u32| {
        move |scene: &Scene, sol: &Solution, opts: &BakeOptions| {
            bake::bake_as(scene, sol, opts, BakeForm::Lightmap(LightmapParams::new(size)), BakeFormat::Glb)
                .unwrap()
        }
    };
    let gltf_1024 = |scene: &Scene, sol: &Solution, opts: &BakeOptions| {
        bake::bake_as(scene, sol, opts, BakeForm::Lightmap(LightmapParams::new(1024)), BakeFormat::Gltf)
            .unwrap()
    };
    let files = bake_every_builtin(&dir, &bake_at(256), &gltf_1024);
    for (name, msgs) in assert_valid(&validator, &files) {
        // The infos are only TEXCOORD_0 (the planar map) not being used by the material.
        for m in msgs.split("; ").filter(|m| !m.is_empty()) {
            assert!(m.starts_with("UNUSED_OBJECT") && m.contains("TEXCOORD_0"), "{name}: {m}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
