//! Galerkin radiosity with elements of order p = 0 or p = 1 ([`crate::geometry::basis`]), discontinuous
//! (each element its own coefficients) or continuous (one coefficient per mesh vertex of a
//! patch, shared by the elements around it) [Heckbert & Winget 1991; Zatz 1993, "Galerkin
//! radiosity: a higher order solution method for global illumination"; Troutman & Max 1993,
//! "Radiosity algorithms using higher order finite element methods"].
//!
//! B(x) = Σ_j b_j φ_j(x) is put into the radiosity equation
//! `B(x) = E(x) + ρ(x) ∫_S K(x, y) V(x, y) B(y) dy`, `K = cos θ_x cos θ_y / (π r²)`, and the
//! residual is made orthogonal to every basis function φ_i:
//!
//! ```text
//! Σ_j M_ij b_j = e_i + ρ_i Σ_j G_ij b_j                  M b = e + ρ G b
//! M_ij = ∫ φ_i φ_j dx        e_i = ∫ φ_i E dx        G_ij = ∫∫ φ_i(x) K(x, y) V(x, y) φ_j(y) dy dx
//! ```
//!
//! (per RGB channel; ρ and E are constant on a patch, and a continuous coefficient never spans
//! two materials). With p = 0 this is the classical system of [`super::uniform`] multiplied by
//! the element areas (`G_ij = A_i F_ij`).
//!
//! ## How it works
//! - **Couplings** (`pair_block`): for each unordered element pair {a, b} facing each other,
//!   the block `G_ab` (rows a's basis, columns b's) is integrated once — the outer integral over
//!   the smaller element with a 3 × 3 Gauss rule (6 × 6 on near pairs), the inner one over the
//!   other element adaptively — and `G_ba = G_abᵀ` (K and V are symmetric), so G is exactly symmetric:
//!
//!   ```text
//!   inner(x, piece):  piece far from x (distance > 3 × its radius)  →  4 × 4 Gauss, point kernel
//!                     near, depth < 6                               →  the four children
//!                     near, at depth 6                              →  exact F(x → piece)
//!                                                                       (Lambert, handles the
//!                                                                       contact singularity) ×
//!                                                                       φ at the piece's centre
//!   ```
//! - **Visibility**: the pair is first classified by the classical jittered-ray fraction
//!   ([`crate::geometry::visibility::visible_fraction`], `rays` rays, keyed by the pair as in
//!   [`super::uniform::pair_coupling`]): 0 → no coupling, 1 → V ≡ 1, otherwise V(x, y) is one
//!   shadow ray per quadrature point pair, **inside** the integral — so a p = 1 element sees the
//!   shadow vary across it. (A pair whose rays all pass or all miss is treated as unoccluded or
//!   hidden, as in the p = 0 solver.)
//! - **Solve**: `b ← M⁻¹ (e + ρ G b)` until the largest change is below `tolerance` × the largest
//!   coefficient, M⁻¹ by conjugate gradients (M is symmetric positive definite and well
//!   conditioned: a bilinear element's mass matrix has condition number 9). The iteration
//!   converges like the p = 0 one: the spectral radius of M⁻¹ρG is that of ρF.
//! - **Energy**: `absorbed = Σ_i (1 − ρ_i)(G b)_i`, `escaped = Σ_j b_j (∫φ_j − Σ_i G_ij)`; they add
//!   up to `emitted = Σ_i e_i` exactly when b solves the system (Σ_i φ_i = 1 on every element).
//!
//! Memory is O(unknowns²): `max_unknowns` caps the coefficients (4 per bilinear element when
//! discontinuous, ~1 per element when continuous).

use super::uniform::{Element, SharedProgress, mesh_scene, mesh_solution};
use super::{EnergyBalance, PhaseTimes, Progress, Solution, SolveStats, SolvedElement};
use crate::geometry::accel::Accel;
use crate::geometry::basis::{self, Domain, Local, MAX_FUNCTIONS, Order, QuadPoint, Values};
use crate::geometry::form_factor::point_to_polygon_oriented;
use crate::geometry::visibility::visible_fraction;
use crate::math::{DVec3, Rgb, newell_normal, polygon_centroid};
use crate::scene::Scene;
use rayon::prelude::*;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::time::Instant;

