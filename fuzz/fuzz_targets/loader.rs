//! Fuzz target: glTF JSON and GLB bytes → `load_slice` → `Scene` (validation, bounds, area,
//! emitted power) → `gltf_string` → `load_slice` again.
//!
//! The loader gets no folder (`base_dir = None`), so relative URIs are refused and the fuzzer
//! never touches the file system. What must hold for every input: no panic, no hang, no
//! allocation beyond the caps, and every error one line naming the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use radlab::scene::gltf::{LoadOptions, gltf_string, load_slice};
use std::path::Path;

/// The caps are set below the defaults (5 M triangles, 4 GiB, 2^26-pixel textures) so that a
/// small hostile file that instances a mesh up to the cap, or whose texture header claims a
/// huge image, is a quick refusal, not a multi-gigabyte scene under ASan; the work per output
/// triangle or texel is the same at any cap.
fn options() -> LoadOptions {
    LoadOptions {
        max_triangles: 200_000,
        max_file_bytes: 1 << 24,
        max_texture_pixels: 1 << 20,
        ..LoadOptions::default()
    }
}

fn check_error(e: &radlab::scene::SceneError) {
    let msg = e.to_string();
    assert!(msg.contains("fuzz.gltf"), "error does not name the file: {msg}");
    assert!(!msg.contains('\n'), "error is not one line: {msg}");
}

fuzz_target!(|data: &[u8]| {
    let opts = options();
    let label = Path::new("fuzz.gltf");
    match load_slice(data, None, label, &opts) {
        Err(e) => check_error(&e),
        Ok(scene) => {
            assert!(!scene.patches.is_empty());
            // Scene building: every derived quantity is computed without panicking.
            let _report = scene.validate();
            let _ = (scene.bounds(), scene.total_area(), scene.emitted_power());
            // The writer's output is read back by the same loader.
            match gltf_string(&scene) {
                Ok(text) => {
                    if let Err(e) = load_slice(text.as_bytes(), None, label, &opts) {
                        check_error(&e);
                    }
                }
                Err(e) => check_error(&e),
            }
        }
    }
});
