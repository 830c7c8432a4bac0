//! Turns the viewer's element lists (see [`crate::present::overlay`]) into GPU vertex arrays in the
//! scene's local frame (world minus `origin`, then `f32`), so scenes far from the origin keep
//! their precision on the GPU.
//!
//! The mesh is *conforming*: a leaf with T-vertices on its edges (corners of finer neighbours,
//! [`VertexField::boundary`]) is drawn as a fan around its centre through all of them, so the
//! rasteriser sees the same shared edges from both sides and no background shows through at
//! T-junctions. A leaf without T-vertices stays two triangles (quads) or one.
//!
//! ```text
//!  ┌──────────┬────┐        ┌──────────●────┐   ● T-vertex on the big leaf's edge
//!  │          │    │        │ ╲      ╱ │    │   the big leaf: a fan around its centre
//!  │   big    ├────┤   →    │   ╲  ╱   ●────┤   through its corners and T-vertices
//!  │          │    │        │    ╱╲    │    │
//!  └──────────┴────┘        └──────────┴────┘
//! ```
//!
//! Each vertex also carries its position in its leaf's parameter square (`uv`) and the leaf's
//! quadtree-depth colour, from which `mesh.wgsl` draws the quadtree overlay and the picked
//! element's outline without any line geometry.

use super::gpu_data::{LineVertex, MeshVertex};
use crate::math::{DVec3, Rgb};
use crate::present::overlay::{BoundaryPoint, ElementView, LineList, VertexField, depth_color};

/// How the mesh is coloured.
#[derive(Copy, Clone, Debug)]
pub enum MeshColors<'a> {
    /// Each element's radiosity at all its corners.
    Flat,
    /// Gouraud: vertex averages with T-vertices anchored ([`VertexField`]).
    Smooth,
    /// A display colour per element id (error heatmap); the shader's mode must be 1.
    Display(&'a [[f32; 3]]),
    /// Each element's own p = 1 function: its vertex values (indexed like `elements`, in vertex
    /// order; one value: constant) interpolated with its basis ([`crate::geometry::basis`]) at every
    /// boundary point, so T-vertices take the element's own value there.
    Nodal(&'a [Vec<Rgb>]),
}

/// An indexed triangle list.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<MeshVertex>,
    /// Three indices per triangle, into `vertices`.
    pub indices: Vec<u32>,
}

impl Mesh {
    #[must_use]
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

fn local(p: DVec3, origin: DVec3) -> [f32; 3] {
    let q = p - origin;
    [q.x as f32, q.y as f32, q.z as f32]
}

fn rgb(c: Rgb) -> [f32; 3] {
    [c.0[0] as f32, c.0[1] as f32, c.0[2] as f32]
}

/// The depth colour as unorm8, alpha marking quads (255) and triangles (0) for the shader.
fn line_rgba8(c: [f32; 3], quad: bool) -> [u8; 4] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c[0]), q(c[1]), q(c[2]), if quad { 255 } else { 0 }]
}

/// Conforming triangle mesh of the leaves (indices into `elements`).
#[must_use]
pub fn mesh(elements: &[ElementView], leaves: &[u32], colors: MeshColors<'_>, origin: DVec3) -> Mesh {
    let field = VertexField::build(elements, leaves);
    let mut out = Mesh {
        vertices: Vec::with_capacity(leaves.len() * 4 + leaves.len() / 2),
        indices: Vec::with_capacity(leaves.len() * 6 + leaves.len() / 2),
    };
    for &l in leaves {
        let e = &elements[l as usize];
        let quad = e.n_vertices == 4;
        let boundary = field.boundary(e);
        let element_color = match colors {
            MeshColors::Flat | MeshColors::Smooth | MeshColors::Nodal(_) => rgb(e.radiosity),
            MeshColors::Display(c) => c.get(l as usize).copied().unwrap_or([0.0; 3]),
        };
        let line_color = line_rgba8(depth_color(e.depth), quad);
        let base = out.vertices.len() as u32;
        let mut push = |p: &BoundaryPoint| {
            let color = match colors {
                MeshColors::Smooth => rgb(p.value),
                MeshColors::Nodal(c) => {
                    c.get(l as usize).map_or(element_color, |c| rgb(nodal_value(c, quad, p.uv)))
                }
                MeshColors::Flat | MeshColors::Display(_) => element_color,
            };
            out.vertices.push(MeshVertex {
                position: local(p.position, origin),
                element: e.id,
                color,
                uv: [p.uv[0] as f32, p.uv[1] as f32],
                line_color,
            });
        };
        boundary.iter().for_each(&mut push);
        let n = boundary.len() as u32;
        if n == u32::from(e.n_vertices) {
            let tris: &[[u32; 3]] = if quad { &[[0, 1, 2], [0, 2, 3]] } else { &[[0, 1, 2]] };
            for t in tris {
                out.indices.extend(t.iter().map(|i| base + i));
            }
        } else {
            // A fan around the centre through every boundary point.
            let corners: Vec<&BoundaryPoint> =
                boundary.iter().filter(|p| p.uv.iter().all(|c| *c == 0.0 || *c == 1.0)).collect();
            let k = corners.len().max(1) as f64;
            let centre = BoundaryPoint {
                position: corners.iter().map(|p| p.position).sum::<DVec3>() / k,
                uv: if quad { [0.5, 0.5] } else { [1.0 / 3.0, 1.0 / 3.0] },
                value: corners.iter().fold(Rgb::ZERO, |acc, p| acc + p.value) / k,
            };
            push(&centre);
            let c = base + n;
            for i in 0..n {
                out.indices.extend([c, base + i, base + (i + 1) % n]);
            }
        }
    }
    out
}