/// Gauss points per direction of the outer rule (over the smaller element of a pair) on far
/// pairs, where the outer integrand is smooth: exact for the p = 1 mass-like part (degree ≤ 5 a
/// direction), and the parallel-squares study (docs/meshing.md) keeps its slope 2 down to a
/// 7e-6 relative error, so the rule's error is below that.
const OUTER_ORDER: usize = 3;
/// Outer Gauss points per direction on a near pair (centroids closer than [`FAR_RATIO`] × the
/// sum of the radii): there the inner integral, as a function of x, has a log-singular
/// derivative at a shared edge. Measured on a closed box of 2 × 2 elements a face (p = 1,
/// tests/order.rs): worst vertex 0.69 % off the exact value with 3 points, 0.051 % with 6.
const OUTER_NEAR_ORDER: usize = 6;
/// Gauss points per direction of the inner rule on a piece that is far from the outer point:
/// the product rule's error falls like (radius / distance)^8 ≈ 1.5e-4 relative at the 3 ×
/// radius threshold, and far less on all but the nearest pieces.
const INNER_ORDER: usize = 4;
/// A piece farther than this many radii from the outer point takes the Gauss rule.
const FAR_RATIO: f64 = 3.0;
/// Deepest split of the inner element (4^6 = 4 096 pieces at most, only along the contact).
const MAX_DEPTH: u32 = 6;

/// Settings of the Galerkin solver.
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct LinearParams {
    /// Longest element side of the uniform mesh ([`super::uniform::mesh_patch`]).
    pub element_size: f64,
    /// Order of the basis on every element.
    pub order: Order,
    /// Share the vertex coefficients between the elements of a patch (p = 1 only).
    pub continuous: bool,
    /// Rays of the pair's visibility class, and of nothing else (module docs).
    pub rays: u32,
    /// Stop when the largest change of a coefficient is at most this × the largest coefficient.
    pub tolerance: f64,
    pub max_iterations: u32,
    /// Seed of the pair classification's jitter.
    pub seed: u64,
    /// Refuse meshes with more coefficients than this (the matrix is O(unknowns²)).
    pub max_unknowns: usize,
}

impl Default for LinearParams {
    fn default() -> Self {
        LinearParams {
            element_size: f64::INFINITY,
            order: Order::Linear,
            continuous: false,
            rays: 16,
            tolerance: 1e-10,
            max_iterations: 1000,
            seed: 0,
            max_unknowns: 6_000,
        }
    }
}

impl LinearParams {
    /// Reject absurd values with a message naming the parameter.
    pub fn validate(&self) -> Result<(), String> {
        super::uniform::validate_common(self.element_size, self.rays, 0.5, self.max_unknowns)?;
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(format!("tolerance must be > 0 (got {})", self.tolerance));
        }
        if self.max_iterations == 0 {
            return Err("max-iterations must be at least 1".into());
        }
        if self.continuous && self.order == Order::Constant {
            return Err("a continuous basis needs order 1 (constant elements cannot share values)".into());
        }
        Ok(())
    }

    /// "p0", "p1-discontinuous" or "p1-continuous".
    #[must_use]
    pub fn label(&self) -> &'static str {
        match (self.order, self.continuous) {
            (Order::Constant, _) => "p0",
            (Order::Linear, false) => "p1-discontinuous",
            (Order::Linear, true) => "p1-continuous",
        }
    }
}

/// A solved Galerkin system: the [`Solution`] (each element's radiosity is its function's
/// average) and every element's coefficients — its vertex values at p = 1 (in vertex order),
/// its one value at p = 0. [`crate::eval::reconstruction::Nodal`] evaluates them.
#[derive(Clone, Debug)]
pub struct LinearSolution {
    pub solution: Solution,
    pub order: Order,
    pub coefficients: Vec<Vec<Rgb>>,
}

