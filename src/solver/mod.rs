//! Radiosity solvers and what they all return.
//!
//! ```text
//! B_i = E_i + ρ_i Σ_j F_ij V_ij B_j        [Cohen & Wallace 1993, eq. 2.3]
//! ```
//!
//! - [`uniform`]: every patch meshed to a target element size, full form-factor matrix
//!   (quadrature + visibility, reciprocity), Gauss–Seidel.
//! - [`progressive`]: Southwell shooting of unshot power [Cohen et al. 1988], ambient term for display.
//! - [`hierarchical`]: HSA91 — quadtree, Refine (Feps/Aeps or BF oracle), Gather, push-pull.
//! - [`discontinuity`]: the uniform solver at p = 0 on a discontinuity mesh ([`crate::mesh`]),
//!   reported on the input scene's patches.
//! - [`linear`]: Galerkin radiosity with p = 0 or p = 1 elements (linear / bilinear),
//!   discontinuous or continuous, mass matrix on the left [Zatz 1993; Troutman & Max 1993].
//! - [`escape`]: where the power no front face gathers goes (back faces, out of the scene, the
//!   rows' shortfall), and whether the scene is closed.
//! - [`meshed`]: one entry for the uniform and discontinuity meshes at p = 0 or 1 (the viewer's
//!   mesh choice), with the display reconstructions' names.
//!
//! Every solver returns a [`Solution`]: leaf elements with geometry and radiosity, per-patch
//! area-weighted radiosity, the energy balance and statistics. The CLI's JSON, the PNG renderer,
//! the error metrics and the viewer read only this type.

pub mod discontinuity;
pub mod escape;
pub mod hierarchical;
pub mod hierarchy;
pub mod linear;
pub mod link;
pub mod meshed;
/// The hierarchical solver's own error estimate (kept at its old path).
pub use hierarchical::estimate;
pub mod params;
pub mod progressive;
pub mod spec;
pub mod uniform;

use crate::math::{DVec3, Rgb};
use serde::Serialize;

/// A linear variation of an element's radiosity across it: B(x) = B + Σ_axis d_axis (x − centroid)_axis
/// (world axes x, y, z; B the element's average, which an affine function takes at the area
/// centroid). The hierarchical solver gives its leaves the slope of the irradiance it pushed down
/// (`solver::hierarchical`, push-pull), times ρ.
#[derive(Copy, Clone, Debug, Serialize)]
pub struct Slope {
    pub centroid: DVec3,
    pub d: [Rgb; 3],
}

impl Slope {
    /// B at `x`, for the element average `b`; never below 0 per channel.
    #[must_use]
    pub fn at(&self, b: Rgb, x: DVec3) -> Rgb {
        let r = x - self.centroid;
        (b + self.d[0] * r.x + self.d[1] * r.y + self.d[2] * r.z).map(|v| v.max(0.0))
    }
}

/// One leaf element of a solution.
#[derive(Clone, Debug, Serialize)]
pub struct SolvedElement {
    /// Index of the input patch this element lies on.
    pub patch: usize,
    /// 3 or 4 vertices, same orientation as the patch.
    pub vertices: Vec<DVec3>,
    pub area: f64,
    /// Radiosity B (emitted + reflected exitance).
    pub radiosity: Rgb,
    /// The solver's own a-posteriori estimate of this element's error in B (same unit as B,
    /// scalar over channels), where the solver has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_estimate: Option<f64>,
    /// How B varies across the element (its reconstruction is linear where a solver gives one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slope: Option<Slope>,
}

impl SolvedElement {
    /// An element with one radiosity across it: no error estimate, no slope.
    #[must_use]
    pub fn constant(patch: usize, vertices: Vec<DVec3>, area: f64, radiosity: Rgb) -> SolvedElement {
        SolvedElement { patch, vertices, area, radiosity, error_estimate: None, slope: None }
    }

    /// Every patch of `scene` one constant element, patch `i` with B = `radiosity(i)`: a
    /// solution's shape without a solve (to test what reads solutions).
    pub fn whole_patches(
        scene: &crate::scene::Scene,
        radiosity: impl Fn(usize) -> Rgb,
    ) -> Vec<SolvedElement> {
        let patches = scene.patches.iter().enumerate();
        patches.map(|(i, p)| SolvedElement::constant(i, p.vertices.clone(), p.area, radiosity(i))).collect()
    }

    /// B at `x` on the element: its average with its slope where it has one, the one
    /// reconstruction that the viewer draws, the bake and the image write and the rulers score.
    #[must_use]
    pub fn radiosity_at(&self, x: DVec3) -> Rgb {
        self.slope.map_or(self.radiosity, |s| s.at(self.radiosity, x))
    }

