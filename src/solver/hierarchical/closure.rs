//! Closed rows: a point that front faces enclose sees them with its whole hemisphere, so its
//! form factors sum to one [Cohen & Wallace 1993, the form factors' summation relation],
//!
//! ```text
//! Σ_j F_xj V_xj = 1,        and with every surface E, ρ:  B = E + ρ B  ⇒  B = E / (1 − ρ)
//! ```
//!
//! (the white furnace). A leaf's row holds this only on average: it gathers through its own
//! links and its ancestors', each an average over a larger element moved along its slope, so
//! its row is off by the kernel's curvature across the ancestor (a refined furnace's rows run
//! from 0.82 at a face's centre to 1.55 in its corners), and its radiosity follows the row.
//!
//! ## How it works
//! The leaves' operator is symmetric: with K_xy = A_x × (the weight of B_y in leaf x's
//! irradiance H_x), a link and its mirror carry one coupling G ([`super::transfer`]) and their
//! slopes and source moments mirror each other ([`super::push_pull`]), so K_xy = K_yx. On the
//! leaves of enclosed patches the solver gathers through D K D instead, D = diag(d), d chosen so
//! that their rows sum to exactly 1 (d = 1 on every other leaf):
//!
//! ```text
//! H_x = d_x Σ_y (K_xy / A_x) d_y B_y          r_x = Σ_y (K_xy / A_x) d_y          d_x r_x = 1
//!
//!   gather:  sources send d·B (pulled: area averages and first moments of d·B)
//!   push:    a leaf's irradiance × d_x
//!   balance: d_x ← d_x (d_x r_x)^(−ω), r from one gather of d, until every |d_x r_x − 1| is small
//! ```
//! The balance is the symmetric Sinkhorn–Knopp iteration (ω = ½) [Sinkhorn & Knopp 1967; Knight
//! 2008, "The Sinkhorn–Knopp algorithm: convergence and applications"], over-relaxed
//! ([`CLOSURE_STEP`]), run after every change of the links from the last d (new leaves start
//! from their parent's). D K D is symmetric as K is, so
//! what a source sends is still what its receivers gather: the power balance closes
//! (Σ A B (1 − d r) is the escaped power), and an enclosed leaf, its row being 1, neither loses
//! nor creates light. A one-sided scale, H_x / r_x, makes the furnace exact too, but it is not
//! reciprocal: it created light in every closed room measured (table-room `interactive` 0.52 %
//! of the emitted power, `splash2` 2.2 %, cube-one-light `draft` 0.21 %).
//!
//! A patch is enclosed when none of the cosine-distributed rays cast from it
//! ([`crate::solver::escape::cast_hemisphere`], [`enclosure_rays`]) leaves the scene or meets a
//! back face: its row's target 1 is then known. A ceiling above a one-sided lamp sees the lamp's
//! back, an open box's walls see out: they keep their own rows. Off in clustered solves (cluster
//! links carry bounded approximations of their rows, `super::cluster`) and with Gauss–Seidel.

use super::*;
use crate::solver::escape::{Hit, Region, cast_hemisphere};

pub(super) fn own_exponent() -> f64 {
    static M: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *M.get_or_init(|| std::env::var("GAMMA").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0))
}

/// Rays shared by the input patches in proportion to their area to decide which are enclosed,
/// beside [`ENCLOSURE_MIN_RAYS`] each and at most [`ENCLOSURE_MAX_RAYS`] a patch.
pub(super) const ENCLOSURE_RAY_BUDGET: f64 = 131_072.0;
pub(super) const ENCLOSURE_MIN_RAYS: u32 = 32;
pub(super) const ENCLOSURE_MAX_RAYS: u32 = 1024;

/// The balance stops once every enclosed leaf's row is within `tolerance` × this of 1
/// (`HierarchicalParams::tolerance`, the gathers' own stopping rule), and within at most
/// [`CLOSURE_TOL_MAX`] and at least [`CLOSURE_TOL_MIN`]: a row off by δ moves the furnace's B
/// by ρ δ / (1 − ρ), as an iterate off by δ does, and leaks or creates δ of the light the leaf
/// sends.
pub(super) const CLOSURE_TOL_SHARE: f64 = 0.1;
pub(super) const CLOSURE_TOL_MAX: f64 = 1e-5;
pub(super) const CLOSURE_TOL_MIN: f64 = 1e-12;