/// Solve the scene on the uniform mesh of `params.element_size` (one continuity group per patch).
pub fn solve(
    scene: &Scene,
    accel: &Accel,
    params: &LinearParams,
    progress: Progress,
) -> Result<LinearSolution, String> {
    params.validate()?;
    let per_element = params.order.functions(4);
    let elems =
        mesh_scene(scene, params.element_size, params.max_unknowns / per_element.max(1)).map_err(|e| {
            format!("{e} (order {}: up to {per_element} unknowns per element)", params.order.degree())
        })?;
    let groups: Vec<usize> = elems.iter().map(|e| e.patch).collect();
    let mut out = solve_mesh(scene, accel, elems, &groups, params, progress)?;
    out.solution.method = "uniform".into();
    Ok(out)
}

/// A prepared element: geometry, material and its coefficients' indices.
struct Prepared {
    verts: Vec<DVec3>,
    normal: DVec3,
    centroid: DVec3,
    radius: f64,
    area: f64,
    patch: usize,
    /// Global unknown of each basis function.
    dofs: Vec<u32>,
}

/// Solve on a given mesh: `elems` on the patches of `scene` (3 or 4 vertices each), and per
/// element its continuity group (elements of one group share vertex coefficients when
/// `params.continuous`; they must have one material). `params.element_size` is not used.
pub fn solve_mesh(
    scene: &Scene,
    accel: &Accel,
    elems: Vec<Element>,
    groups: &[usize],
    params: &LinearParams,
    progress: Progress,
) -> Result<LinearSolution, String> {
    params.validate()?;
    if groups.len() != elems.len() {
        return Err(format!("{} continuity groups for {} elements", groups.len(), elems.len()));
    }
    if let Some(e) = elems.iter().find(|e| !(3..=4).contains(&e.vertices.len())) {
        return Err(format!(
            "an element of patch {} has {} vertices (3 or 4 supported)",
            e.patch,
            e.vertices.len()
        ));
    }
    let t_start = Instant::now();
    let (elems, nu) = number_unknowns(elems, groups, params)?;
    let system = mass_system(scene, &elems, nu, params.order);
    let (rows, evaluations, rays) = couplings(accel, &elems, nu, params, progress);
    let entries: usize = rows.iter().map(Vec::len).sum();
    let t_ff = t_start.elapsed().as_secs_f64();

    // b ← M⁻¹ (e + ρ G b).
    let t_solve = Instant::now();
    let apply = |b: &[Rgb]| -> Vec<Rgb> {
        rows.par_iter().map(|r| r.iter().map(|&(j, g)| b[j as usize] * g).sum::<Rgb>()).collect()
    };
    let System { mass_rows, integral, load, rho } = system;
    let mut b = mass_solve(&mass_rows, &load, None);
    let (mut iterations, mut converged, mut last_change) = (0usize, false, f64::INFINITY);
    for _ in 0..params.max_iterations {
        iterations += 1;
        let gb = apply(&b);
        let rhs: Vec<Rgb> = (0..nu).map(|i| load[i] + rho[i].mul_rgb(gb[i])).collect();
        let next = mass_solve(&mass_rows, &rhs, Some(&b));
        let change = next.iter().zip(&b).map(|(x, y)| x.abs_diff_max(*y)).fold(0.0, f64::max);
        let scale = next.iter().map(|x| x.max_channel().abs()).fold(0.0, f64::max);
        b = next;
        last_change = if scale > 0.0 { change / scale } else { 0.0 };
        if last_change <= params.tolerance {
            converged = true;
            break;
        }
    }

    // Energy balance (module docs).
    let gb = apply(&b);
    let mut energy = EnergyBalance::default();
    for i in 0..nu {
        let column: f64 = rows[i].iter().map(|&(_, g)| g).sum(); // = Σ_k G_ki (G symmetric)
        energy.emitted += load[i];
        energy.absorbed += (Rgb::ONE - rho[i]).mul_rgb(gb[i]);
        energy.escaped += b[i] * (integral[i] - column);
    }
    let t_solve = t_solve.elapsed().as_secs_f64();

    let (elements, coefficients) = solved_elements(elems, &b, params.order);
    Ok(LinearSolution {
        solution: mesh_solution(
            scene,
            format!("galerkin-{}", params.label()),
            elements,
            energy,
            SolveStats {
                links: entries,
                iterations,
                rays,
                time_s: PhaseTimes::of_solve(t_ff, t_solve),
                extra: Some(serde_json::json!({
                    "order": params.order.degree(),
                    "continuity": if params.continuous { "continuous" } else { "discontinuous" },
                    "unknowns": nu,
                    "converged": converged,
                    "final_change": last_change,
                    "kernel_evaluations": evaluations,
                    "params": params,
                })),
                ..SolveStats::default()
            },
        ),
        order: params.order,
        coefficients,
    })
}