/// An element's p = 1 function at a point of its parameter square (`uv` as
/// [`BoundaryPoint::uv`]): the vertex values weighted by the basis; one value is a constant.
fn nodal_value(coefficients: &[Rgb], quad: bool, uv: [f64; 2]) -> Rgb {
    use crate::geometry::basis::{Local, Order, values};
    let n = if quad { 4 } else { 3 };
    if coefficients.len() != n {
        return coefficients.first().copied().unwrap_or(Rgb::ZERO);
    }
    let phi = values(Order::Linear, n, Local(uv[0], uv[1]));
    coefficients.iter().zip(phi).map(|(c, w)| *c * w).sum()
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

    fn quad(id: u32, depth: u8, x0: f64, y0: f64, s: f64, b: f64) -> ElementView {
        crate::present::overlay::test_support::quad_rgb(id, depth, x0, y0, s, Rgb::new(b, 0.0, 0.0))
    }

    #[test]
    fn mesh_is_local_indexed_and_coloured() {
        let mut t = quad(0, 0, 10.0, 0.0, 1.0, 2.0);
        t.n_vertices = 3;
        let els = vec![t];
        let m = mesh(&els, &[0], MeshColors::Flat, DVec3::new(10.0, 0.0, 0.0));
        assert_eq!((m.vertices.len(), m.indices.len()), (3, 3));
        assert_eq!(m.vertices[1].position, [1.0, 0.0, 0.0]);
        assert_eq!(m.vertices[0].color, [2.0, 0.0, 0.0]);
        assert_eq!(m.vertices[2].uv, [0.0, 1.0], "third corner of a triangle");
        assert_eq!(m.vertices[2].line_color[3], 0, "marked as a triangle");
        let d = [[0.1, 0.2, 0.3]];
        assert_eq!(mesh(&els, &[0], MeshColors::Display(&d), DVec3::ZERO).vertices[2].color, d[0]);
    }

    #[test]
    fn nodal_colours_are_the_elements_own_vertex_values() {
        let els = vec![quad(0, 0, 0.0, 0.0, 1.0, 2.0)];
        let values: Vec<Vec<Rgb>> = vec![(1..=4).map(|k| Rgb::splat(f64::from(k))).collect()];
        let m = mesh(&els, &[0], MeshColors::Nodal(&values), DVec3::ZERO);
        let colours: Vec<f32> = m.vertices.iter().map(|v| v.color[0]).collect();
        assert_eq!(colours, [1.0, 2.0, 3.0, 4.0], "each corner its own value, not the average 2");
        // One value: a constant element.
        let m = mesh(&els, &[0], MeshColors::Nodal(&[vec![Rgb::splat(5.0)]]), DVec3::ZERO);
        assert!(m.vertices.iter().all(|v| v.color == [5.0; 3]));
        // Inside: bilinear.
        assert_eq!(nodal_value(&values[0], true, [0.5, 0.5]), Rgb::splat(2.5));
    }

    #[test]
    fn t_junctions_become_fans_through_the_t_vertex() {
        // Big 2×2 square (depth 1) next to two unit squares (depth 2): (2,1) is a T-vertex.
        let els = crate::present::overlay::test_support::t_junction();
        let m = mesh(&els, &[0, 1, 2], MeshColors::Smooth, DVec3::ZERO);
        // Big leaf: 5 boundary points + centre, 5 fan triangles; the small ones: 4 + 2 each.
        assert_eq!(m.vertices.len(), 6 + 4 + 4);
        assert_eq!(m.triangles(), 5 + 2 + 2);
        let t = m.vertices.iter().position(|v| v.position == [2.0, 1.0, 0.0]).unwrap();
        assert!(m.indices.chunks(3).filter(|tri| tri.contains(&(t as u32))).count() >= 2);
        // The T-vertex takes the big edge's interpolated value in the big leaf too: (5 + 7) / 2.
        assert!((m.vertices[t].color[0] - 6.0).abs() < 1e-6, "{:?}", m.vertices[t].color);
        // Its parameter lies on the big leaf's boundary (u = 1).
        assert_eq!(m.vertices[t].uv, [1.0, 0.5]);
        assert_eq!(m.vertices[0].line_color, line_rgba8(depth_color(1), true));
    }
}
