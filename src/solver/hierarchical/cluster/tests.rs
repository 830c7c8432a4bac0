//! The cluster tree's linking, frames, transfer and row bound on small scenes of cubes and
//! grids.

use super::*;
use crate::geometry::accel::Accel;
use crate::geometry::form_factor;
use crate::math::{DVec3, Rgb};
use crate::scene::{Patch, Scene};
use crate::solver::hierarchy::Hierarchy;

/// The six outward faces of a cube of side `s` at `c`, turned by `yaw` radians about y.
fn cube(c: DVec3, s: f64, yaw: f64) -> Vec<Patch> {
    let rot = glam::DQuat::from_rotation_y(yaw);
    let h = s / 2.0;
    let mut out = Vec::new();
    for n in [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z] {
        let t1 = if n.x.abs() > 0.5 { DVec3::Y } else { DVec3::X };
        let t2 = n.cross(t1);
        let v = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(a, b)| c + rot * ((n + t1 * a + t2 * b) * h))
            .to_vec();
        out.push(Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "cube", 0, "face", "m").expect("valid face"));
    }
    out
}

fn hierarchy(patches: Vec<Patch>) -> Hierarchy {
    Hierarchy::from_scene(&Scene::new("t", "test", patches))
}

/// Every member patch of a node.
fn members(t: &ClusterTree, node: u32) -> Vec<u32> {
    let n = &t.nodes[node as usize];
    t.order[n.lo as usize..n.hi as usize].to_vec()
}

/// Four cubes in a row and a turned one (30 patches), and their tree.
fn cubes_in_a_row() -> (Hierarchy, ClusterTree) {
    let mut patches = Vec::new();
    for k in 0..4 {
        patches.extend(cube(DVec3::new(3.0 * f64::from(k), 0.0, 0.0), 1.0, 0.0));
    }
    patches.extend(cube(DVec3::new(0.0, 5.0, 2.0), 2.0, 0.3));
    let hier = hierarchy(patches);
    let tree = ClusterTree::build(&hier);
    (hier, tree)
}

#[test]
fn linking_covers_every_pair_of_patches_exactly_once() {
    // Cubes in a row and a turned one: 30 patches; an arbitrary (but deterministic) accept.
    let (hier, tree) = cubes_in_a_row();
    assert_eq!(tree.len(), 2 * hier.roots - 1, "a binary tree down to single patches");
    let mut pairs = Vec::new();
    tree.link(0, 0, &|a, b| (a + b) % 3 == 0, &mut pairs);
    let n = hier.roots;
    let mut count = vec![0u32; n * n];
    let mut clusters = 0;
    for pair in &pairs {
        let (xs, ys) = match *pair {
            Pairing::Cluster(a, b) => {
                clusters += 1;
                assert!(!(tree.nodes[a as usize].is_leaf() && tree.nodes[b as usize].is_leaf()));
                (members(&tree, a), members(&tree, b))
            }
            Pairing::Patches(p, q) => {
                assert!(p < q, "patch pairs ascending");
                (vec![p], vec![q])
            }
        };
        for &x in &xs {
            for &y in &ys {
                count[x.min(y) as usize * n + x.max(y) as usize] += 1;
            }
        }
    }
    assert!(clusters > 0, "the test accepts some cluster links");
    for p in 0..n {
        for q in p + 1..n {
            assert_eq!(count[p * n + q], 1, "pair ({p}, {q}) covered {} times", count[p * n + q]);
        }
        assert_eq!(count[p * n + p], 0, "patch {p} linked to itself");
    }
}

