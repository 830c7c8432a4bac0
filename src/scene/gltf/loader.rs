//! The loader's walk over a glTF document [glTF 2.0, sec. 3.5 (nodes), 3.7 (meshes), 3.9
//! (materials)]: the node trees depth-first with their world transforms, the triangle count
//! checked against the cap before any geometry is read, each primitive decoded once and turned
//! into patches per instance, the materials (ρ, E, double-sided, base-colour texture), the
//! warnings, and the first perspective camera as the scene's viewpoint.

use super::base_color::texture_ref;
use super::{Instance, Loader, MAX_NAME_BYTES, Mat, MeshInfo, PrimGeometry, READ_EXTENSIONS};
use crate::math::{DVec3, Rgb};
use crate::scene::{RHO_MAX, Scene, SceneError, Viewpoint};
use glam::DMat4;
use std::collections::HashMap;

impl Loader<'_> {
    pub(super) fn run(mut self, bytes: &[u8]) -> Result<Scene, SceneError> {
        let (json, blob) = if bytes.starts_with(b"glTF") { self.split_glb(bytes)? } else { (bytes, None) };
        let document = self.parse(json)?;
        let doc = &document;
        self.extension_warnings(doc.as_json());

        for image in doc.images() {
            // `parse` checked that every image has exactly one source (the crate panics otherwise).
            if let gltf::image::Source::Uri { uri, .. } = image.source()
                && let Some(rel) = self.check_uri(uri)?
            {
                self.check_image_file(image.index(), &rel, uri)?;
            }
        }

        // Walk the graph first: instances, camera, and the triangle count before reading geometry.
        let (instances, camera_node) = self.walk(doc)?;
        let meshes: Vec<MeshInfo> = doc.meshes().map(|m| self.mesh_info(&m)).collect();
        let mut triangles: usize = 0;
        for inst in &instances {
            let mesh = meshes.get(inst.mesh).ok_or_else(|| self.invalid("mesh index out of range"))?;
            triangles = triangles.saturating_add(mesh.triangles);
            if triangles > self.opts.max_triangles {
                return Err(SceneError::TooLarge { file: self.file.clone(), cap: self.opts.max_triangles });
            }
        }

        let buffers = self.read_buffers(doc, blob)?;
        let materials = self.materials(doc)?;
        self.check_texture_budget(doc, &instances, &meshes, &materials, &buffers)?;
        let default_mat = Mat {
            name: "default".into(),
            rho: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            double_sided: false,
            texture: None,
        };

        // Each primitive is decoded once, however many nodes instance its mesh: the work per
        // instance is then linear in the triangles it adds (which the cap above bounds).
        let mut geometry: HashMap<(usize, usize), PrimGeometry> = HashMap::new();
        let mut patches = Vec::new();
        let (mut skipped_modes, mut missing_positions, mut dropped) = (0usize, 0usize, 0usize);
        for inst in &instances {
            let mesh = &meshes[inst.mesh];
            skipped_modes += mesh.skipped_modes;
            missing_positions += mesh.missing_positions;
            for &(primitive, material) in &mesh.primitives {
                let mat = material.map_or(&default_mat, |i| &materials[i]);
                let geom = match geometry.entry((inst.mesh, primitive)) {
                    std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
                    std::collections::hash_map::Entry::Vacant(e) => {
                        let g =
                            self.decode_primitive(doc, inst.mesh, primitive, &mesh.name, mat, &buffers)?;
                        e.insert(g)
                    }
                };
                let (prim_patches, d) = self.primitive_patches(geom, inst, mat, &mesh.name, primitive)?;
                dropped += d;
                patches.extend(prim_patches);
            }
        }
        if skipped_modes > 0 {
            self.warnings.push(format!(
                "{skipped_modes} primitive(s) with a non-triangle mode (points, lines, strips, fans) skipped"
            ));
        }
        if missing_positions > 0 {
            self.warnings.push(format!("{missing_positions} primitive(s) without POSITION skipped"));
        }
        if dropped > 0 {
            self.warnings.push(format!("{dropped} zero-area triangle(s) dropped"));
        }
        if self.shortened_names > 0 {
            self.warnings.push(format!(
                "{} mesh or material name(s) longer than {MAX_NAME_BYTES} bytes shortened",
                self.shortened_names
            ));
        }
        if patches.is_empty() {
            return Err(SceneError::Empty { file: self.file.clone() });
        }

        let name = self.file.file_stem().map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
        let mut scene = Scene::new(name, self.file.display().to_string(), patches);
        crate::scene::decal::cut_under_decals(&mut scene);
        if let Some((node, world)) = camera_node {
            scene.camera = self.viewpoint(doc, node, world, &scene);
        }
        let mut warnings = self.warnings;
        warnings.append(&mut scene.warnings);
        scene.warnings = warnings;
        Ok(scene)
    }

    /// One line naming the extensions the file uses that are not read (their data is ignored;
    /// an unsupported one in `extensionsRequired` was refused by `parse`), and one for the
    /// punctual lights skipped: radlab's light comes from emissive surfaces, and a point has no
    /// area to emit from.
    fn extension_warnings(&mut self, root: &gltf::json::Root) {
        let mut ignored: Vec<&str> = root
            .extensions_used
            .iter()
            .map(String::as_str)
            .filter(|e| !READ_EXTENSIONS.contains(e) && *e != "KHR_lights_punctual")
            .collect();
        ignored.sort_unstable();
        ignored.dedup();
        if !ignored.is_empty() {
            let shown: Vec<String> = ignored.iter().take(8).map(|e| self.short_name(e)).collect();
            let more =
                if ignored.len() > 8 { format!(" and {} more", ignored.len() - 8) } else { String::new() };
            self.warnings.push(format!("extensions not supported (ignored): {}{more}", shown.join(", ")));
        }
        let lights = root
            .nodes
            .iter()
            .filter(|n| n.extensions.as_ref().is_some_and(|e| e.khr_lights_punctual.is_some()))
            .count();
        if lights > 0 {
            self.warnings.push(format!(
                "KHR_lights_punctual: {lights} light(s) skipped (radlab is lit by emissive surfaces only; model the lamp as an emissive mesh)"
            ));
        }
    }

    /// `name`, cut to at most [`MAX_NAME_BYTES`] (at a character boundary, marked with "…").
    fn short_name(&mut self, name: &str) -> String {
        if name.len() <= MAX_NAME_BYTES {
            return name.to_string();
        }
        self.shortened_names += 1;
        let cut = (0..=MAX_NAME_BYTES).rev().find(|&i| name.is_char_boundary(i)).unwrap_or(0);
        format!("{}…", &name[..cut])
    }

    /// A mesh's name (shortened) and the primitives an instance of it makes triangles from.
    fn mesh_info(&mut self, mesh: &gltf::Mesh) -> MeshInfo {
        let name = match mesh.name() {
            Some(n) => self.short_name(n),
            None => format!("mesh{}", mesh.index()),
        };
        let mut info =
            MeshInfo { name, triangles: 0, primitives: Vec::new(), skipped_modes: 0, missing_positions: 0 };
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                info.skipped_modes += 1;
                continue;
            }
            let Some(positions) = prim.get(&gltf::Semantic::Positions) else {
                info.missing_positions += 1;
                continue;
            };
            let n = prim.indices().map_or(positions.count(), |ix| ix.count()) / 3;
            if n > 0 {
                info.triangles = info.triangles.saturating_add(n);
                info.primitives.push((prim.index(), prim.material().index()));
            }
        }
        info
    }

    fn materials(&mut self, doc: &gltf::Document) -> Result<Vec<Mat>, SceneError> {
        let mut out = Vec::new();
        for m in doc.materials() {
            let index = m.index().unwrap_or(0);
            let name = match m.name() {
                Some(n) => self.short_name(n),
                None => format!("material{index}"),
            };
            let pbr = m.pbr_metallic_roughness();
            let base = pbr.base_color_factor();
            let mut rho = Rgb::new(f64::from(base[0]), f64::from(base[1]), f64::from(base[2]));
            for c in rho.0 {
                if !(0.0..=1.0).contains(&c) {
                    return Err(SceneError::ReflectanceOutOfRange {
                        file: self.file.clone(),
                        material: name,
                        value: c,
                    });
                }
            }
            let json = m.index().and_then(|i| doc.as_json().materials.get(i));
            let texture = json
                .and_then(|j| j.pbr_metallic_roughness.base_color_texture.as_ref())
                .and_then(|info| texture_ref(doc.as_json(), info.index.value(), info.tex_coord));
            // With a texture the factor is a multiplier (1 is the usual value): the product is
            // clamped per patch instead (`primitive_patches`).
            if texture.is_none() && rho.max_channel() > RHO_MAX {
                self.warnings.push(format!(
                    "material {name:?}: reflectance {:?} clamped to {RHO_MAX} (ρ = 1 absorbs nothing: the system would be singular)",
                    rho.0
                ));
                rho = rho.map(|c| c.min(RHO_MAX));
            }
            if json.is_some_and(|j| j.emissive_texture.is_some()) {
                self.warnings.push(format!("material {name:?}: emissive texture ignored (factor used)"));
            }
            let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
            let ef = m.emissive_factor();
            let emission = Rgb::new(f64::from(ef[0]), f64::from(ef[1]), f64::from(ef[2])) * strength;
            for c in emission.0 {
                if !(c >= 0.0 && c.is_finite()) {
                    return Err(SceneError::BadEmission {
                        file: self.file.clone(),
                        material: name,
                        value: c,
                    });
                }
            }
            out.push(Mat { name, rho, emission, double_sided: m.double_sided(), texture });
        }
        Ok(out)
    }

    /// Depth-first walk of the default scene (or, without scenes, of every root node), in document
    /// order. Returns the mesh instances and the first perspective camera node.
    #[allow(clippy::type_complexity)]
    fn walk(&self, doc: &gltf::Document) -> Result<(Vec<Instance>, Option<(usize, DMat4)>), SceneError> {
        let roots: Vec<usize> = if let Some(s) = doc.default_scene().or_else(|| doc.scenes().next()) {
            s.nodes().map(|n| n.index()).collect()
        } else {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            (0..is_child.len()).filter(|&i| !is_child[i]).collect()
        };
        let nodes: Vec<gltf::Node> = doc.nodes().collect();
        let mut instances = Vec::new();
        let mut camera = None;
        // `check_structure` made the nodes disjoint trees, so no node is reached twice; the
        // check stays as the walk's own guarantee of linear work.
        let mut visited = vec![false; nodes.len()];
        // Explicit stack: (node, parent world matrix) so deep trees cannot overflow.
        let mut stack: Vec<(usize, DMat4)> = roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
        while let Some((i, parent)) = stack.pop() {
            let node = nodes.get(i).ok_or_else(|| self.invalid(format!("node {i} does not exist")))?;
            if std::mem::replace(&mut visited[i], true) {
                return Err(self.invalid(format!("node {i} is reached twice (the nodes are not trees)")));
            }
            let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
            if !local.is_finite() {
                return Err(self.invalid(format!("node {i}: non-finite transform")));
            }
            let world = parent * local;
            if let Some(m) = node.mesh() {
                instances.push(Instance { mesh: m.index(), world });
            }
            if camera.is_none() && node.camera().is_some() {
                camera = Some((i, world));
            }
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            for &c in children.iter().rev() {
                stack.push((c, world));
            }
        }
        Ok((instances, camera))
    }

    /// The camera node's placement: eye = node origin, looking down its −z, up = its +y
    /// [glTF 2.0, sec. 3.10]. glTF has no target; it is put at the distance of the scene's centre.
    fn viewpoint(
        &mut self,
        doc: &gltf::Document,
        node: usize,
        world: DMat4,
        scene: &Scene,
    ) -> Option<Viewpoint> {
        let cam = doc.nodes().nth(node)?.camera()?;
        let gltf::camera::Projection::Perspective(p) = cam.projection() else {
            self.warnings.push("orthographic camera ignored (a default view is used)".into());
            return None;
        };
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
        let fov = f64::from(p.yfov()).to_degrees();
        if forward == DVec3::ZERO || up == DVec3::ZERO || !(fov > 0.0 && fov < 180.0) {
            self.warnings.push("degenerate camera ignored (a default view is used)".into());
            return None;
        }
        let b = scene.bounds();
        let dist = (b.center() - eye).length();
        let dist = if dist > 0.0 { dist } else { 0.5 * b.diagonal().max(1.0) };
        Some(Viewpoint { eye, target: eye + forward * dist, up, fov_y_deg: fov })
    }
}
