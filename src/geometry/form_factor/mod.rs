//! Form-factor kernels: pure functions of geometry, `f64` inside.
//!
//! The form factor from a receiver i to a source j is the fraction of the power leaving a
//! diffuse i that arrives at j:
//!
//! ```text
//! F_ij = 1/A_i ∫_i ∫_j cosθ_i cosθ_j / (π r²) dA_j dA_i          [Cohen & Wallace 1993, eq. 4.8]
//!      = 1/A_i ∫_i F(x → j) dA_i
//! ```
//!
//! - [`point_to_polygon`]: the inner integral in closed form, Lambert's contour integral
//!   `F(x → j) = 1/(2π) Σ_k β_k n·γ_k`, β_k the angle edge k subtends at x, γ_k the unit normal of
//!   the plane through x and edge k [Cohen & Wallace 1993, eq. 4.17; Baum, Rushmeier, Winget 1989].
//!   Angles by `atan2` (accurate for tiny and near-π angles); the source is first clipped against
//!   the receiver's tangent plane. Exact to rounding. Triangles and quads (every hierarchy
//!   element) take a fixed-size path whose four edge terms are computed side by side in vector
//!   lanes, the same operations in the same order: the same bits, fewer instructions.
//! - [`disk`]: the lecture's disk approximation `F ≈ A cosθ cosθ' / (π r² + A)`.
//! - [`polygon_to_polygon`]: the outer integral by globally adaptive cubature of the exact
//!   kernel (Genz–Malik degree-7 rule with a degree-5 error estimate, bisection along the axis
//!   of largest fourth difference [Genz & Malik 1980; Berntsen, Espelid, Genz 1991]). Near a
//!   shared edge or contact the kernel's derivative is log-singular and the embedded estimate
//!   fails (50× optimistic in tests), so regions near the source are estimated against their
//!   two halves instead; the adaptive split concentrates work there. The receiver is first
//!   clipped to the half-space in front of the source (behind it the one-sided kernel is 0), so
//!   the kernel never jumps inside the domain (a wall standing on a floor at an angle would
//!   otherwise need millions of evaluations).
//! - [`polygon_to_polygon_axial`] / [`polygon_to_polygon_contour`]: the double contour integral
//!   `A_i F_ij = 1/(2π) ∮_i ∮_j ln r dx_i · dx_j` [Sparrow 1963], exact for boxes and rooms,
//!   graded Gauss–Legendre rules for edges at other angles.
//! - [`polygon_to_polygon_fixed`]: cheap fixed n×n Gauss–Legendre rule of the same kernel.
//! - [`polygon_to_polygon_mc`] / [`point_to_polygon_mc`]: Monte Carlo estimates with their
//!   standard error.
//!
//! ## Files
//! - `point`: the point-to-polygon kernel (contour integral, four edge terms at a time) and the
//!   disk approximation.
//! - `pair`: the receiver's pieces mapped from the unit square, and its clip to the half-space in
//!   front of the source.
//! - `adaptive`: Genz–Malik cubature; `region`: the error-ordered region heap it shares with
//!   [`crate::geometry::exact`].
//! - `contour`: the double contour integral (axial pairs in closed form); `oblique`: its edge
//!   pairs at other angles, on a ladder of graded Gauss–Legendre rules.
//! - `gauss`: fixed Gauss–Legendre rules; `monte_carlo`: the Monte Carlo estimates.

mod adaptive;
mod contour;
mod gauss;
mod monte_carlo;
mod oblique;
mod pair;
mod point;
pub(crate) mod region;

pub use adaptive::{MAX_EVALUATIONS, Quadrature, polygon_to_polygon, polygon_to_polygon_adaptive};
pub use contour::{polygon_to_polygon_axial, polygon_to_polygon_contour};
pub use gauss::{gauss_legendre, polygon_to_polygon_fixed, polygon_to_polygon_rule};
pub use monte_carlo::{point_to_polygon_mc, polygon_to_polygon_mc};
pub use point::{disk, point_to_polygon, point_to_polygon_oriented};

/// A point closer than this to the source's plane, relative to its largest distance to a source
/// vertex, counts as lying in the plane: the kernel returns its limit from the front side.
/// (Rounding of the vertex coordinates is ~1e-16 relative; the limit differs from the value at
/// this distance by ~1e-11.)
const IN_PLANE_REL: f64 = 1e-11;