#[test]
fn batched_linking_gives_the_same_pairings_in_the_same_order() {
    // 30 patches linked in batches of pairs of at most 4 members: the batches put together
    // are `link`'s list, pairing for pairing.
    let (_, tree) = cubes_in_a_row();
    let accept = |a: u32, b: u32| (a + b).is_multiple_of(3);
    let mut whole = Vec::new();
    tree.link(0, 0, &accept, &mut whole);
    for batch_members in [1, 4, 7, 1024] {
        let mut batches = Vec::new();
        tree.link_batched_in(0, 0, &accept, batch_members, &mut |p| batches.push(p.to_vec()));
        assert_eq!(batches.concat(), whole, "batches of {batch_members}");
        if batch_members == 1024 {
            assert_eq!(batches.len(), 1, "30 patches are one batch");
        } else {
            assert!(batches.len() > 1, "batches of {batch_members}: {}", batches.len());
        }
    }
}

#[test]
fn frames_make_boxes_and_turned_boxes_exact() {
    // Cubes turned 45° about y, not at all, and 0.3 rad, each linked to a far cube turned
    // alike: seen in several directions, the frame the link takes gives the exact
    // projected area of the first two (Σ A max(0, n·w)), and for the third at most the
    // world frame's overestimate.
    for (yaw, exact_expected) in [(std::f64::consts::FRAC_PI_4, true), (0.0, true), (0.3, false)] {
        let mut patches = cube(DVec3::ZERO, 1.0, yaw);
        patches.extend(cube(DVec3::new(0.0, 0.0, 100.0), 1.0, yaw));
        let hier = hierarchy(patches.clone());
        let tree = ClusterTree::build(&hier);
        // The root's two children: the two cubes (split along z, the longest extent).
        let [k0, k1] = tree.nodes[0].kids;
        let (near, other) = if tree.nodes[k0 as usize].center.z < 50.0 { (k0, k1) } else { (k1, k0) };
        let near_node = &tree.nodes[near as usize];
        for w in [
            DVec3::X,
            DVec3::new(1.0, 0.0, 1.0).normalize(),
            DVec3::new(1.0, 1.0, 0.0).normalize(),
            DVec3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            let exact: f64 = patches[..6].iter().map(|p| p.area * p.normal.dot(w).max(0.0)).sum();
            let f = link_frame(near_node, &tree.nodes[other as usize], w);
            let approx = near_node.projected_area(w, f);
            assert!(approx >= exact * (1.0 - 1e-12), "yaw {yaw}, w {w}: {approx} < exact {exact}");
            if exact_expected {
                assert!((approx - exact).abs() <= 1e-12 * exact, "yaw {yaw}, w {w}: {approx} vs {exact}");
            } else {
                let world = near_node.projected_area(w, 0);
                assert!(
                    approx <= world * (1.0 + 1e-12),
                    "yaw {yaw}, w {w}: frame {f} worse than the world's"
                );
            }
        }
    }
}

/// Two clusters of cubes; one cluster link between them.
fn two_clusters(distance: f64) -> (Hierarchy, ClusterTree, Vec<ClusterLink>, u32, u32) {
    let mut patches = Vec::new();
    patches.extend(cube(DVec3::ZERO, 1.0, 0.0));
    patches.extend(cube(DVec3::new(1.5, 0.2, 0.0), 0.7, 0.4));
    patches.extend(cube(DVec3::new(0.3, 0.0, distance), 1.2, 0.9));
    patches.extend(cube(DVec3::new(-1.0, 0.5, distance + 0.2), 0.5, 0.0));
    let hier = hierarchy(patches);
    let tree = ClusterTree::build(&hier);
    let [a, b] = tree.nodes[0].kids;
    let w = (tree.nodes[b as usize].center - tree.nodes[a as usize].center).normalize();
    let frame = link_frame(&tree.nodes[a as usize], &tree.nodes[b as usize], w);
    (hier, tree, vec![ClusterLink { a, b, vis: 0.8, frame }], a, b)
}

