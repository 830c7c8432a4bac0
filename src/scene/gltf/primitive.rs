//! One primitive's triangles: positions and indices read from accessors whose ranges are
//! checked against their views and buffers first, the vertices the triangles use kept once,
//! and, per instance, the world-space patches — zero-area triangles dropped, the winding
//! reversed under a mirroring transform, and pairs of triangles sharing an edge merged into a
//! planar, strictly convex quad.
//!
//! ```text
//!   tri i = (p0 p1 p2), shared edge p2→p0, tri j = (p0 p2 q)      p2 ──── q
//!   quad  = (p0 p1 p2 q)   (starts at p0, keeps i's orientation)   │ i   ╱ │
//!                                                                  │   ╱ j │
//!                                                                  p1 ── p0
//! ```

use super::{
    DEGENERATE_REL_AREA, Instance, Loader, MAX_EDGE_CANDIDATES, MERGE_CONVEX_REL, Mat, PrimGeometry,
};
use crate::math::{DVec3, Rgb};
use crate::scene::{PLANARITY_TOL, Patch, RHO_MAX, SceneError, is_convex};
use glam::DMat3;
use gltf::accessor::{DataType, Dimensions};
use std::borrow::Cow;
use std::collections::HashMap;

impl Loader<'_> {
    /// Read one primitive's positions and indices and keep the vertices its triangles use.
    pub(super) fn decode_primitive(
        &mut self,
        doc: &gltf::Document,
        mesh_index: usize,
        primitive: usize,
        mesh_name: &str,
        mat: &Mat,
        buffers: &[Cow<[u8]>],
    ) -> Result<PrimGeometry, SceneError> {
        let prim = doc
            .meshes()
            .nth(mesh_index)
            .and_then(|m| m.primitives().nth(primitive))
            .ok_or_else(|| self.invalid("primitive index out of range"))?;
        let pos_acc =
            prim.get(&gltf::Semantic::Positions).ok_or_else(|| self.invalid("primitive without POSITION"))?;
        let positions = self.read_positions(&pos_acc, buffers, mesh_name, primitive)?;
        let indices = match prim.indices() {
            Some(acc) => {
                if acc.count() % 3 != 0 {
                    self.warnings.push(format!(
                        "mesh {mesh_name:?} primitive {primitive}: index count is not a multiple of 3 (the rest is ignored)"
                    ));
                }
                self.read_indices(&acc, buffers, positions.len())?
            }
            None => (0..positions.len() as u32).collect(),
        };
        // Compact: only the vertices the triangles use, numbered in order of first use, so an
        // instance transforms at most 3 vertices per triangle whatever the accessor's size.
        let mut compact = vec![u32::MAX; positions.len()];
        let mut vertices = Vec::new();
        let mut ids = Vec::new();
        let mut canon: HashMap<[u32; 3], u32> = HashMap::new();
        let mut triangles = Vec::with_capacity(indices.len() / 3);
        for tri in indices.chunks_exact(3) {
            triangles.push([tri[0], tri[1], tri[2]].map(|i| {
                let slot = &mut compact[i as usize];
                if *slot == u32::MAX {
                    *slot = vertices.len() as u32;
                    let p = positions[i as usize];
                    vertices.push(DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])));
                    // Canonical ids by exact position, so unindexed duplicates still share edges.
                    let next = canon.len() as u32;
                    ids.push(*canon.entry(p.map(f32::to_bits)).or_insert(next));
                }
                *slot
            }));
        }
        let texture_means = match mat.texture {
            Some(tex) => {
                self.texture_means(doc, &prim, tex, &mat.name, &indices, positions.len(), buffers)?
            }
            None => None,
        };
        Ok(PrimGeometry { vertices, ids, triangles, texture_means })
    }

    /// Check an accessor's range against its view and buffer; return (bytes, offset, stride).
    pub(super) fn accessor_bytes<'b>(
        &self,
        acc: &gltf::Accessor,
        buffers: &'b [Cow<'_, [u8]>],
        elem: usize,
    ) -> Result<(&'b [u8], usize), SceneError> {
        let ai = acc.index();
        if acc.sparse().is_some() {
            return Err(self.invalid(format!("accessor {ai}: sparse accessors are not supported")));
        }
        let view = acc.view().ok_or_else(|| self.invalid(format!("accessor {ai} has no bufferView")))?;
        let buf = buffers
            .get(view.buffer().index())
            .ok_or_else(|| self.invalid(format!("accessor {ai}: bad buffer")))?;
        let declared = view.buffer().length();
        let view_end = view.offset().checked_add(view.length());
        let Some(view_end) = view_end.filter(|&e| e <= declared && e <= buf.len()) else {
            return Err(SceneError::Buffer {
                file: self.file.clone(),
                index: view.buffer().index(),
                cause: format!(
                    "bufferView {} (offset {}, length {}) runs past the buffer's {} bytes",
                    view.index(),
                    view.offset(),
                    view.length(),
                    buf.len().min(declared)
                ),
            });
        };
        let view_bytes = &buf[view.offset()..view_end];
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(
                self.invalid(format!("bufferView {}: stride {stride} < element size {elem}", view.index()))
            );
        }
        let count = acc.count();
        let end = count
            .checked_sub(1)
            .and_then(|n| n.checked_mul(stride))
            .and_then(|x| x.checked_add(acc.offset()))
            .and_then(|x| x.checked_add(elem));
        match end {
            Some(end) if end <= view_bytes.len() => Ok((&view_bytes[acc.offset()..end], stride)),
            _ if count == 0 => Ok((&view_bytes[..0], stride)),
            _ => Err(SceneError::Buffer {
                file: self.file.clone(),
                index: view.buffer().index(),
                cause: format!(
                    "accessor {ai} ({count} elements, stride {stride}, offset {}) runs past bufferView {}'s {} bytes",
                    acc.offset(),
                    view.index(),
                    view_bytes.len()
                ),
            }),
        }
    }

    fn read_positions(
        &self,
        acc: &gltf::Accessor,
        buffers: &[Cow<[u8]>],
        mesh: &str,
        primitive: usize,
    ) -> Result<Vec<[f32; 3]>, SceneError> {
        if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
            return Err(self.invalid(format!("accessor {}: POSITION must be float VEC3", acc.index())));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, 12)?;
        let f = |b: &[u8], k: usize| f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]]);
        let mut out = Vec::with_capacity(acc.count());
        for i in 0..acc.count() {
            let e = &bytes[i * stride..i * stride + 12];
            let p = [f(e, 0), f(e, 1), f(e, 2)];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(SceneError::NonFinitePosition {
                    file: self.file.clone(),
                    mesh: mesh.into(),
                    primitive,
                });
            }
            out.push(p);
        }
        Ok(out)
    }

    fn read_indices(
        &self,
        acc: &gltf::Accessor,
        buffers: &[Cow<[u8]>],
        n_vertices: usize,
    ) -> Result<Vec<u32>, SceneError> {
        let size = match acc.data_type() {
            DataType::U8 => 1,
            DataType::U16 => 2,
            DataType::U32 => 4,
            t => return Err(self.invalid(format!("accessor {}: index type {t:?}", acc.index()))),
        };
        if acc.dimensions() != Dimensions::Scalar {
            return Err(self.invalid(format!("accessor {}: indices must be SCALAR", acc.index())));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, size)?;
        let mut out = Vec::with_capacity(acc.count());
        for i in 0..acc.count() {
            let e = &bytes[i * stride..i * stride + size];
            let v = match size {
                1 => u32::from(e[0]),
                2 => u32::from(u16::from_le_bytes([e[0], e[1]])),
                _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
            };
            if v as usize >= n_vertices {
                return Err(
                    self.invalid(format!("accessor {}: index {v} ≥ vertex count {n_vertices}", acc.index()))
                );
            }
            out.push(v);
        }
        Ok(out)
    }

    /// Triangles of one primitive instance → patches (merged quads, double-sided copies).
    /// Returns the patches and the number of zero-area triangles dropped.
    pub(super) fn primitive_patches(
        &self,
        geom: &PrimGeometry,
        inst: &Instance,
        mat: &Mat,
        mesh: &str,
        primitive: usize,
    ) -> Result<(Vec<Patch>, usize), SceneError> {
        let flip = DMat3::from_mat4(inst.world).determinant() < 0.0;
        let world: Vec<DVec3> = geom.vertices.iter().map(|&p| inst.world.transform_point3(p)).collect();
        if world.iter().any(|v| !v.is_finite()) {
            return Err(SceneError::NonFinitePosition {
                file: self.file.clone(),
                mesh: mesh.into(),
                primitive,
            });
        }
        let (tris, dropped) = front_triangles(geom, &world, flip);
        let edges = edge_triangles(&tris, &geom.ids);
        let mut used = vec![false; tris.len()];
        let mut out = Vec::new();
        for k in 0..tris.len() {
            if used[k] {
                continue;
            }
            used[k] = true;
            let (t, v) = tris[k];
            let p = v.map(|i| world[i as usize]);
            let best = merge_partner(k, &tris, &edges, &used, &geom.ids, &world);
            // ρ = baseColorFactor × the texture's mean over the patch (area-weighted over a
            // merged quad's two triangles).
            let tex_mean = |t: usize| geom.texture_means.as_ref().and_then(|m| m.get(t)).copied();
            let area = |v: &[u32; 3]| {
                let [a, b, c] = v.map(|i| world[i as usize]);
                (b - a).cross(c - a).length()
            };
            let (verts, texel) = match best {
                Some((j, quad)) => {
                    used[j] = true;
                    let (tj, vj) = tris[j];
                    let texel = tex_mean(t).zip(tex_mean(tj)).map(|(ci, cj)| {
                        let (ai, aj) = (area(&v), area(&vj));
                        (ci * ai + cj * aj) / (ai + aj)
                    });
                    (quad, texel)
                }
                None => (p.to_vec(), tex_mean(t)),
            };
            let r = mat.rho.0;
            let rho = texel
                .map_or(mat.rho, |c| Rgb::new(r[0] * c.0[0], r[1] * c.0[1], r[2] * c.0[2]))
                .map(|c| c.min(RHO_MAX));
            let name = format!("{mesh}/{primitive}/{t}");
            let mut push = |verts: Vec<DVec3>, name: String| -> Result<(), SceneError> {
                let index = out.len();
                let patch = Patch::new(verts, rho, mat.emission, mesh, primitive, name, mat.name.clone())
                    .map_err(|cause| SceneError::BadPatch { file: self.file.clone(), index, cause })?;
                out.push(patch);
                Ok(())
            };
            if mat.double_sided {
                let back: Vec<DVec3> = verts.iter().rev().copied().collect();
                push(verts, name.clone())?;
                push(back, format!("{name}/back"))?;
            } else {
                push(verts, name)?;
            }
        }
        Ok((out, dropped))
    }
}