/// The step's exponent: d_x ← d_x (d_x r_x)^(−ω). Linearised about the balance, an error mode of
/// the row operator's eigenvalue λ shrinks by (1 − ω) − ωλ per step; the symmetric
/// Sinkhorn–Knopp step ω = ½ leaves ½(1 − λ), and ω = 0.7 is smaller for every λ ≤ 1 down to
/// −1 (the refined furnace's balance from scratch to 1e-10: 28 steps at ½, 18 at 0.7; at 0.9
/// it overshoots, 66).
pub(super) const CLOSURE_STEP: f64 = 0.7;

/// Steps that Anderson acceleration combines ([`Anderson`]). Measured to 1e-6 on splash_room's
/// contact mesh (`draft`, 14 balances): 1901 steps without (several stopped at the cap, slow
/// modes between facing surfaces: a floor and a table's underside see mostly each other), 637
/// with 3, 375 with 6, 332 with 10; the refined furnace to 1e-11, 363 → 184 (6) and 200 (10).
pub(super) const ANDERSON_DEPTH: usize = 6;

/// A step whose largest row residual is this many times the smallest so far restarts the
/// acceleration's history (a safeguard: the extrapolation went astray).
pub(super) const ANDERSON_RESTART: f64 = 4.0;

/// Iterations of the balance at most (each one gather of d). The furnace refined by the BF oracle
/// takes about 20 to 1e-10, from scratch or after a refinement.
pub(super) const CLOSURE_MAX_ITERATIONS: u32 = 200;

/// How far the balance may move a leaf's scale: |ln d| ≤ SCALE_REACH · max(|ln row|,
/// SCALE_FLOOR) of its row as it is, and ≤ ln SCALE_RANGE. Where the exact balance asks more, a
/// leaf whose own row is nearly right is making up another's error through weak couplings: a
/// pocket whose two sides see mostly each other (a floor under a desk and the desk's underside)
/// can share only one coupling, so a mismatch of their rows of 1 % falls on their little
/// coupling to the room, which the exact balance scaled by 1.55 and 0.65 on splash_room
/// (`quality`). The furnace's balance stays within 2.25 × its rows' own (BF oracle at 0.1, ρ 0.5)
/// and within 0.171 in all (Feps 0.1).
pub(super) const SCALE_REACH: f64 = 3.0;
pub(super) const SCALE_FLOOR: f64 = 0.02;

/// d stays within [1 / SCALE_RANGE, SCALE_RANGE]: a leaf whose row is far from 1 for another
/// reason than curvature (its links lost to zero visibility) keeps the part of its scale within
/// it, and the others still balance.
pub(super) const SCALE_RANGE: f64 = 2.0;

/// The closed rows' state.
#[derive(Debug, Default)]
pub(super) struct Closure {
    /// Per input patch: enclosed by front faces (empty: not decided yet), and the seed the rays
    /// were cast with.
    pub(super) enclosed: Vec<bool>,
    pub(super) seed: u64,
    /// Per element id: d of each leaf (1 on leaves of patches not enclosed; interior elements
    /// keep the value they had as leaves, the start of their children's). Empty: not balanced.
    pub(super) scale: Vec<f64>,
    /// Per element id: each leaf's balanced row d_x r_x, the row the power balance reads.
    pub(super) row: Vec<f64>,
    /// `scale` and `row` match the current links.
    pub(super) balanced: bool,
    /// Per element id: what it sends through a link, the area average of d·B over its leaves,
    /// and (with slopes) the first moment of d·B in its tangent basis.
    pub(super) sent: Vec<Rgb>,
    pub(super) sent_moment: Vec<[Rgb; 2]>,
    /// Scratch: world moments while pulling.
    world: Vec<[Rgb; 3]>,
    /// Iterations of the last balance and its largest |d r − 1| over the enclosed leaves.
    pub(super) iterations: u32,
    pub(super) residual: f64,
}

/// Rays for a patch of area `area` of a scene of area `total`.
#[must_use]
pub(super) fn enclosure_rays(area: f64, total: f64) -> u32 {
    let share = if total > 0.0 { (ENCLOSURE_RAY_BUDGET * area / total).ceil() } else { 0.0 };
    (f64::from(ENCLOSURE_MIN_RAYS) + share).min(f64::from(ENCLOSURE_MAX_RAYS)) as u32
}