#[test]
fn a_cluster_link_delivers_what_its_source_sends() {
    // Power gathered by a's members with b's radiosities B equals Σ_b A_j B_j F_j→a, where
    // F_j→a is b's members' row through the link (the transfer with B = 1 on a): the link
    // is reciprocal, so the power balance closes.
    let (hier, tree, links, a, b) = two_clusters(8.0);
    let in_a = members(&tree, a);
    let in_b = members(&tree, b);
    let bs = |p: u32| Rgb::new(0.1 + 0.07 * f64::from(p % 5), 0.3, 0.05 * f64::from(p % 3));
    let mut x = ClusterTransfer::new(&tree, &links);
    let h = x.irradiance(&tree, &hier, &|p| if in_b.contains(&p) { bs(p) } else { Rgb::ZERO });
    let received: Rgb = in_a.iter().fold(Rgb::ZERO, |s, &p| s + h[p as usize] * hier.get(p).area);
    let rows = x.irradiance(&tree, &hier, &|p| if in_a.contains(&p) { Rgb::ONE } else { Rgb::ZERO });
    let sent: Rgb =
        in_b.iter().fold(Rgb::ZERO, |s, &p| s + bs(p) * (hier.get(p).area * rows[p as usize].0[0]));
    assert!(received.max_channel() > 0.0);
    for c in 0..3 {
        assert!((received.0[c] - sent.0[c]).abs() <= 1e-12 * sent.0[c].abs(), "{received:?} vs {sent:?}");
    }
}

/// A floor lit by a cluster (a cube) standing above one end of it gets the link's transfer
/// as a slope, not only a constant: brighter towards the cube, its mean unchanged (the
/// slope is about the floor's centroid), never negative at a corner.
#[test]
fn a_patch_gathers_a_cluster_links_slope_towards_its_source() {
    let mut patches = vec![
        Patch::new(
            vec![
                DVec3::ZERO,
                DVec3::new(10.0, 0.0, 0.0),
                DVec3::new(10.0, 0.0, -10.0),
                DVec3::new(0.0, 0.0, -10.0),
            ],
            Rgb::splat(0.5),
            Rgb::ZERO,
            "floor",
            0,
            "floor",
            "m",
        )
        .expect("valid floor"),
    ];
    patches.extend(cube(DVec3::new(8.5, 3.0, -5.0), 1.0, 0.3));
    let hier = hierarchy(patches);
    assert!(hier.get(0).normal.y > 0.99, "the floor faces up");
    let tree = ClusterTree::build(&hier);
    // The floor's leaf, and the largest cluster of cube faces.
    let floor = (0..tree.len() as u32).find(|&i| members(&tree, i) == [0]).expect("the floor's leaf");
    let cube_node = (0..tree.len() as u32)
        .filter(|&i| !members(&tree, i).contains(&0))
        .max_by_key(|&i| members(&tree, i).len())
        .expect("a cluster of cube faces");
    assert!(members(&tree, cube_node).len() >= 2, "a cluster, not a patch");
    let (na, nb) = (&tree.nodes[floor as usize], &tree.nodes[cube_node as usize]);
    let w = (nb.center - na.center).normalize();
    let links = vec![ClusterLink { a: floor, b: cube_node, vis: 1.0, frame: link_frame(na, nb, w) }];
    let mut x = ClusterTransfer::new(&tree, &links);
    let (h, slopes) = x.irradiance_and_slopes(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { Rgb::ONE });
    let e = hier.get(0);
    let [gu, gv] = slopes[0];
    assert!(h[0].0[0] > 0.0, "the floor gathers from the cube: {:?}", h[0]);
    let (t1, t2) = crate::math::orthonormal_basis(e.normal);
    let grad = t1 * gu.0[0] + t2 * gv.0[0];
    assert!(grad.x > 0.0, "brighter towards the cube (+x): gradient {grad}");
    let at = |v: DVec3| h[0].0[0] + grad.dot(v - e.centroid);
    let (near, far) = (at(DVec3::new(10.0, 0.0, -5.0)), at(DVec3::new(0.0, 0.0, -5.0)));
    assert!(near > 1.5 * far, "near edge {near} vs far edge {far}");
    for v in e.vertices() {
        assert!(at(*v) >= -1e-12, "corner {v}: {}", at(*v));
    }
    // The cube's own faces gather nothing through the link from the black floor.
    assert!((1..7).all(|p| slopes[p] == [Rgb::ZERO; 2] && h[p] == Rgb::ZERO));
    // The same irradiance without the slopes.
    assert_eq!(x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { Rgb::ONE }), h);
}

