//! Turns the viewer's element lists (see [`crate::overlay`]) into GPU vertex arrays in the
//! scene's local frame (world minus `origin`, then `f32`), so scenes far from the origin keep
//! their precision on the GPU.

use super::gpu_data::{LineVertex, MeshVertex};
use crate::math::{DVec3, Rgb};
use crate::overlay::{ElementView, LineList, vertex_radiosity};

/// How the mesh is coloured.
#[derive(Copy, Clone, Debug)]
pub enum MeshColors<'a> {
    /// Each element's radiosity at all its corners.
    Flat,
    /// Gouraud: vertex averages with T-vertices anchored ([`vertex_radiosity`]).
    Smooth,
    /// A display colour per element id (error heatmap); the shader's mode must be 1.
    Display(&'a [[f32; 3]]),
}

fn local(p: DVec3, origin: DVec3) -> [f32; 3] {
    let q = p - origin;
    [q.x as f32, q.y as f32, q.z as f32]
}

fn rgb(c: Rgb) -> [f32; 3] {
    [c.0[0] as f32, c.0[1] as f32, c.0[2] as f32]
}

/// Triangle list of the leaves (quads as two triangles 0-1-2, 0-2-3).
#[must_use]
pub fn mesh(
    elements: &[ElementView],
    leaves: &[u32],
    colors: MeshColors<'_>,
    origin: DVec3,
) -> Vec<MeshVertex> {
    let smooth = matches!(colors, MeshColors::Smooth).then(|| vertex_radiosity(elements, leaves));
    let mut out = Vec::with_capacity(leaves.len() * 6);
    for (k, &l) in leaves.iter().enumerate() {
        let e = &elements[l as usize];
        let corner = |i: usize| -> [f32; 3] {
            match colors {
                MeshColors::Flat => rgb(e.radiosity),
                MeshColors::Smooth => smooth.as_ref().map_or(rgb(e.radiosity), |s| rgb(s[k][i])),
                MeshColors::Display(c) => c.get(l as usize).copied().unwrap_or([0.0; 3]),
            }
        };
        let tris: &[[usize; 3]] = if e.n_vertices == 4 { &[[0, 1, 2], [0, 2, 3]] } else { &[[0, 1, 2]] };
        for t in tris {
            for &i in t {
                out.push(MeshVertex {
                    position: local(e.vertices[i], origin),
                    element: e.id,
                    color: corner(i),
                });
            }
        }
    }
    out
}

/// Line vertices of a [`LineList`].
#[must_use]
pub fn lines(list: &LineList, origin: DVec3) -> Vec<LineVertex> {
    list.points
        .iter()
        .zip(&list.colors)
        .map(|(p, c)| LineVertex { position: local(*p, origin), color: *c })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(id: u32, b: f64) -> ElementView {
        ElementView {
            id,
            patch: 0,
            parent: None,
            depth: 0,
            leaf: true,
            vertices: [
                DVec3::new(10.0, 0.0, 0.0),
                DVec3::new(11.0, 0.0, 0.0),
                DVec3::new(10.0, 1.0, 0.0),
                DVec3::ZERO,
            ],
            n_vertices: 3,
            area: 0.5,
            reflectance: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            radiosity: Rgb::new(b, 0.0, 0.0),
            error_estimate: 0.0,
            stop: "",
        }
    }

    #[test]
    fn mesh_is_local_and_coloured() {
        let els = vec![tri(0, 2.0)];
        let m = mesh(&els, &[0], MeshColors::Flat, DVec3::new(10.0, 0.0, 0.0));
        assert_eq!(m.len(), 3);
        assert_eq!(m[1].position, [1.0, 0.0, 0.0]);
        assert_eq!(m[0].color, [2.0, 0.0, 0.0]);
        let d = [[0.1, 0.2, 0.3]];
        assert_eq!(mesh(&els, &[0], MeshColors::Display(&d), DVec3::ZERO)[2].color, d[0]);
    }
}
