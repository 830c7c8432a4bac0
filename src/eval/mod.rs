//! The rulers: how far a solution is from the truth, and where.

/// The lecture's five meshing artifacts, one number each, against a reference.
pub mod artifacts;
/// Per-element and per-patch error, L1/L2/L∞, energy balance, rank correlation.
pub mod metrics;
/// The penumbra band of a point set: points that see part of the direct light.
pub mod penumbra;
/// The pointwise ruler: a reconstruction evaluated at the reference's points.
pub mod pointwise;
/// Display reconstructions: each element's own function, Gouraud vertex averages.
pub mod reconstruction;
/// An independent Monte Carlo reference that shares no kernel with the solvers.
pub mod reference;
