//! The JSON checked before the `gltf` crate reads it: every attribute index in range, the
//! crate's own validation (the accessor `min`/`max` many exporters omit tolerated), and what the
//! spec requires and the crate relies on without checking — one source per image, the projection
//! a camera's type names, nodes forming disjoint trees [glTF 2.0, sec. 3.5.3, 5.18].

use super::{Loader, SceneError};

impl Loader<'_> {
    /// Parse and validate the JSON. Every index must be in range (the `gltf` crate's iterators
    /// rely on it); the accessor `min`/`max` the spec requires for POSITION are not needed here
    /// and many exporters omit them, so their absence is tolerated.
    pub(super) fn parse(&self, json: &[u8]) -> Result<gltf::Document, SceneError> {
        use gltf::json::validation::{Error as VError, Validate};
        let root: gltf::json::Root =
            gltf::json::deserialize::from_slice(json).map_err(|e| self.invalid(e.to_string()))?;
        // gltf-json's own validation indexes `accessors[POSITION]` unchecked (it panics on a
        // dangling index), so attribute indices are checked first.
        for (m, mesh) in root.meshes.iter().enumerate() {
            for (p, prim) in mesh.primitives.iter().enumerate() {
                if let Some(bad) = prim.attributes.values().find(|i| i.value() >= root.accessors.len()) {
                    return Err(self.invalid(format!(
                        "meshes[{m}].primitives[{p}].attributes: accessor {} does not exist",
                        bad.value()
                    )));
                }
            }
        }
        let mut errors = Vec::new();
        root.validate(&root, gltf::json::Path::new, &mut |path, error| {
            let path = path();
            let min_max = path.as_str().ends_with(".min") || path.as_str().ends_with(".max");
            if !(min_max && error == VError::Missing) {
                errors.push(format!("{path}: {error}"));
            }
        });
        if let Some(first) = errors.first() {
            let more =
                if errors.len() > 1 { format!(" (and {} more)", errors.len() - 1) } else { String::new() };
            return Err(self.invalid(format!("{first}{more}")));
        }
        self.check_structure(&root)?;
        Ok(gltf::Document::from_json_without_validation(root))
    }

    /// What the spec requires, gltf-json does not validate, and the `gltf` crate (or a linear
    /// walk of the scene) relies on:
    /// - an image has a `uri` or a `bufferView`, not both, and a `bufferView` image has a
    ///   `mimeType` [glTF 2.0, sec. 5.18] (`Image::source` unwraps them);
    /// - a camera has the projection its `type` names (`Camera::projection` unwraps it);
    /// - the nodes form disjoint trees [glTF 2.0, sec. 3.5.3]: no node has two parents, a
    ///   scene's root nodes have none and are listed once. A node reused as a child of several
    ///   nodes (or listed many times) would describe exponentially many instances from a few
    ///   bytes; as trees, the walk visits each node at most once.
    fn check_structure(&self, root: &gltf::json::Root) -> Result<(), SceneError> {
        for (i, image) in root.images.iter().enumerate() {
            match (&image.uri, &image.buffer_view, &image.mime_type) {
                (Some(_), None, _) | (None, Some(_), Some(_)) => {}
                (None, None, _) => {
                    return Err(self.invalid(format!("image {i} has neither uri nor bufferView")));
                }
                (Some(_), Some(_), _) => {
                    return Err(self.invalid(format!("image {i} has both uri and bufferView")));
                }
                (None, Some(_), None) => {
                    return Err(self.invalid(format!("image {i} has a bufferView but no mimeType")));
                }
            }
        }
        for (i, camera) in root.cameras.iter().enumerate() {
            use gltf::json::camera::Type;
            use gltf::json::validation::Checked;
            let ok = match camera.type_ {
                Checked::Valid(Type::Perspective) => camera.perspective.is_some(),
                Checked::Valid(Type::Orthographic) => camera.orthographic.is_some(),
                Checked::Invalid => false,
            };
            if !ok {
                return Err(self.invalid(format!("camera {i} lacks the projection its type names")));
            }
        }
        let mut parent: Vec<Option<usize>> = vec![None; root.nodes.len()];
        for (i, node) in root.nodes.iter().enumerate() {
            for c in node.children.iter().flatten() {
                let slot = parent
                    .get_mut(c.value())
                    .ok_or_else(|| self.invalid(format!("node {i}: child {} does not exist", c.value())))?;
                if let Some(p) = slot.replace(i) {
                    return Err(self.invalid(format!(
                        "node {} has two parents ({p} and {i}); glTF nodes form disjoint trees",
                        c.value()
                    )));
                }
            }
        }
        for (s, scene) in root.scenes.iter().enumerate() {
            let mut listed = vec![false; root.nodes.len()];
            for n in &scene.nodes {
                let i = n.value();
                let seen = listed
                    .get_mut(i)
                    .ok_or_else(|| self.invalid(format!("scene {s}: node {i} does not exist")))?;
                if std::mem::replace(seen, true) {
                    return Err(self.invalid(format!("scene {s} lists node {i} twice")));
                }
                if let Some(p) = parent[i] {
                    return Err(self.invalid(format!("scene {s}: root node {i} has a parent ({p})")));
                }
            }
        }
        Ok(())
    }
}