/// A 4 × 4 grid of squares making the unit square at height `z`, facing up or down.
fn grid(z: f64, up: bool) -> Vec<Patch> {
    let mut out = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let (x, y) = (f64::from(i) * 0.25, f64::from(j) * 0.25);
            let mut v = vec![
                DVec3::new(x, y, z),
                DVec3::new(x + 0.25, y, z),
                DVec3::new(x + 0.25, y + 0.25, z),
                DVec3::new(x, y + 0.25, z),
            ];
            if !up {
                v.reverse();
            }
            out.push(Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "grid", 0, "sq", "m").expect("valid square"));
        }
    }
    out
}

#[test]
fn coplanar_and_turned_away_clusters_carry_nothing() {
    // Two 4 × 4 grids side by side in one plane (a floor's clusters), and the same two
    // facing each other across a gap: only the facing pair exchanges light. One grid moved
    // to face away from the other (below it, facing down) carries nothing either.
    let pair = |second: Vec<Patch>| {
        let mut patches = grid(0.0, true);
        patches.extend(second);
        let hier = hierarchy(patches);
        let tree = ClusterTree::build(&hier);
        let [a, b] = tree.nodes[0].kids;
        let (na, nb) = (tree.nodes[a as usize].clone(), tree.nodes[b as usize].clone());
        let w = (nb.center - na.center).normalize();
        carries_nothing(&na, &nb, w, link_frame(&na, &nb, w))
    };
    let beside: Vec<Patch> = grid(0.0, true)
        .into_iter()
        .map(|p| {
            let v = p.vertices.iter().map(|v| *v + DVec3::new(3.0, 0.0, 0.0)).collect();
            Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "grid", 0, "sq", "m").expect("valid square")
        })
        .collect();
    assert!(pair(beside), "coplanar grids exchange nothing");
    assert!(!pair(grid(1.5, false)), "facing grids exchange light");
    assert!(pair(grid(-1.5, false)), "a grid below facing down sees nothing of one facing up");
}

