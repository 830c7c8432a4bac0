//! Refine (HSA91, sec. 4, the lecture's `Refine(p, q, Feps, Aeps)`): apply the oracle to every link
//! and replace the links it rejects by links to the children of the split side, until nothing
//! splits.
//!
//! ```text
//! Refine(p, q):  if Oracle(p, q) accepts            → Link(p, q)
//!                else if F_pq > F_qp and q splits    → for each child c of q: Refine(p, c)
//!                else if p splits                    → for each child c of p: Refine(c, q)
//!                else                                → Link(p, q)
//! ```
//! Each pass: (A, parallel, read-only) a verdict per link; (B, sorted ids) split the chosen
//! elements so ids are deterministic; (C, parallel) the replacement links' coupling
//! ([`super::transfer`]), visibility and verdicts; (D, receiver order) install them. Every
//! decision is symmetric in the pair, so the links q ← p mirror the links p ← q at every level.
//! The oracles themselves are in [`super::oracle`]; the input patches' (and clusters') first
//! links in [`super::linking`].
//!
//! ## Files
//! - `passes`: `refine_step` and its passes A–D;
//! - `decide`: the oracle on one link (phase A), and the thresholds it reads;
//! - `rows`: the row check, which splits the largest links into a leaf whose row exceeds 1;
//! - `replace`: a receiver's replacement links (phase C) and the per-pass memo of split pairs;
//! - `make`: a new link's coupling and visibility, with as few rays as its verdict needs;
//! - `pair`: a pair's link with the oracle's cached estimates, and how the two elements sit;
//! - `verdict`: what a pass decides, and the set of elements it splits.

mod decide;
mod make;
mod pair;
mod passes;
mod replace;
mod rows;
mod verdict;

pub(super) use decide::resolve_bf_eps;
#[cfg(test)]
pub(super) use make::coupling_in;
pub(super) use pair::{nearly_equal, new_link, pair_key, pair_sides};
pub(super) use replace::PairMemo;
pub(super) use verdict::IdSet;
