//! The frames a cluster's cosines are taken in: |n·w| ≈ Σ_k |n_k| |w_k| in the frame that
//! overestimates a link's projected areas least (SAG94's oriented clusters), and whether a
//! link carries nothing either way.
//! ```text
//! I_s(w) ≈ ½ (S·w + T_f·|w|_f),   S = Σ_j A_j B_j n_j,   T_f = Σ_j A_j B_j |n_j|_f
//! ```

use super::tree::ClusterNode;
use crate::math::DVec3;

/// Orthonormal frames (rows: the axes) in which |n·w| ≈ Σ_k |n_k| |w_k| is taken; the
/// smallest of the frames' values is kept (each is an upper bound, exact when n or w lies on
/// one of the frame's axes). The world axes, and the world turned 45° about each axis: a
/// cylinder seen at 45° between two axes is overestimated by 41 % in the world frame alone,
/// exactly right in the frame turned about its axis. Furniture turned on the floor, lamp
/// shades and table legs are what a room holds besides axis-aligned boxes.
pub const FRAMES: [[DVec3; 3]; 4] = {
    const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
    [
        [DVec3::X, DVec3::Y, DVec3::Z],
        [DVec3::X, DVec3::new(0.0, H, H), DVec3::new(0.0, -H, H)],
        [DVec3::new(H, 0.0, -H), DVec3::Y, DVec3::new(H, 0.0, H)],
        [DVec3::new(H, H, 0.0), DVec3::new(-H, H, 0.0), DVec3::Z],
    ]
};

/// |v| componentwise in frame `f`.
#[inline]
pub(super) fn abs_in(f: usize, v: DVec3) -> DVec3 {
    let [a, b, c] = FRAMES[f];
    DVec3::new(a.dot(v).abs(), b.dot(v).abs(), c.dot(v).abs())
}

/// The frame in which the cosines of a link between nodes `a` and `b` along the unit
/// direction `w` are taken: the one whose |·| sums overestimate the two ends' projected areas
/// least (geometry only, so fixed per link). One frame for both ends and both directions keeps
/// the transfer reciprocal: what a sends to b is what b's members gather from a.
#[must_use]
pub fn link_frame(a: &ClusterNode, b: &ClusterNode, w: DVec3) -> u8 {
    let excess = |f: usize| {
        let aw = abs_in(f, w);
        a.area_t[f].dot(aw) + b.area_t[f].dot(aw)
    };
    (1..FRAMES.len()).fold(0, |best, f| if excess(f) < excess(best) { f } else { best }) as u8
}

/// Does a link between nodes `a` and `b` (unit direction `w` from a to b, cosines in frame
/// `f`) transfer nothing either way? Each member's cosine term ½ (n·w + |n|·|w|) is ≥ 0, so a
/// node's projected area towards the other end is 0 only when every member's term is, and then
/// whatever the radiosities, the node neither sends along the link nor receives from it
/// (coplanar clusters of a floor or a wall, clusters facing away from each other). Such a pair
/// needs no link (less than 1e-9 of a node's area counts as 0).
#[must_use]
pub fn carries_nothing(a: &ClusterNode, b: &ClusterNode, w: DVec3, f: u8) -> bool {
    a.projected_area(w, f) <= 1e-9 * a.area || b.projected_area(-w, f) <= 1e-9 * b.area
}