/// Per input patch of `scene` (BVH `accel`): does every ray of its hemisphere meet a front face?
/// Keyed by the patch and `seed`: the same answer for any thread count.
#[must_use]
pub(super) fn enclosed_patches(scene: &Scene, accel: &Accel, seed: u64) -> Vec<bool> {
    let total = scene.total_area();
    scene
        .patches
        .par_iter()
        .enumerate()
        .with_min_len(16)
        .map(|(i, p)| {
            let region = Region { verts: &p.vertices, normal: p.normal, patch: i as u32 };
            let rays = enclosure_rays(p.area, total);
            let mut all = true;
            cast_hemisphere(scene, accel, region, rays, splitmix64(i as u64), seed ^ 0xC105_ED00, |hit| {
                all &= matches!(hit, Hit::Front(_));
            });
            all
        })
        .collect()
}

/// Area averages of the leaf values in `v` up the forest (parents have smaller ids than their
/// children), and with `slopes` each element's first moment Σ_leaves A v (c − c_e) / A_e in its
/// tangent basis into `moment` (`world` is scratch). Leaves' entries of `v` are read, interior
/// ones written.
fn pull<T>(els: &[Element], v: &mut [T], world: &mut Vec<[T; 3]>, moment: &mut Vec<[T; 2]>, slopes: bool)
where
    T: Copy + Default + std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>,
{
    let n = els.len();
    world.clear();
    world.resize(if slopes { n } else { 0 }, [T::default(); 3]);
    for i in (0..n).rev() {
        let first = els[i].first_child;
        if first == NONE {
            continue;
        }
        let (area, at) = (els[i].area, els[i].centroid);
        let mut s = T::default();
        let mut m = [T::default(); 3];
        for (k, c) in els[first as usize..first as usize + 4].iter().enumerate() {
            let w = c.area / area;
            let vc = v[first as usize + k];
            s = s + vc * w;
            if slopes {
                let d = (c.centroid - at) * w;
                let mc = world[first as usize + k];
                m = [m[0] + (mc[0] * w + vc * d.x), m[1] + (mc[1] * w + vc * d.y), m[2] + (mc[2] * w + vc * d.z)];
            }
        }
        v[i] = s;
        if slopes {
            world[i] = m;
        }
    }
    moment.clear();
    if slopes {
        moment.extend(els.iter().zip(world.iter()).map(|(e, m)| {
            if e.is_leaf() {
                return [T::default(); 2];
            }
            let (t1, t2) = crate::math::orthonormal_basis(e.normal);
            [m[0] * t1.x + m[1] * t1.y + m[2] * t1.z, m[0] * t2.x + m[1] * t2.y + m[2] * t2.z]
        }));
    }
}

impl HierarchicalSolver {
    /// Do the closed rows apply to this solve (`HierarchicalParams::close_rows`, not clustered,
    /// Jacobi gathers)?
    pub(super) fn closure_applies(&self) -> bool {
        self.params.close_rows && !self.params.gauss_seidel && !self.clustering()
    }

    /// Decide which input patches are enclosed (once per scene and seed).
    pub(super) fn closure_prepare(&mut self) {
        if self.closure_applies()
            && (self.closure.enclosed.len() != self.scene.patches.len() || self.closure.seed != self.params.seed)
        {
            let t = Instant::now();
            self.closure.enclosed = enclosed_patches(&self.scene, &self.accel, self.params.seed);
            if std::env::var_os("RADLAB_CLOSURE_DEBUG").is_some() {
                eprintln!("enclosure: {} of {} patches, {:.3} s", self.closure.enclosed.iter().filter(|&&e| e).count(), self.closure.enclosed.len(), t.elapsed().as_secs_f64());
            }
            self.closure.seed = self.params.seed;
        }
    }

    /// Forget the balance (the links are gone); which patches are enclosed stays.
    pub(super) fn closure_reset(&mut self) {
        let c = &mut self.closure;
        c.scale.clear();
        c.row.clear();
        c.sent.clear();
        c.sent_moment.clear();
        c.balanced = false;
    }

    /// Is the balance in use now (links exist and some patch is enclosed)?
    pub(super) fn closure_active(&self) -> bool {
        !self.closure.scale.is_empty()
    }

