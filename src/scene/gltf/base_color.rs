//! Base-colour textures: the image bytes (a file inside the folder, a data URI or a buffer
//! view), decoded once per image by [`crate::scene::texture`] after the headers of all the
//! file's textures were summed against the pixel budget, texture coordinates read from their
//! accessor, and the texture's mean over each triangle, which multiplies the material's ρ.

use super::io::decode_data_uri;
use super::{Instance, Loader, Mat, MeshInfo, TEXTURE_BUDGET, TextureRef};
use crate::math::Rgb;
use crate::scene::SceneError;
use crate::scene::texture::{Texture, Wrap};
use gltf::accessor::{DataType, Dimensions};
use std::borrow::Cow;
use std::collections::BTreeSet;
use std::rc::Rc;

/// An image's encoded bytes and where they came from (for errors).
type ImageBytes<'b> = (Cow<'b, [u8]>, String);

impl Loader<'_> {
    /// The base-colour texture's mean over each triangle (`indices` in threes) of a primitive,
    /// or `None` with a warning when the texture or the texture coordinates are unavailable.
    pub(super) fn texture_means(
        &mut self,
        doc: &gltf::Document,
        prim: &gltf::Primitive,
        tex: TextureRef,
        material: &str,
        indices: &[u32],
        n_vertices: usize,
        buffers: &[Cow<[u8]>],
    ) -> Result<Option<Vec<Rgb>>, SceneError> {
        let Some(acc) = prim.get(&gltf::Semantic::TexCoords(tex.tex_coord)) else {
            self.warnings.push(format!(
                "material {material:?}: a primitive has no TEXCOORD_{} (texture not used, factor used)",
                tex.tex_coord
            ));
            return Ok(None);
        };
        if acc.count() != n_vertices {
            return Err(self.invalid(format!(
                "accessor {}: TEXCOORD_{} has {} elements, POSITION has {n_vertices}",
                acc.index(),
                tex.tex_coord,
                acc.count()
            )));
        }
        let uvs = self.read_uvs(&acc, buffers)?;
        let Some(texture) = self.texture(doc, tex.image, buffers)? else { return Ok(None) };
        Ok(Some(
            indices
                .chunks_exact(3)
                .map(|t| {
                    texture
                        .triangle_mean([uvs[t[0] as usize], uvs[t[1] as usize], uvs[t[2] as usize]], tex.wrap)
                })
                .collect(),
        ))
    }

    /// Texture coordinates: float, or normalized unsigned byte/short VEC2 [glTF 2.0, sec. 3.7.2.1].
    fn read_uvs(&self, acc: &gltf::Accessor, buffers: &[Cow<[u8]>]) -> Result<Vec<[f64; 2]>, SceneError> {
        let size = match acc.data_type() {
            DataType::F32 => 4,
            DataType::U8 if acc.normalized() => 1,
            DataType::U16 if acc.normalized() => 2,
            _ => 0,
        };
        if size == 0 || acc.dimensions() != Dimensions::Vec2 {
            return Err(self.invalid(format!(
                "accessor {}: TEXCOORD must be float or normalized unsigned byte/short VEC2",
                acc.index()
            )));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, 2 * size)?;
        let comp = |e: &[u8], k: usize| -> f64 {
            match size {
                4 => f64::from(f32::from_le_bytes([e[4 * k], e[4 * k + 1], e[4 * k + 2], e[4 * k + 3]])),
                2 => f64::from(u16::from_le_bytes([e[2 * k], e[2 * k + 1]])) / 65535.0,
                _ => f64::from(e[k]) / 255.0,
            }
        };
        Ok((0..acc.count())
            .map(|i| {
                let e = &bytes[i * stride..i * stride + 2 * size];
                [comp(e, 0), comp(e, 1)]
            })
            .collect())
    }

    /// Refuse a file whose base-colour textures would decode to more than `TEXTURE_BUDGET` ×
    /// [`LoadOptions::max_texture_pixels`] pixels in all, from their headers, before any is
    /// decoded. Only the images of materials that instanced primitives use are counted; an
    /// image whose header is unreadable or over the per-image cap is left to [`Loader::texture`],
    /// which refuses it with its own cause when it is used.
    pub(super) fn check_texture_budget(
        &mut self,
        doc: &gltf::Document,
        instances: &[Instance],
        meshes: &[MeshInfo],
        materials: &[Mat],
        buffers: &[Cow<[u8]>],
    ) -> Result<(), SceneError> {
        let images: BTreeSet<usize> = instances
            .iter()
            .filter_map(|inst| meshes.get(inst.mesh))
            .flat_map(|mesh| &mesh.primitives)
            .filter_map(|&(_, material)| materials.get(material?)?.texture)
            .map(|t| t.image)
            .collect();
        let budget = self.opts.max_texture_pixels.saturating_mul(TEXTURE_BUDGET);
        let warnings = self.warnings.len();
        let mut pixels: u64 = 0;
        for image in images {
            let Some((bytes, label)) = self.image_bytes(doc, image, buffers)? else { continue };
            let Ok((w, h)) = Texture::header(&bytes, self.opts.max_texture_pixels) else { continue };
            pixels = pixels.saturating_add(u64::from(w) * u64::from(h));
            if pixels > budget {
                return Err(SceneError::Image {
                    file: self.file.clone(),
                    index: image,
                    cause: format!(
                        "{label}: {w}×{h} takes the textures' headers to {pixels} pixels in all, \
                         more than the limit of {budget} ({TEXTURE_BUDGET} × {}) (nothing decoded)",
                        self.opts.max_texture_pixels
                    ),
                });
            }
        }
        // `texture` warns about an image it cannot read when a primitive uses it.
        self.warnings.truncate(warnings);
        Ok(())
    }

    /// An image decoded as a texture, once per image; `None` (warned) if it cannot be read
    /// here: a missing file, or a relative URI with no folder to resolve it in.
    fn texture(
        &mut self,
        doc: &gltf::Document,
        image: usize,
        buffers: &[Cow<[u8]>],
    ) -> Result<Option<Rc<Texture>>, SceneError> {
        if let Some(t) = self.textures.get(&image) {
            return Ok(t.clone());
        }
        let decoded = match self.image_bytes(doc, image, buffers)? {
            None => None,
            Some((bytes, label)) => {
                let t = Texture::decode(&bytes, self.opts.max_texture_pixels).map_err(|cause| {
                    SceneError::Image {
                        file: self.file.clone(),
                        index: image,
                        cause: format!("{label}: {cause}"),
                    }
                })?;
                Some(Rc::new(t))
            }
        };
        self.textures.insert(image, decoded.clone());
        Ok(decoded)
    }

    /// An image's encoded bytes and a label naming where they came from (its file, a data
    /// URI, a buffer view).
    fn image_bytes<'b>(
        &mut self,
        doc: &gltf::Document,
        image: usize,
        buffers: &'b [Cow<[u8]>],
    ) -> Result<Option<ImageBytes<'b>>, SceneError> {
        let err = |cause: String| SceneError::Image { file: self.file.clone(), index: image, cause };
        let img = doc.images().nth(image).ok_or_else(|| err("does not exist".into()))?;
        // `parse` checked that every image has exactly one source (the crate panics otherwise).
        match img.source() {
            gltf::image::Source::Uri { uri, .. } => match self.check_uri(uri)? {
                None => Ok(Some((Cow::Owned(decode_data_uri(uri).map_err(err)?), "data: URI".into()))),
                Some(rel) => {
                    let Some(base) = self.base_dir else {
                        self.warnings.push(format!(
                            "image {image}: {uri:?} not read (no folder to resolve it in; its texture is not used)"
                        ));
                        return Ok(None);
                    };
                    let shown = base.join(&rel);
                    if std::fs::metadata(&shown).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) {
                        return Ok(None); // warned by `check_image_file`
                    }
                    let bytes = self.read_relative(&rel, uri, usize::MAX).map_err(err)?;
                    Ok(Some((Cow::Owned(bytes), shown.display().to_string())))
                }
            },
            gltf::image::Source::View { view, .. } => {
                let buf = buffers.get(view.buffer().index()).ok_or_else(|| err("bad buffer".into()))?;
                let range = view
                    .offset()
                    .checked_add(view.length())
                    .filter(|&end| end <= buf.len())
                    .map(|end| view.offset()..end)
                    .ok_or_else(|| err(format!("bufferView {} runs past its buffer", view.index())))?;
                Ok(Some((Cow::Borrowed(&buf[range]), format!("bufferView {}", view.index()))))
            }
        }
    }
}

/// A material's base-colour texture from the JSON (indices were validated by `parse`).
pub(super) fn texture_ref(root: &gltf::json::Root, texture: usize, tex_coord: u32) -> Option<TextureRef> {
    use gltf::json::validation::Checked;
    let t = root.textures.get(texture)?;
    let wrap = |w: &Checked<gltf::json::texture::WrappingMode>| match w {
        Checked::Valid(w) => Wrap::from_gl(w.as_gl_enum()),
        Checked::Invalid => Wrap::Repeat,
    };
    let sampler = t.sampler.and_then(|s| root.samplers.get(s.value()));
    let wrap = sampler.map_or([Wrap::Repeat; 2], |s| [wrap(&s.wrap_s), wrap(&s.wrap_t)]);
    Some(TextureRef { image: t.source.value(), tex_coord, wrap })
}