/// Number the unknowns: each element's basis functions in element order, a vertex function
/// shared by the elements of its continuity group that meet at the vertex when
/// `params.continuous`. The prepared elements and the number of unknowns; an error past
/// `params.max_unknowns`.
fn number_unknowns(
    elems: Vec<Element>,
    groups: &[usize],
    params: &LinearParams,
) -> Result<(Vec<Prepared>, usize), String> {
    let mut shared: HashMap<(usize, [u64; 3]), u32> = HashMap::new();
    let mut unknowns = 0u32;
    let mut prepared = Vec::with_capacity(elems.len());
    for (e, &group) in elems.into_iter().zip(groups) {
        let nf = params.order.functions(e.vertices.len());
        let dofs = (0..nf)
            .map(|k| {
                if params.continuous {
                    let v = e.vertices[k];
                    *shared.entry((group, [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])).or_insert_with(
                        || {
                            unknowns += 1;
                            unknowns - 1
                        },
                    )
                } else {
                    unknowns += 1;
                    unknowns - 1
                }
            })
            .collect();
        let centroid = polygon_centroid(&e.vertices);
        let radius = e.vertices.iter().map(|v| (*v - centroid).length()).fold(0.0, f64::max);
        prepared.push(Prepared {
            normal: newell_normal(&e.vertices).normalize_or_zero(),
            centroid,
            radius,
            area: e.area,
            patch: e.patch,
            dofs,
            verts: e.vertices,
        });
        if unknowns as usize > params.max_unknowns {
            return Err(format!(
                "more than {} unknowns (the cap; the matrix needs O(unknowns²) memory): use a larger element size",
                params.max_unknowns
            ));
        }
    }
    Ok((prepared, unknowns as usize))
}

/// The left side and the sources of M b = e + ρ G b, per unknown.
struct System {
    /// The mass matrix M, row by row (sorted, duplicates added).
    mass_rows: Vec<Vec<(u32, f64)>>,
    /// ∫ φ_i dA.
    integral: Vec<f64>,
    /// e_i = E ∫ φ_i dA.
    load: Vec<Rgb>,
    /// The reflectance of the unknown's patch.
    rho: Vec<Rgb>,
}

/// The mass matrix, load vector and material of every unknown.
fn mass_system(scene: &Scene, elems: &[Prepared], nu: usize, order: Order) -> System {
    let mut mass_rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); nu];
    let mut integral = vec![0.0; nu];
    let mut load = vec![Rgb::ZERO; nu];
    let mut rho = vec![Rgb::ZERO; nu];
    for e in elems {
        let (m, int) = basis::mass(order, &e.verts);
        let patch = &scene.patches[e.patch];
        for (k, &dk) in e.dofs.iter().enumerate() {
            integral[dk as usize] += int[k];
            load[dk as usize] += patch.emission * int[k];
            rho[dk as usize] = patch.reflectance;
            for (l, &dl) in e.dofs.iter().enumerate() {
                mass_rows[dk as usize].push((dl, m[k][l]));
            }
        }
    }
    let mass_rows: Vec<Vec<(u32, f64)>> = mass_rows.into_iter().map(merge).collect();
    System { mass_rows, integral, load, rho }
}

