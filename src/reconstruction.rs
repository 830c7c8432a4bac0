//! Display reconstructions of a solution, each a [`Reconstruction`] the pointwise ruler
//! ([`crate::pointwise`]) can score:
//!
//! - **flat**: [`crate::pointwise::PiecewiseConstant`], each element's value;
//! - **Gouraud from vertex averages** ([`gouraud`] + [`Nodal`]): every mesh vertex of a patch
//!   takes the area-weighted average of the elements around it, and each element interpolates
//!   its vertices' values with its p = 1 basis (linear on triangles, bilinear on quads) — what
//!   most radiosity systems display [Cohen & Wallace 1993, §9.2];
//! - **the element's own p = 1 function** ([`Nodal`] of a
//!   [`crate::solver::linear::LinearSolution`]'s coefficients): what a Galerkin p = 1 solve
//!   computed, discontinuous across element edges when the basis is.
//!
//! ```text
//! B(x) = Σ_k c_k φ_k(local(x))        on the element e of x's patch that contains x
//! ```
//!
//! [`crate::artifacts::Gouraud`] (the Mach-band measure's reconstruction) is this one.
//!
//! T-vertices: a vertex of one element lying inside another's edge is averaged like any other,
//! but the element with the long edge does not interpolate it, so a non-conforming mesh (the
//! hierarchical quadtree) shows cracks; the uniform mesh of a patch and the CDT are conforming.

use crate::basis::{self, Order};
use crate::math::{DVec3, Rgb};
use crate::metrics::MetricsError;
use crate::pointwise::{PiecewiseConstant, Reconstruction};
use crate::scene::Scene;
use crate::solver::SolvedElement;
use std::collections::HashMap;

/// Each element's coefficients evaluated with its basis: one value → constant, one per vertex →
/// linear / bilinear. Points are located like [`PiecewiseConstant`]'s.
pub struct Nodal<'a> {
    flat: PiecewiseConstant<'a>,
    elements: &'a [SolvedElement],
    coefficients: Vec<Vec<Rgb>>,
}

impl<'a> Nodal<'a> {
    /// Errors if an element names a patch the scene lacks, or the coefficients do not match the
    /// elements (one list per element, of 1 or vertex-count values).
    pub fn new(
        scene: &'a Scene,
        elements: &'a [SolvedElement],
        coefficients: Vec<Vec<Rgb>>,
    ) -> Result<Self, MetricsError> {
        if coefficients.len() != elements.len() {
            return Err(MetricsError::LengthMismatch {
                solution: coefficients.len(),
                reference: elements.len(),
            });
        }
        if let Some((i, _)) = elements
            .iter()
            .zip(&coefficients)
            .enumerate()
            .find(|(_, (e, c))| c.len() != 1 && c.len() != e.vertices.len())
        {
            return Err(MetricsError::LengthMismatch {
                solution: coefficients[i].len(),
                reference: elements[i].vertices.len(),
            });
        }
        Ok(Nodal { flat: PiecewiseConstant::new(scene, elements)?, elements, coefficients })
    }
}

impl Reconstruction for Nodal<'_> {
    fn radiosity_at(&self, patch: usize, x: DVec3) -> Rgb {
        let Some(i) = self.flat.element_at(patch, x) else {
            return self.flat.radiosity_at(patch, x);
        };
        let (verts, coef) = (&self.elements[i].vertices, &self.coefficients[i]);
        if coef.len() == 1 {
            return coef[0];
        }
        if coef.len() > basis::MAX_FUNCTIONS {
            // A polygon of more than 4 vertices has no p = 1 basis here: its average.
            return self.elements[i].radiosity;
        }
        let phi = basis::values(Order::Linear, verts.len(), basis::local_coordinates(verts, x));
        coef.iter().zip(phi).map(|(c, p)| *c * p).sum()
    }
}

/// Gouraud coefficients of a solution's elements: per element, per vertex, the area-weighted
/// average of the values of the elements of the same patch that share that vertex (vertices
/// welded within 10⁻⁹ of the scene's diagonal; a T-junction's vertex is not shared by the long
/// edge).
#[must_use]
pub fn gouraud(scene: &Scene, elements: &[SolvedElement]) -> Vec<Vec<Rgb>> {
    let quantum = 1e-9 * scene.bounds().diagonal().max(f64::MIN_POSITIVE);
    let key = |patch: usize, v: DVec3| {
        let q = (v / quantum).round();
        (patch, [q.x as i64, q.y as i64, q.z as i64])
    };
    let mut sums: HashMap<(usize, [i64; 3]), (Rgb, f64)> = HashMap::new();
    for e in elements {
        for v in &e.vertices {
            let s = sums.entry(key(e.patch, *v)).or_insert((Rgb::ZERO, 0.0));
            s.0 += e.radiosity * e.area;
            s.1 += e.area;
        }
    }
    elements
        .iter()
        .map(|e| {
            e.vertices
                .iter()
                .map(|v| {
                    let (s, a) = sums[&key(e.patch, *v)];
                    if a > 0.0 { s / a } else { e.radiosity }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Patch;

    #[test]
    fn gouraud_averages_shared_vertices_and_nodal_interpolates() {
        let v = |x: f64, z: f64| DVec3::new(x, 0.0, z);
        let patch = Patch::new(
            vec![v(0., 0.), v(0., 1.), v(2., 1.), v(2., 0.)],
            Rgb::splat(0.5),
            Rgb::ZERO,
            "floor",
            0,
            "floor",
            "m",
        )
        .unwrap();
        let scene = Scene::new("two", "test", vec![patch]);
        let el = |verts: Vec<DVec3>, b: f64| SolvedElement {
            patch: 0,
            area: 1.0,
            vertices: verts,
            radiosity: Rgb::splat(b),
            error_estimate: None,
            slope: None,
        };
        let elements = vec![
            el(vec![v(0., 0.), v(0., 1.), v(1., 1.), v(1., 0.)], 1.0),
            el(vec![v(1., 0.), v(1., 1.), v(2., 1.), v(2., 0.)], 3.0),
        ];
        let coef = gouraud(&scene, &elements);
        assert_eq!(coef[0][2], Rgb::splat(2.0), "shared vertex: the average");
        assert_eq!(coef[0][0], Rgb::splat(1.0), "own vertex: the element's value");
        let nodal = Nodal::new(&scene, &elements, coef).unwrap();
        // Continuous across the shared edge, linear in x.
        let at = |x: f64| nodal.radiosity_at(0, v(x, 0.5)).g();
        assert!((at(1.0 - 1e-9) - 2.0).abs() < 1e-6 && (at(1.0 + 1e-9) - 2.0).abs() < 1e-6);
        assert!((at(0.5) - 1.5).abs() < 1e-12 && (at(1.5) - 2.5).abs() < 1e-12);
    }
}