    /// One application of the leaves' operator to the leaf values `v` (by element id): each
    /// leaf's (K v)_x / A_x into `out`, the same sums in the same order as a gather and a push
    /// (pull, per receiver Σ F·V v plus the source moments' terms, push with the slopes).
    fn apply_operator(&self, plan: &GatherPlan, v: &[f64], out: &mut [(f64, f64)], scratch: &mut OperatorScratch) {
        let els = &self.hier.elements;
        let slopes = self.params.push_slopes;
        let OperatorScratch { value, world, moment, gathered, basis } = scratch;
        value.clear();
        value.extend_from_slice(v);
        pull(els, value, world, moment, slopes);
        let gamma = own_exponent();
        if gamma != 1.0 {
            for (x, e) in value.iter_mut().zip(els) {
                if e.is_leaf() {
                    *x = x.powf(gamma);
                }
            }
        }
        let (value, moment) = (&*value, &*moment);
        gathered.clear();
        gathered.par_extend((0..els.len()).into_par_iter().with_min_len(256).map(|r| plan.gather_scalar(r, value, moment)));
        // Push: the value at each element's centroid and its world gradient, parents first.
        let mut at: Vec<(f64, DVec3)> = Vec::with_capacity(els.len());
        for (i, e) in els.iter().enumerate() {
            let (g, [su, sv]) = gathered[i];
            let (up, grad) = if e.parent == NONE {
                (0.0, DVec3::ZERO)
            } else {
                let (pv, pg) = at[e.parent as usize];
                (pv + pg.dot(e.centroid - els[e.parent as usize].centroid), pg)
            };
            let grad = if slopes && (su != 0.0 || sv != 0.0) {
                let [t1, t2] = basis[i];
                grad + t1 * su + t2 * sv
            } else {
                grad
            };
            at.push((up + g, grad));
            if e.is_leaf() {
                out[i] = (g, up);
            }
        }
    }