#[test]
fn near_facing_clusters_are_not_overestimated() {
    // Two unit squares 1.5 apart, facing, each a cluster of 16 pieces (their spheres are
    // 0.09 apart, so linking accepts the pair). The point form A/(π d²) reads F = 0.141 where
    // the exact F is 0.115 (+23 %: light created in a closed room); the regularised distance
    // term must land within 6 %, and the transfer stays reciprocal.
    let mut patches = grid(0.0, true);
    patches.extend(grid(1.5, false));
    let hier = hierarchy(patches);
    let tree = ClusterTree::build(&hier);
    let [a, b] = tree.nodes[0].kids;
    let (in_a, in_b) = (members(&tree, a), members(&tree, b));
    assert_eq!((in_a.len(), in_b.len()), (16, 16), "the tree splits floor from ceiling");
    let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
    let d = na.center.distance(nb.center);
    assert!(d - na.radius - nb.radius > 0.0, "the spheres are apart");
    let w = (nb.center - na.center) / d;
    let frame = link_frame(na, nb, w);
    let links = vec![ClusterLink { a, b, vis: 1.0, frame }];
    let mut x = ClusterTransfer::new(&tree, &links);
    let area = |ids: &[u32]| ids.iter().map(|&i| hier.get(i).area).sum::<f64>();
    // F from `from` to `to`: 16 × 16 pieces, the exact kernel at each receiving centroid.
    let exact = |from: &[u32], to: &[u32]| {
        from.iter()
            .map(|&i| {
                let e = hier.get(i);
                let f: f64 = to
                    .iter()
                    .map(|&j| {
                        let s = hier.get(j);
                        form_factor::point_to_polygon_oriented(e.centroid, e.normal, s.vertices(), s.normal)
                    })
                    .sum();
                f * e.area
            })
            .sum::<f64>()
            / area(from)
    };
    let f_exact = exact(&in_a, &in_b);
    let point = nb.projected_area(-w, frame) / (std::f64::consts::PI * d * d);
    assert!(point > 1.15 * f_exact, "the point form overestimates: {point} vs {f_exact}");
    let one_on = |on: &[u32]| {
        let on = on.to_vec();
        move |p: u32| if on.contains(&p) { Rgb::ONE } else { Rgb::ZERO }
    };
    let h = x.irradiance(&tree, &hier, &one_on(&in_b));
    let f_ab = in_a.iter().map(|&i| h[i as usize].0[0] * hier.get(i).area).sum::<f64>() / area(&in_a);
    assert!(
        (f_ab - f_exact).abs() <= 0.06 * f_exact,
        "transfer {f_ab} vs exact {f_exact} (point form {point})"
    );
    let h = x.irradiance(&tree, &hier, &one_on(&in_a));
    let f_ba = in_b.iter().map(|&i| h[i as usize].0[0] * hier.get(i).area).sum::<f64>() / area(&in_b);
    assert!((f_ab * area(&in_a) - f_ba * area(&in_b)).abs() <= 1e-12, "reciprocal: {f_ab} vs {f_ba}");
}

#[test]
fn far_clusters_transfer_the_exact_form_factors() {
    // B = 1 on b, V = 1: each member of a gathers Σ_j F(x_i → j) (the exact point kernel at
    // its centroid, no occlusion), to the point approximation's accuracy: (r_a + r_b) / d
    // is 0.08 here; 3 % allowed on the total, 8 % per member.
    let (hier, tree, mut links, a, b) = two_clusters(40.0);
    links[0].vis = 1.0;
    let in_a = members(&tree, a);
    let in_b = members(&tree, b);
    let mut x = ClusterTransfer::new(&tree, &links);
    let h = x.irradiance(&tree, &hier, &|p| if in_b.contains(&p) { Rgb::ONE } else { Rgb::ZERO });
    let (mut tot_exact, mut tot) = (0.0, 0.0);
    for &i in &in_a {
        let e = hier.get(i);
        let exact: f64 = in_b
            .iter()
            .map(|&j| {
                let s = hier.get(j);
                form_factor::point_to_polygon_oriented(e.centroid, e.normal, s.vertices(), s.normal)
            })
            .sum();
        let got = h[i as usize].0[0];
        tot_exact += exact * e.area;
        tot += got * e.area;
        if exact > 1e-5 {
            assert!((got - exact).abs() <= 0.08 * exact, "member {i}: {got} vs exact {exact}");
        } else {
            assert!(got <= 1e-5, "member {i} faces away but gathers {got}");
        }
    }
    assert!((tot - tot_exact).abs() <= 0.03 * tot_exact, "total {tot} vs exact {tot_exact}");
}

/// A square of side `side` centred at `c` in the plane z = c.z, facing up or down.
fn square(c: DVec3, side: f64, up: bool) -> Patch {
    let h = side / 2.0;
    let mut v: Vec<DVec3> =
        [(-h, -h), (h, -h), (h, h), (-h, h)].iter().map(|&(x, y)| c + DVec3::new(x, y, 0.0)).collect();
    if !up {
        v.reverse();
    }
    Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "sq", 0, "sq", "m").expect("valid square")
}