/// A triangle of a primitive: its number in index order, and its vertex indices in front-facing
/// order.
type Tri = (usize, [u32; 3]);

/// The triangles of a primitive instance that have an area, in index order, their winding
/// reversed under a mirroring transform (`flip`); and how many had none.
fn front_triangles(geom: &PrimGeometry, world: &[DVec3], flip: bool) -> (Vec<Tri>, usize) {
    let mut tris: Vec<Tri> = Vec::new();
    let mut dropped = 0;
    for (t, c) in geom.triangles.iter().enumerate() {
        let v = if flip { [c[0], c[2], c[1]] } else { [c[0], c[1], c[2]] };
        let [a, b, cc] = v.map(|i| world[i as usize]);
        let longest = (b - a).length_squared().max((cc - b).length_squared()).max((a - cc).length_squared());
        let area2 = (b - a).cross(cc - a).length();
        let has_area = area2 > DEGENERATE_REL_AREA * longest; // false for NaN too
        if !has_area {
            dropped += 1;
            continue;
        }
        tris.push((t, v));
    }
    (tris, dropped)
}

/// Directed edges (canonical vertex ids) → the triangles having them, in order.
fn edge_triangles(tris: &[Tri], ids: &[u32]) -> HashMap<(u32, u32), Vec<usize>> {
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (k, (_, v)) in tris.iter().enumerate() {
        for e in 0..3 {
            edges.entry((ids[v[e] as usize], ids[v[(e + 1) % 3] as usize])).or_default().push(k);
        }
    }
    edges
}

