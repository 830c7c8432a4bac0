//! Clusters above the input patches, so that links grow as n instead of n² [Smits, Arvo &
//! Greenberg 1994, "A clustering algorithm for radiosity in complex environments" (SAG94);
//! Sillion 1995, "A unified hierarchical algorithm for global illumination with scattering
//! volumes and object clusters" (S95)].
//!
//! HSA91 starts from a link between every pair of input patches, n² links for a room of n small
//! polygons. Here a binary cluster tree is built over the patches (median splits of their
//! centroids, as a BVH), and linking starts from the root's link with itself:
//! ```text
//! Link(a, b):  a = b            → Link(a₀, a₀), Link(a₀, a₁), Link(a₁, a₁)   (a cluster sees itself)
//!              a, b patches     → the patch pair's element links (HSA91 from there on)
//!              accept(a, b)     → one cluster link a ↔ b
//!              else             → split the larger cluster (never a patch): Link(kᵢ, other)
//! accept(a, b): the bounding spheres are apart (gap g = d − r_a − r_b > 0) and
//!              max(ρ_a B_b F_ab, ρ_b B_a F_ba) · min(1, 2 (r_a + r_b) / d) < BFeps,
//!              F_ab = min(1, A_b / (π g²))       (the BF oracle's form, SPLASH-2's criterion)
//! ```
//! Every pair of distinct patches is covered exactly once: by its own element links or by the
//! one cluster link between two of its ancestors. A pair whose transfer is zero both ways
//! ([`carries_nothing`]: coplanar, or facing away) gets no link. A big patch (a floor) is never
//! split here; element refinement subdivides it.
//!
//! **Transfer** (SAG94's oriented clusters, not S95's isotropic volume): with max(0, x) =
//! (x + |x|)/2 and |n·w| ≈ Σ_k |n_k| |w_k| (exact for axis-aligned normals), what a cluster s
//! sends in a direction w is
//! ```text
//! I_s(w) = Σ_j A_j B_j max(0, n_j·w) ≈ ½ (S·w + T·|w|),   S = Σ_j A_j B_j n_j,   T = Σ_j A_j B_j |n_j|
//! φ_{r←s} = I_s(−ω) V / (π d² + P_r(ω) + P_s(−ω))
//! ```
//! S and T are pulled up the tree in O(n). The distance term adds the two ends' projected areas
//! (Wallace's disk regularisation, symmetric so the link stays reciprocal): π d² alone
//! overestimates close facing clusters and a furnished room creates light. A patch receiver takes
//! φ max(0, n·ω); a cluster receiver keeps U = Σ φ ω and W = Σ φ |ω|, pushed down the tree and
//! read by each member as H = ½ (n·U + |n|·W), landing on the patch's root element for
//! push-pull. A cluster link's visibility is sampled between facing points of area-weighted
//! members; after each gather the links are tested again and a failing one is subdivided. The
//! energy rows are the same transfer with B = 1. Measurements: docs/scale.md.
//!
//! ## Files
//! - `tree`: the cluster tree, its nodes' bounds and moments, a cluster link's visibility;
//! - `pairing`: `Link(a, b)` over the tree, whole or a batch at a time;
//! - `frames`: the frames the cosines are taken in, and the links that carry nothing;
//! - `transfer`: the transfer through the cluster links (pull, gather, push);
//! - `slope`: a patch's slope of what its own cluster links deliver;
//! - `bound`: the row bound by what each patch's hemisphere sees.

mod bound;
mod frames;
mod pairing;
mod slope;
mod transfer;
mod tree;

pub use bound::{BOUND_RAYS, BOUND_RAYS_MORE, RowBound, covers, hemisphere_bound};
pub use frames::{FRAMES, carries_nothing, link_frame};
pub use pairing::{ClusterLink, Pairing};
pub use transfer::ClusterTransfer;
pub use tree::{ClusterNode, ClusterTree, LEAF};

#[cfg(test)]
mod tests;