/// The coupling matrix G, row by row (sorted, duplicates added), from every pair's block
/// ([`pair_block`]), streamed into the rows chunk by chunk (the blocks are 16 values per pair);
/// and the kernel evaluations and rays spent.
fn couplings(
    accel: &Accel,
    elems: &[Prepared],
    nu: usize,
    params: &LinearParams,
    progress: Progress,
) -> (Vec<Vec<(u32, f64)>>, u64, u64) {
    let n = elems.len();
    let total_pairs = (n as u64) * (n as u64).saturating_sub(1) / 2;
    let shared_progress = SharedProgress::new(progress, total_pairs);
    let mut rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); nu];
    let (mut evaluations, mut rays) = (0u64, 0u64);
    const CHUNK: usize = 64;
    for start in (0..n).step_by(CHUNK) {
        let chunk: Vec<RowBlocks> = (start..(start + CHUNK).min(n))
            .into_par_iter()
            .map(|a| {
                let (mut evals, mut rays) = (0u64, 0u64);
                let mut out = Vec::new();
                for b in a + 1..n {
                    if let Some((block, e, r)) = pair_block(accel, elems, a, b, params) {
                        evals += e;
                        rays += r;
                        out.push((b, block));
                    }
                }
                shared_progress.add((n - 1 - a) as u64);
                (out, evals, rays)
            })
            .collect();
        for (offset, (blocks, e, r)) in chunk.into_iter().enumerate() {
            evaluations += e;
            rays += r;
            let a = &elems[start + offset];
            for (b, block) in blocks {
                let b = &elems[b];
                for (i, &di) in a.dofs.iter().enumerate() {
                    for (j, &dj) in b.dofs.iter().enumerate() {
                        let g = block[i][j];
                        if g != 0.0 {
                            rows[di as usize].push((dj, g));
                            rows[dj as usize].push((di, g));
                        }
                    }
                }
            }
        }
    }
    shared_progress.finish();
    let rows: Vec<Vec<(u32, f64)>> = rows.into_par_iter().map(merge).collect();
    (rows, evaluations, rays)
}

/// The solved elements, each with its average (∫ Σ_k b_k φ_k dA / A), and each element's
/// coefficients in the order of its basis functions.
fn solved_elements(elems: Vec<Prepared>, b: &[Rgb], order: Order) -> (Vec<SolvedElement>, Vec<Vec<Rgb>>) {
    let mut coefficients = Vec::with_capacity(elems.len());
    let elements: Vec<SolvedElement> = elems
        .into_iter()
        .map(|e| {
            let (_, int) = basis::mass(order, &e.verts);
            let coef: Vec<Rgb> = e.dofs.iter().map(|&d| b[d as usize]).collect();
            let total: Rgb = coef.iter().zip(int).map(|(c, w)| *c * w).sum();
            coefficients.push(coef);
            SolvedElement {
                patch: e.patch,
                radiosity: total / e.area,
                vertices: e.verts,
                area: e.area,
                error_estimate: None,
                // Its own p = 1 function is `LinearSolution`'s (`reconstruction::Nodal`).
                slope: None,
            }
        })
        .collect();
    (elements, coefficients)
}

/// Sort a row's entries by column and add duplicates.
fn merge(mut row: Vec<(u32, f64)>) -> Vec<(u32, f64)> {
    row.sort_by_key(|&(j, _)| j);
    let mut out: Vec<(u32, f64)> = Vec::with_capacity(row.len());
    for (j, v) in row {
        match out.last_mut() {
            Some(last) if last.0 == j => last.1 += v,
            _ => out.push((j, v)),
        }
    }
    out
}

