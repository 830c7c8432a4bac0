//! Measured sweeps over the solvers: speed against error, h against p, hard cases.

/// The speed-against-error sweep behind `radlab bench`.
pub mod bench;
/// Generated numerically hard scenes for the stability suite.
pub mod hard_cases;
/// h- against p-refinement measured on exact single-bounce scenes.
pub mod order_study;
