//! Geometry below the solvers: form-factor kernels, exact integrals, the BVH, visibility and
//! the element basis. Needs only `math` and `scene`.

/// The BVH over the input polygons and its shadow rays.
pub mod accel;
/// The area-uniform map from the unit square onto a triangle or convex quad.
pub mod area_map;
/// Element basis functions (p = 0, p = 1) and quadrature on an element.
pub mod basis;
/// Exact single-bounce radiosity: a closed-form ruler with no reference noise.
pub mod exact;
/// Form-factor kernels: point→polygon (Lambert), disk, quadrature, Monte Carlo.
pub mod form_factor;
/// The fraction of the direct light a point sees (umbra, penumbra, fully lit).
pub mod lit;
/// Visible fraction between two regions from seeded, stratified rays.
pub mod visibility;