/// Triangle `k`'s merge partner: the earliest later unused triangle that shares one of its edges
/// (running the other way) and makes with it a quad [`mergeable`] accepts, and that quad
/// (starting at k's first vertex, keeping k's orientation).
fn merge_partner(
    k: usize,
    tris: &[Tri],
    edges: &HashMap<(u32, u32), Vec<usize>>,
    used: &[bool],
    ids: &[u32],
    world: &[DVec3],
) -> Option<(usize, Vec<DVec3>)> {
    let v = tris[k].1;
    let p = v.map(|i| world[i as usize]);
    let mut best: Option<(usize, Vec<DVec3>)> = None;
    for e in 0..3 {
        let key = (ids[v[(e + 1) % 3] as usize], ids[v[e] as usize]);
        // The list is in triangle order: skip to the triangles after k, and look at no
        // more than MAX_EDGE_CANDIDATES of them (an edge that many triangles share is not
        // a surface a quad belongs to; without the bound a fan of n triangles on one edge
        // costs n² merge tests).
        let list = edges.get(&key).map_or(&[][..], Vec::as_slice);
        let later = &list[list.partition_point(|&j| j <= k)..];
        for &j in later.iter().take(MAX_EDGE_CANDIDATES) {
            if best.as_ref().is_some_and(|(b, _)| *b <= j) {
                break;
            }
            if used[j] {
                continue;
            }
            let w = tris[j].1;
            let shared = [ids[v[e] as usize], ids[v[(e + 1) % 3] as usize]];
            let Some(q) = w.iter().find(|&&i| !shared.contains(&ids[i as usize])) else { continue };
            let q = world[*q as usize];
            let quad = match e {
                0 => vec![p[0], q, p[1], p[2]],
                1 => vec![p[0], p[1], q, p[2]],
                _ => vec![p[0], p[1], p[2], q],
            };
            if mergeable(&quad) {
                best = Some((j, quad));
            }
        }
    }
    best
}

/// Is this quad (from two triangles) planar and strictly convex, as `Scene::validate` requires?
/// (Generated scenes use it to emit as quads exactly the triangle pairs this loader merges.)
pub(crate) fn mergeable(quad: &[DVec3]) -> bool {
    let Ok(p) = Patch::new(quad.to_vec(), Rgb::ZERO, Rgb::ZERO, "", 0, "", "") else { return false };
    let diam = p.diameter();
    if quad.iter().any(|v| (p.normal.dot(*v) - p.plane_d()).abs() > PLANARITY_TOL * diam) {
        return false;
    }
    if !is_convex(quad, p.normal) {
        return false;
    }
    (0..4).all(|i| {
        let (a, b, c) = (quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]);
        (b - a).cross(c - b).dot(p.normal) > MERGE_CONVEX_REL * diam * diam
    })
}