/// Solve M x = rhs per channel by conjugate gradients from `start` (M symmetric positive
/// definite, condition ≤ 9 per element: 60 iterations reach 1e-15 relative).
fn mass_solve(mass: &[Vec<(u32, f64)>], rhs: &[Rgb], start: Option<&[Rgb]>) -> Vec<Rgb> {
    let n = rhs.len();
    let mut out = start.map_or_else(|| vec![Rgb::ZERO; n], <[Rgb]>::to_vec);
    let mul = |x: &[f64]| -> Vec<f64> {
        mass.iter().map(|r| r.iter().map(|&(j, m)| m * x[j as usize]).sum()).collect()
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    for c in 0..3 {
        let mut x: Vec<f64> = out.iter().map(|v| v.0[c]).collect();
        let f: Vec<f64> = rhs.iter().map(|v| v.0[c]).collect();
        let target = dot(&f, &f).sqrt() * 1e-15;
        let mx = mul(&x);
        let mut r: Vec<f64> = f.iter().zip(&mx).map(|(a, b)| a - b).collect();
        let mut p = r.clone();
        let mut rr = dot(&r, &r);
        for _ in 0..200 {
            if rr.sqrt() <= target {
                break;
            }
            let mp = mul(&p);
            let alpha = rr / dot(&p, &mp);
            for k in 0..n {
                x[k] += alpha * p[k];
                r[k] -= alpha * mp[k];
            }
            let next = dot(&r, &r);
            let beta = next / rr;
            rr = next;
            for k in 0..n {
                p[k] = r[k] + beta * p[k];
            }
        }
        for (o, v) in out.iter_mut().zip(x) {
            o.0[c] = v;
        }
    }
    out
}

/// `G_ab`: rows the basis of element a, columns b's.
type Block = [[f64; MAX_FUNCTIONS]; MAX_FUNCTIONS];

/// The blocks of one element's pairs with later elements, and the kernel evaluations and rays
/// they cost.
type RowBlocks = (Vec<(usize, Block)>, u64, u64);

/// How a pair's visibility enters its integral.
#[derive(Copy, Clone)]
enum Vis {
    Full,
    /// One shadow ray per point pair, ignoring the pair's two patches.
    Rays([u32; 2]),
}

/// The coupling block of a pair (a < b) with the kernel evaluations and rays spent, or `None`
/// when it is zero (same patch, facing away, hidden).
fn pair_block(
    accel: &Accel,
    elems: &[Prepared],
    a: usize,
    b: usize,
    params: &LinearParams,
) -> Option<(Block, u64, u64)> {
    let (ea, eb) = (&elems[a], &elems[b]);
    if ea.patch == eb.patch {
        return None;
    }
    let behind = |of: &Prepared, other: &Prepared| {
        // Rounding of a vertex that lies in the plane (coplanar pieces of one receiver, shared
        // edges) is ~1e-16 relative: 1e-12 of the pair's size counts as in the plane.
        let eps = 1e-12 * (of.radius + other.radius);
        other.verts.iter().all(|v| of.normal.dot(*v - of.centroid) <= eps)
    };
    if behind(ea, eb) || behind(eb, ea) {
        return None;
    }
    let mut rays = 0u64;
    let vis = if params.rays == 0 {
        Vis::Full
    } else {
        rays += u64::from(params.rays);
        let f = visible_fraction(
            accel,
            &ea.verts,
            ea.patch as u32,
            &eb.verts,
            eb.patch as u32,
            params.rays,
            params.seed,
            ((a as u64) << 32) | b as u64,
        );
        if f <= 0.0 {
            return None;
        } else if f >= 1.0 {
            Vis::Full
        } else {
            Vis::Rays([ea.patch as u32, eb.patch as u32])
        }
    };
    let a_outer = ea.area <= eb.area;
    let (outer, inner) = if a_outer { (ea, eb) } else { (eb, ea) };
    let (no, ni) = (params.order.functions(outer.verts.len()), params.order.functions(inner.verts.len()));
    let mut block: Block = [[0.0; MAX_FUNCTIONS]; MAX_FUNCTIONS];
    let mut counter = Counter::default();
    let whole = Domain::whole(inner.verts.len());
    let near = (ea.centroid - eb.centroid).length() <= FAR_RATIO * (ea.radius + eb.radius);
    let order = if near { OUTER_NEAR_ORDER } else { OUTER_ORDER };
    for q in basis::rule(&outer.verts, order, &Domain::whole(outer.verts.len())) {
        let phi = basis::values(params.order, outer.verts.len(), q.at);
        let mut g: Values = [0.0; MAX_FUNCTIONS];
        inner_integral(accel, q.x, outer.normal, inner, &whole, 0, params.order, vis, &mut g, &mut counter);
        for i in 0..no {
            for j in 0..ni {
                block[i][j] += q.weight * phi[i] * g[j];
            }
        }
    }
    rays += counter.rays;
    if !a_outer {
        let mut t: Block = [[0.0; MAX_FUNCTIONS]; MAX_FUNCTIONS];
        for (i, row) in block.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                t[j][i] = *v;
            }
        }
        block = t;
    }
    Some((block, counter.evaluations, rays))
}

#[derive(Default)]
struct Counter {
    evaluations: u64,
    rays: u64,
}

/// Point kernel cos θ_x cos θ_y / (π r²), one-sided at both ends.
fn kernel(x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    let (cx, cy) = (nx.dot(d), -ny.dot(d));
    if cx <= 0.0 || cy <= 0.0 || r2 <= 0.0 { 0.0 } else { cx * cy / (PI * r2 * r2) }
}