/// A unit square on the floor under four dense stacks of twelve squares facing down, each
/// linked to it by the cluster links that cover it (its leaf with the sibling of every node
/// on its way to the root), all with V = 1: the members' summed cosines over the distance
/// term give the square a row of 1.60, where its hemisphere holds 0.30 of front faces (the
/// stacks' lowest squares; the eleven above each hide behind them). The bound cuts the row
/// to what the square's rays see (0.38), leaves the hidden squares (which see only
/// the back of the square below) almost nothing, and keeps the transfer reciprocal.
#[test]
fn a_dense_stack_of_occluders_is_bounded_by_the_hemisphere() {
    let mut patches = vec![square(DVec3::ZERO, 1.0, true)];
    for (x, y) in [(2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (0.0, -2.0)] {
        for i in 0..12 {
            patches.push(square(DVec3::new(x, y, 2.0 + 0.08 * f64::from(i)), 1.6, false));
        }
    }
    let scene = Scene::new("t", "test", patches);
    let accel = Accel::build(&scene);
    let hier = Hierarchy::from_scene(&scene);
    let tree = ClusterTree::build(&hier);
    let leaf = (0..tree.len() as u32).find(|&i| members(&tree, i) == [0]).expect("the square's leaf");
    let mut links = Vec::new();
    let mut at = leaf;
    while tree.nodes[at as usize].parent != LEAF {
        let parent = &tree.nodes[tree.nodes[at as usize].parent as usize];
        let sibling = if parent.kids[0] == at { parent.kids[1] } else { parent.kids[0] };
        let (na, nb) = (&tree.nodes[leaf as usize], &tree.nodes[sibling as usize]);
        let w = (nb.center - na.center).normalize();
        links.push(ClusterLink { a: leaf, b: sibling, vis: 1.0, frame: link_frame(na, nb, w) });
        at = tree.nodes[at as usize].parent;
    }
    let others: Vec<u32> = (1..hier.roots as u32).collect();
    let mut x = ClusterTransfer::new(&tree, &links);
    let unbounded = x.irradiance(&tree, &hier, &|_| Rgb::ONE)[0].0[0];
    let region =
        crate::solver::escape::Region { verts: hier.get(0).vertices(), normal: hier.get(0).normal, patch: 0 };
    let set = crate::solver::escape::HemisphereRays { region, rays: 1 << 14, key: 1, seed: 2 };
    let seen = crate::solver::escape::hemisphere(&scene, &accel, set).front;
    assert!((0.25..0.45).contains(&seen), "the stacks' lowest squares fill {seen} of the hemisphere");
    assert!(unbounded > 1.0, "the unbounded row {unbounded} exceeds the hemisphere");
    let bound = x.bound_rows(&tree, &hier, &scene, &accel, 0);
    let row = bound.rows[0];
    assert!(row <= seen + 0.08 && row >= 0.8 * seen, "bounded row {row} against the {seen} seen");
    // Every hidden square (all but each stack's lowest) sees only the back of the one below.
    for q in (1..hier.roots).filter(|q| (q - 1) % 12 != 0) {
        assert!(bound.rows[q] <= 0.01, "hidden square {q}: row {}", bound.rows[q]);
    }
    assert!(bound.cut >= 1 && bound.cut_area_row > 0.0, "the square's row is cut: {bound:?}");
    // Reciprocal still: what the square gathers from the stacks is what they send to it.
    let bs = |p: u32| Rgb::new(0.2 + 0.05 * f64::from(p % 7), 0.4, 0.1 * f64::from(p % 3));
    let h = x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { bs(p) });
    let received = h[0] * hier.get(0).area;
    let rows = x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ONE } else { Rgb::ZERO });
    let sent = others.iter().fold(Rgb::ZERO, |s, &p| s + bs(p) * (hier.get(p).area * rows[p as usize].0[0]));
    for c in 0..3 {
        assert!((received.0[c] - sent.0[c]).abs() <= 1e-12 * sent.0[c], "{received:?} vs {sent:?}");
    }
}