    /// B at each vertex, in vertex order: with a slope, the coefficients of the element's linear
    /// function (linear on a triangle, bilinear on a quad, which reproduces a linear function on a
    /// parallelogram); without, its constant at every vertex.
    #[must_use]
    pub fn corner_values(&self) -> Vec<Rgb> {
        self.vertices.iter().map(|&v| self.radiosity_at(v)).collect()
    }
}

/// Power balance of a solution, per channel: at convergence `emitted = absorbed + escaped`.
/// `absorbed` = Σ A (1−ρ) H (H the gathered irradiance); `escaped` = Σ A B (1 − Σ_j F V),
/// the part of the leaving power that no front face gathers: what back faces absorb, what
/// leaves the scene and what the rows of F·V fall short of the hemisphere, which
/// [`escape::split`] tells apart. Both are computed from the solver's own quantities, so the
/// balance is a real check, not an identity.
#[derive(Copy, Clone, Debug, Default, Serialize)]
pub struct EnergyBalance {
    pub emitted: Rgb,
    pub absorbed: Rgb,
    pub escaped: Rgb,
}

impl EnergyBalance {
    /// |emitted − absorbed − escaped| / emitted, worst channel (0 for a dark scene).
    #[must_use]
    pub fn relative_residual(&self) -> f64 {
        (0..3)
            .map(|c| {
                let e = self.emitted.0[c];
                if e > 0.0 { (e - self.absorbed.0[c] - self.escaped.0[c]).abs() / e } else { 0.0 }
            })
            .fold(0.0, f64::max)
    }
}

/// Wall time per phase, seconds.
#[derive(Copy, Clone, Debug, Default, Serialize)]
pub struct PhaseTimes {
    pub load: f64,
    pub bvh: f64,
    pub form_factors: f64,
    pub solve: f64,
    pub total: f64,
}

impl PhaseTimes {
    /// A solver's own two phases (load and BVH are the caller's): form factors, then the solve.
    #[must_use]
    pub fn of_solve(form_factors: f64, solve: f64) -> PhaseTimes {
        PhaseTimes { form_factors, solve, total: form_factors + solve, ..PhaseTimes::default() }
    }
}

/// Statistics common to every solver (the hierarchical solver adds its own in `extra`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SolveStats {
    pub patches: usize,
    pub elements: usize,
    /// Form-factor matrix entries (uniform), shots (progressive) or links (hierarchical).
    pub links: usize,
    pub iterations: usize,
    pub rays: u64,
    pub time_s: PhaseTimes,
    /// Solver-specific statistics (hierarchical: leaves, depth histogram, links by visibility…).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extra: Option<serde_json::Value>,
}

/// What every solver returns.
#[derive(Clone, Debug, Serialize)]
pub struct Solution {
    pub method: String,
    pub elements: Vec<SolvedElement>,
    /// Area-weighted average radiosity of each input patch's elements, in patch order.
    pub patch_radiosity: Vec<Rgb>,
    pub energy: EnergyBalance,
    pub stats: SolveStats,
}

impl Solution {
    /// A solution made of `elements` on a scene of `n_patches` patches, with their per-patch
    /// averages and no energy balance or statistics.
    #[must_use]
    pub fn of_elements(
        method: impl Into<String>,
        n_patches: usize,
        elements: Vec<SolvedElement>,
    ) -> Solution {
        Solution {
            method: method.into(),
            patch_radiosity: Solution::patch_averages(n_patches, &elements),
            elements,
            energy: EnergyBalance::default(),
            stats: SolveStats::default(),
        }
    }

    /// Area-weighted per-patch averages of the elements' radiosity.
    #[must_use]
    pub fn patch_averages(n_patches: usize, elements: &[SolvedElement]) -> Vec<Rgb> {
        let mut sum = vec![Rgb::ZERO; n_patches];
        let mut area = vec![0.0; n_patches];
        for e in elements {
            sum[e.patch] += e.radiosity * e.area;
            area[e.patch] += e.area;
        }
        sum.iter().zip(&area).map(|(s, a)| if *a > 0.0 { *s / *a } else { Rgb::ZERO }).collect()
    }

    /// True if every radiosity value is finite and non-negative.
    #[must_use]
    pub fn is_physical(&self) -> bool {
        self.elements.iter().all(|e| e.radiosity.is_finite() && e.radiosity.min_channel() >= 0.0)
    }
}

/// Progress reporting for long work: `(done, total)` in solver-defined units. The CLI turns it
/// into an indicatif bar; the viewer into a progress bar; tests pass `&mut |_, _| {}`.
pub type Progress<'a> = &'a mut (dyn FnMut(u64, u64) + Send);