/// Add `∫_piece K(x, y) V(x, y) φ_j(y) dy` to `g` (module docs: Gauss when far, split when near,
/// the exact point-to-polygon form factor at the deepest level).
#[allow(clippy::too_many_arguments)] // the recursion's state, each argument one quantity
fn inner_integral(
    accel: &Accel,
    x: DVec3,
    nx: DVec3,
    inner: &Prepared,
    piece: &Domain,
    depth: u32,
    order: Order,
    vis: Vis,
    g: &mut Values,
    counter: &mut Counter,
) {
    let nv = inner.verts.len();
    let nf = order.functions(nv);
    let visible = |y: DVec3, counter: &mut Counter| match vis {
        Vis::Full => true,
        Vis::Rays(ignore) => {
            counter.rays += 1;
            !accel.occluded(x, y, ignore)
        }
    };
    let corners: Vec<DVec3> = piece.corners().into_iter().map(|c| basis::position(&inner.verts, c)).collect();
    let centre = basis::position(&inner.verts, piece.centre());
    let radius = corners.iter().map(|c| (*c - centre).length()).fold(0.0, f64::max);
    if (x - centre).length() > FAR_RATIO * radius {
        for QuadPoint { x: y, weight, at } in basis::rule(&inner.verts, INNER_ORDER, piece) {
            counter.evaluations += 1;
            let k = kernel(x, nx, y, inner.normal);
            if k > 0.0 && visible(y, counter) {
                let phi = basis::values(order, nv, at);
                for j in 0..nf {
                    g[j] += weight * k * phi[j];
                }
            }
        }
    } else if depth < MAX_DEPTH {
        for child in piece.split() {
            inner_integral(accel, x, nx, inner, &child, depth + 1, order, vis, g, counter);
        }
    } else {
        counter.evaluations += 1;
        let f = point_to_polygon_oriented(x, nx, &corners, inner.normal);
        if f > 0.0 && visible(centre, counter) {
            let at: Local = piece.centre();
            let phi = basis::values(order, nv, at);
            // F(x → piece) = ∫_piece K dy, so the piece's area is already in f.
            for j in 0..nf {
                g[j] += f * phi[j];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::uniform::{self, UniformParams};

    /// At p = 0 the Galerkin system is the classical one times the areas: on cornell (adjacent
    /// walls: the contact quadrature) the element values agree with the uniform solver's to the
    /// two quadratures' accuracy. Both without occlusion rays (rays = 0) so that only the
    /// kernels are compared. Tolerance: 0.5 % of the largest value; the uniform solver's form
    /// factors are to 1e-4 relative, this one's inner rule to ~1e-4, and its outer Gauss rule
    /// across the contact edges (where the inner integral is log-singular) is what dominates.
    #[test]
    fn constant_elements_match_the_uniform_solver() {
        let scene = Scene::load("builtin:cornell").unwrap();
        let accel = Accel::build(&scene);
        let size = scene.bounds().diagonal() / 4.0;
        let uni = uniform::solve(
            &scene,
            &accel,
            &UniformParams { element_size: size, rays: 0, ff_tolerance: 1e-4, ..UniformParams::default() },
            &mut |_, _| {},
        )
        .unwrap();
        let p =
            LinearParams { element_size: size, order: Order::Constant, rays: 0, ..LinearParams::default() };
        let gal = solve(&scene, &accel, &p, &mut |_, _| {}).unwrap();
        assert_eq!(gal.solution.elements.len(), uni.elements.len());
        let scale = uni.elements.iter().map(|e| e.radiosity.max_channel()).fold(0.0, f64::max);
        let worst = gal
            .solution
            .elements
            .iter()
            .zip(&uni.elements)
            .filter(|(_, u)| scene.patches[u.patch].emission.is_zero())
            .map(|(g, u)| g.radiosity.abs_diff_max(u.radiosity))
            .fold(0.0, f64::max);
        assert!(worst < 5e-3 * scale, "worst {worst} of {scale}");
        assert!(gal.solution.energy.relative_residual() < 1e-8, "{:?}", gal.solution.energy);
    }
}