    /// Balance the rows of the enclosed leaves for the current links (`plan`): the symmetric
    /// Sinkhorn–Knopp iteration from the last scale, until every enclosed leaf's row d r is within
    /// the tolerance of 1 ([`CLOSURE_TOL_SHARE`]) (leaves whose scale reached [`SCALE_RANGE`] aside) or
    /// [`CLOSURE_MAX_ITERATIONS`]. Then every leaf's balanced row is kept for the power balance.
    pub(super) fn balance_rows(&mut self, plan: &GatherPlan) {
        let t0 = Instant::now();
        let n = self.hier.len();
        let enclosed = &self.closure.enclosed;
        let els = &self.hier.elements;
        let part: Vec<u32> = els
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_leaf() && enclosed.get(e.patch as usize).copied().unwrap_or(false))
            .map(|(i, _)| i as u32)
            .collect();
        if part.is_empty() {
            self.closure_reset();
            self.closure.balanced = true;
            return;
        }
        // Each enclosed leaf's reach: |ln d| ≤ SCALE_REACH · max(|ln row|, SCALE_FLOOR) of its row
        // as it is (the chain's Σ F·V), at most ln SCALE_RANGE.
        let mut raw = vec![0.0; n];
        let gamma = own_exponent();
        // The raw row's log over its log-derivative in d: how far this leaf's scale alone would
        // move to close it (stored as the equivalent row).
        let each = |i: usize, e: &Element, _: Rgb, row: f64| {
            let up = row - e.fv_sum;
            let slope = if row > 0.0 { (gamma * e.fv_sum + up) / row } else { 1.0 };
            raw[i] = if row > 0.0 && slope > 0.0 { (row.ln() / slope).exp() } else { 0.0 };
        };
        if self.params.push_slopes {
            for_each_leaf_row(els, &mut Vec::<Chain>::new(), each);
        } else {
            for_each_leaf_row(els, &mut Vec::<FlatChain>::new(), each);
        }
        let (reach_k, range): (f64, f64) = (
            std::env::var("REACH").ok().and_then(|v| v.parse().ok()).unwrap_or(SCALE_REACH),
            std::env::var("RANGE").ok().and_then(|v| v.parse().ok()).unwrap_or(SCALE_RANGE),
        );
        let bounds: Vec<(f64, f64)> = part
            .iter()
            .map(|&x| {
                let row = raw[x as usize];
                let reach = if row > 0.0 {
                    (reach_k * row.ln().abs().max(SCALE_FLOOR)).min(range.ln())
                } else {
                    range.ln()
                };
                ((-reach).exp(), reach.exp())
            })
            .collect();
        let mut d = std::mem::take(&mut self.closure.scale);
        let old = d.len();
        d.resize(n, 1.0);
        for i in old..n {
            let p = els[i].parent;
            if p != NONE {
                d[i] = d[p as usize];
            }
        }
        for (&x, &(lo, hi)) in part.iter().zip(&bounds) {
            d[x as usize] = d[x as usize].clamp(lo, hi);
        }
        let mut scratch = OperatorScratch::default();
        scratch.basis = els
            .iter()
            .map(|e| {
                let (t1, t2) = crate::math::orthonormal_basis(e.normal);
                [t1, t2]
            })
            .collect();
        let tol = (CLOSURE_TOL_SHARE * self.params.tolerance).clamp(CLOSURE_TOL_MIN, CLOSURE_TOL_MAX);
        let mut r = vec![(0.0, 0.0); n];
        // The row with scale d: d^γ own + d inherited.
        let row_of = |dx: f64, (own, up): (f64, f64)| dx.powf(gamma) * own + dx * up;
        let mut iterations = 0;
        let mut anderson = Anderson::default();
        // Leaves the step would carry past their reach stay there for the rest of the balance
        // (the others then balance against them; extrapolating past a bound stalls the
        // acceleration, so its history restarts).
        let mut held = vec![false; part.len()];
        let residual = loop {
            self.apply_operator(plan, &d, &mut r, &mut scratch);
            let worst = part
                .iter()
                .zip(&held)
                .map(|(&x, &h)| {
                    if h || (gamma == 0.0 && r[x as usize].1 <= 0.0) { 0.0 } else { (row_of(d[x as usize], r[x as usize]) - 1.0).abs() }
                })
                .fold(0.0, f64::max);
            if worst <= tol || iterations >= CLOSURE_MAX_ITERATIONS {
                break worst;
            }
            // The step in ln d, x ← x − ω ln(d r), accelerated.
            let xs: Vec<f64> = part.iter().map(|&x| d[x as usize].ln()).collect();
            let fs: Vec<f64> = part
                .iter()
                .zip(&held)
                .map(|(&x, &h)| {
                    let dx = d[x as usize];
                    let (own, up) = r[x as usize];
                    let (mine, theirs) = (dx.powf(gamma) * own, dx * up);
                    let row = mine + theirs;
                    let slope = if row > 0.0 { (gamma * mine + theirs) / row } else { 0.0 };
                    if h || row <= 0.0 || slope <= 0.0 { 0.0 } else { -CLOSURE_STEP * row.ln() / slope }
                })
                .collect();
            let mut newly_held = false;
            for (((&x, &(lo, hi)), h), v) in part.iter().zip(&bounds).zip(&mut held).zip(anderson.step(xs, fs, worst)) {
                if *h {
                    continue;
                }
                let next = v.exp();
                if next <= lo || next >= hi {
                    *h = true;
                    newly_held = true;
                }
                d[x as usize] = next.clamp(lo, hi);
            }
            if newly_held {
                anderson.restart();
            }
            iterations += 1;
        };
        let mut row = std::mem::take(&mut self.closure.row);
        row.clear();
        row.extend(d.iter().zip(&r).map(|(&dx, &rx)| row_of(dx, rx)));
        if std::env::var_os("RADLAB_CLOSURE_DEBUG").is_some() {
            eprintln!("balance: {} leaves enclosed of {n} elements, {iterations} iterations, residual {residual:.2e}, {:.3} s, {} links", part.len(), t0.elapsed().as_secs_f64(), self.links.len());
            let lns: Vec<f64> = part.iter().map(|&x| d[x as usize].ln().abs()).collect();
            let mx = lns.iter().copied().fold(0.0, f64::max);
            let c = |t: f64| lns.iter().filter(|&&v| v > t).count();
            eprintln!("   |ln d| max {mx:.3}  >0.05: {}  >0.1: {}  >0.2: {}  >0.3: {}", c(0.05), c(0.1), c(0.2), c(0.3));
            let at = part.iter().zip(&bounds).filter(|(x, (lo, hi))| d[**x as usize] <= *lo || d[**x as usize] >= *hi).count();
            eprintln!("   at their reach: {at}");
        }
        let c = &mut self.closure;
        (c.scale, c.row, c.balanced, c.iterations, c.residual) = (d, row, true, iterations, residual);
    }

    /// What every element sends through a link while the rows are balanced: the area averages
    /// and first moments of d·B over its leaves (`Closure::sent`).
    pub(super) fn pull_sent(&mut self) {
        let c = &mut self.closure;
        let els = &self.hier.elements;
        c.sent.clear();
        c.sent.extend(els.iter().zip(&c.scale).map(|(e, d)| if e.is_leaf() { e.radiosity * *d } else { Rgb::ZERO }));
        pull(els, &mut c.sent, &mut c.world, &mut c.sent_moment, self.params.push_slopes);
        let gamma = own_exponent();
        if gamma != 1.0 {
            for ((x, e), d) in c.sent.iter_mut().zip(els).zip(&c.scale) {
                if e.is_leaf() {
                    *x = e.radiosity * d.powf(gamma);
                }
            }
        }
    }
}

