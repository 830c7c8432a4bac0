//! Clusters above the input patches, so that links grow as n instead of n² [Smits, Arvo &
//! Greenberg 1994, "A clustering algorithm for radiosity in complex environments" (SAG94);
//! Sillion 1995, "A unified hierarchical algorithm for global illumination with scattering
//! volumes and object clusters" (S95)].
//!
//! HSA91 starts from a link between every pair of input patches, so a room of n small
//! polygons starts with n² links (a 10 k-patch room: 14.4 M links, 138 s). Here a binary
//! cluster tree is built over the patches (median splits of their centroids, as a BVH), and
//! linking starts from the root's link with itself:
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
//! one cluster link between two of its ancestors. An accepted pair whose transfer is zero both
//! ways ([`carries_nothing`]: coplanar clusters of a floor, clusters facing away from each
//! other) gets no link at all: on the furnished rooms these were 20–42 % of the cluster links. A big patch (a floor) is never split here:
//! its sphere holds the clusters near it, so it links to each of their patches, and element
//! refinement subdivides it as it does today.
//!
//! **Transfer** (SAG94's oriented clusters; the cosine of each member, not S95's isotropic
//! volume): what a cluster s sends in a direction w is I_s(w) = Σ_j A_j B_j max(0, n_j·w). With
//! max(0, x) = (x + |x|)/2 and |n·w| ≈ Σ_k |n_k| |w_k| (exact for axis-aligned normals),
//! ```text
//! I_s(w) ≈ ½ (S·w + T·|w|),   S = Σ_j A_j B_j n_j,   T = Σ_j A_j B_j |n_j|   (per channel)
//! ```
//! kept per cluster and pulled up the tree in O(n). A link r ← s delivers the flux density
//! φ = I_s(−ω) V / (π d² + P_r(ω) + P_s(−ω)) from the direction ω (r's centre towards s's; P the
//! projected areas facing the other end: Wallace's disk regularisation, symmetric so the link
//! stays reciprocal — the point form π d² alone overestimated close facing clusters and made
//! furnished-4k create 1.4 % of its light, see `distance_term` in `transfer`); a patch receiver takes
//! φ max(0, n·ω) at once, a cluster receiver keeps U = Σ φ ω and W = Σ φ |ω|, pushed down the
//! tree and read by each member patch as H = ½ (n·U + |n|·W). Patches' own emission and
//! radiosity B are their root elements' (area averages after push-pull). The irradiance lands
//! on each patch's root element, and push-pull carries it to the leaves.
//!
//! **Visibility** of a cluster link: point pairs on area-weighted member patches of both
//! clusters, only those that face each other, weighted by their two cosines (4 × rays tries
//! at most; when none faces, V = 1: the transfer's cosines already make it small).
//!
//! **Refinement**: after each gather the cluster links are tested again with the new B (as
//! the BF oracle does for element links); a link that fails is replaced by its subdivision.
//!
//! The energy rows (Σ F·V of each patch, for the power balance) are the same transfer with
//! B = 1.
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