/// Buffers of [`HierarchicalSolver::apply_operator`], kept over a balance's iterations.
#[derive(Default)]
struct OperatorScratch {
    value: Vec<f64>,
    world: Vec<[f64; 3]>,
    moment: Vec<[f64; 2]>,
    gathered: Vec<(f64, [f64; 2])>,
    /// Each element's tangent basis.
    basis: Vec<[DVec3; 2]>,
}

/// Anderson acceleration of the balance's fixed-point step x ← x + f(x) (x = ln d over the
/// enclosed leaves) [Anderson 1965; Walker & Ni 2011, "Anderson acceleration for fixed-point
/// iterations"]: the next iterate combines the last `depth` steps so that their residuals f
/// cancel as far as a least-squares fit allows. Sums run serially: the same result on any
/// thread count.
#[derive(Default)]
struct Anderson {
    /// The last iterate and residual, and the differences of the `depth` latest.
    last: Option<(Vec<f64>, Vec<f64>)>,
    dx: std::collections::VecDeque<Vec<f64>>,
    df: std::collections::VecDeque<Vec<f64>>,
    /// The smallest worst row residual so far (a step that makes it far worse restarts).
    best: f64,
}

impl Anderson {
    /// Forget the history: the next step is a plain one.
    fn restart(&mut self) {
        self.last = None;
        self.dx.clear();
        self.df.clear();
    }

    /// The next iterate from the iterate `x` and its residual `f` (the plain step is x + f);
    /// `worst` is the largest row residual at `x`.
    fn step(&mut self, x: Vec<f64>, f: Vec<f64>, worst: f64) -> Vec<f64> {
        if self.last.is_none() || worst > ANDERSON_RESTART * self.best {
            self.dx.clear();
            self.df.clear();
            self.best = worst;
        }
        self.best = self.best.min(worst);
        if let Some((x0, f0)) = self.last.take() {
            self.dx.push_back(x.iter().zip(&x0).map(|(a, b)| a - b).collect());
            self.df.push_back(f.iter().zip(&f0).map(|(a, b)| a - b).collect());
            if self.dx.len() > ANDERSON_DEPTH {
                self.dx.pop_front();
                self.df.pop_front();
            }
        }
        let k = self.df.len();
        let mut next: Vec<f64> = x.iter().zip(&f).map(|(a, b)| a + b).collect();
        if k > 0 {
            // Normal equations (ΔFᵀΔF + εI) γ = ΔFᵀ f, by Gaussian elimination with pivoting.
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let mut m = vec![vec![0.0; k + 1]; k];
            for i in 0..k {
                for j in 0..k {
                    m[i][j] = dot(&self.df[i], &self.df[j]);
                }
                m[i][k] = dot(&self.df[i], &f);
            }
            let scale = (0..k).map(|i| m[i][i]).fold(0.0, f64::max);
            for (i, row) in m.iter_mut().enumerate() {
                row[i] += 1e-10 * scale + f64::MIN_POSITIVE;
            }
            if let Some(g) = solve_small(m) {
                for i in 0..k {
                    for (v, (a, b)) in next.iter_mut().zip(self.dx[i].iter().zip(&self.df[i])) {
                        *v -= g[i] * (a + b);
                    }
                }
            }
        }
        self.last = Some((x, f));
        next
    }
}

/// Solve the k × (k + 1) augmented system `m` (Gaussian elimination, partial pivoting); None when
/// singular.
fn solve_small(mut m: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let k = m.len();
    for c in 0..k {
        let p = (c..k).max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))?;
        if m[p][c].abs() <= 0.0 || !m[p][c].is_finite() {
            return None;
        }
        m.swap(c, p);
        for r in c + 1..k {
            let f = m[r][c] / m[c][c];
            for j in c..=k {
                m[r][j] -= f * m[c][j];
            }
        }
    }
    let mut g = vec![0.0; k];
    for c in (0..k).rev() {
        let s: f64 = (c + 1..k).map(|j| m[c][j] * g[j]).sum();
        g[c] = (m[c][k] - s) / m[c][c];
    }
    Some(g)
}
