//! Closed rows: a point that front faces enclose sees them with its whole hemisphere, so its
//! form factors sum to one [Cohen & Wallace 1993, the form factors' summation relation],
//!
//! ```text
//! Σ_j F_xj V_xj = 1,        and with every surface E, ρ:  B = E + ρ B  ⇒  B = E / (1 − ρ)
//! ```
//!
//! (the white furnace). A leaf's row holds this only on average: it gathers through its own
//! links and its ancestors', each an average over a larger element moved along its slope, so
//! its row is off by the kernel's curvature across the ancestor (in a refined furnace, low at a
//! face's centre and high in its corners: docs/solver.md#closed-rows), and its radiosity follows
//! the row.
//!
//! ## How it works
//! The leaves' operator is symmetric: with K_xy = A_x × (the weight of B_y in leaf x's
//! irradiance H_x), a link and its mirror carry one coupling G ([`super::transfer`]) and their
//! slopes and source moments mirror each other ([`super::push_pull`]), so K_xy = K_yx. Each
//! link's end is either the leaf itself or one of its ancestors, and a link and its mirror have
//! the same two ends. On the leaves of enclosed patches the solver gathers through K', each
//! link's term scaled at both ends: by d_x^γ where the end is the leaf x itself, by d_x where it
//! is an ancestor of x (d = 1 on every other leaf), with d chosen so that the enclosed leaves'
//! rows sum to exactly 1:
//!
//! ```text
//! K'_xy = Σ_links s_x s_y K_xy,   s_x = d_x^γ (own end) or d_x (inherited end)
//! H_x   = d_x^γ Σ_own (K'/A_x) … + d_x Σ_inherited (K'/A_x) …      r_x(d) = Σ_y K'_xy / A_x = 1
//!
//!   gather:  a leaf sends d^γ·B through its own links; an interior element the area average
//!            and first moment of d·B over its leaves
//!   push:    a leaf's own irradiance × d_x^γ, its inherited rest × d_x
//!   balance: ln d_x ← ln d_x − ω ln r_x / (∂ ln r_x / ∂ ln d_x), r from one gather of d,
//!            until every |r_x − 1| is small
//! ```
//! K' is symmetric as K is, since both ends' factors are the link's own, so what a source sends
//! is still what its receivers gather: the power balance closes (Σ A B (1 − r) is the escaped
//! power), and an enclosed leaf, its row being 1, neither loses nor creates light. A one-sided
//! scale, H_x / r_x, makes the furnace exact too, but it is not reciprocal: it creates light in
//! closed rooms.
//!
//! The row's error is the inherited part's: a leaf's own links are evaluated at its own size
//! (their Galerkin coefficients to `link_tol`, [`super::transfer`]), its ancestors' are averages
//! over larger elements moved along their slopes, which miss the kernel's curvature across the
//! ancestor [Hanrahan, Salzman & Aupperle 1991, sec. 4; Lischinski, Smits & Greenberg 1994, "Bounds
//! and error estimates for radiosity"]. So the balance moves the inherited part, d, and the own
//! part only by [`OWN_EXPONENT`] of it: one factor on the whole row would scale a leaf's
//! accurate direct light by its inherited links' error, a mix of sources of different radiosity
//! (the per-leaf normalisation's bias, [`super`]). With γ = 1 (K' = D K D) the balance is the
//! symmetric Sinkhorn–Knopp iteration (ω = ½) [Sinkhorn & Knopp 1967; Knight 2008, "The
//! Sinkhorn–Knopp algorithm: convergence and applications"]; here it is over-relaxed
//! ([`CLOSURE_STEP`]), Anderson-accelerated ([`Anderson`]), and run after every change of the
//! links from the last d (new leaves start from their parent's).
//!
//! A patch is enclosed when none of the cosine-distributed rays cast from it
//! ([`crate::solver::escape::cast_hemisphere`], [`enclosure_rays`]) leaves the scene or meets a
//! back face: its row's target 1 is then known. A ceiling above a one-sided lamp sees the lamp's
//! back, an open box's walls see out: they keep their own rows. Off in clustered solves (cluster
//! links carry bounded approximations of their rows, `super::cluster`) and with Gauss–Seidel.

use super::HierarchicalSolver;
use super::gather::GatherPlan;
use super::push_pull::{Chain, FlatChain, for_each_leaf_row};
use crate::geometry::accel::Accel;
use crate::math::{DVec3, Rgb, splitmix64};
use crate::scene::Scene;
use crate::solver::escape::{HemisphereRays, Hit, Region, cast_hemisphere};
use crate::solver::hierarchy::{Element, NONE};
use crate::solver::params::HierarchicalParams;
use rayon::prelude::*;

/// γ, the share of a leaf's scale on its own links (d^γ; its inherited links take d). 0 would
/// leave a leaf that has only its own links no way to close its row, 1 scales its own links' light
/// by its ancestors' error; at ¼ the pointwise error of the closed rooms is that of γ = 0 and
/// below that of γ = 1 (docs/solver.md, "Closed rows"), and every leaf still balances.
pub(super) const OWN_EXPONENT: f64 = 0.25;

/// d^γ: a leaf's scale on its own links ([`OWN_EXPONENT`]).
#[inline]
pub(super) fn own_scale(d: f64) -> f64 {
    d.powf(OWN_EXPONENT)
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

/// The step's relaxation ω: ln d_x ← ln d_x − ω ln r_x / s_x, s_x = ∂ ln r_x / ∂ ln d_x (1 where
/// γ = 1: d_x ← d_x (d_x r_x)^(−ω)). Linearised about the balance, an error mode of the row
/// operator's eigenvalue λ shrinks by (1 − ω) − ωλ per step; the symmetric Sinkhorn–Knopp step
/// ω = ½ leaves ½(1 − λ), and ω = 0.7 is smaller for every λ ≤ 1 down to −1 (at 0.9 the
/// modes near λ = −1 overshoot).
pub(super) const CLOSURE_STEP: f64 = 0.7;

/// Steps that Anderson acceleration combines ([`Anderson`]): the plain step is slow on the modes
/// between facing surfaces that see mostly each other (a floor and a table's underside, λ near
/// −1); a few steps' history removes most of them, and a longer one gains little.
pub(super) const ANDERSON_DEPTH: usize = 6;

/// A step whose largest row residual is this many times the smallest so far restarts the
/// acceleration's history (a safeguard: the extrapolation went astray).
pub(super) const ANDERSON_RESTART: f64 = 4.0;

/// Iterations of the balance at most (each one gather of d; the refined furnace balances to
/// 1e-10 in a few tens, from scratch or after a refinement).
pub(super) const CLOSURE_MAX_ITERATIONS: u32 = 200;

/// How far the balance may move a leaf's scale: |ln d| ≤ SCALE_REACH · max(|ln r| / s,
/// SCALE_FLOOR), |ln r| / s how far its scale alone would move to close its row r of Σ F·V as it
/// is (s as in [`CLOSURE_STEP`]), and ≤ ln SCALE_RANGE. Where the exact balance asks more, a leaf
/// whose own row is nearly right is making up another's error through weak couplings: a pocket
/// whose two sides see mostly each other (a floor under a desk and the desk's underside) can
/// share only one coupling, so a mismatch of their rows falls on their little coupling to the
/// room, which the exact balance would scale far from 1. The furnace's balance stays well
/// within the reach.
pub(super) const SCALE_REACH: f64 = 3.0;
pub(super) const SCALE_FLOOR: f64 = 0.02;

/// d stays within [1 / SCALE_RANGE, SCALE_RANGE]: a leaf whose row is far from 1 for another
/// reason than curvature (its links lost to zero visibility) keeps the part of its scale within
/// it, and the others still balance.
pub(super) const SCALE_RANGE: f64 = 2.0;

/// The closed rows' state.
#[derive(Clone, Debug, Default)]
pub(super) struct Closure {
    /// Per input patch: enclosed by front faces (empty: not decided yet), and the seed the rays
    /// were cast with.
    pub(super) enclosed: Vec<bool>,
    pub(super) seed: u64,
    /// Per element id: d of each leaf (1 on leaves of patches not enclosed; interior elements
    /// keep the value they had as leaves, the start of their children's). Empty: not balanced.
    pub(super) scale: Vec<f64>,
    /// Per element id: each leaf's balanced row r_x(d), the row the power balance reads.
    pub(super) row: Vec<f64>,
    /// `scale` and `row` match the current links.
    pub(super) balanced: bool,
    /// Per element id: what it sends through a link, a leaf d^γ·B, an interior element the area
    /// average of d·B over its leaves and (with slopes) their first moment in its tangent basis.
    pub(super) sent: Vec<Rgb>,
    pub(super) sent_moment: Vec<[Rgb; 2]>,
    /// Scratch: world moments while pulling.
    world: Vec<[Rgb; 3]>,
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
            let set = HemisphereRays { region, rays, key: splitmix64(i as u64), seed: seed ^ 0xC105_ED00 };
            cast_hemisphere(scene, accel, set, |hit| {
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
                m = [
                    m[0] + (mc[0] * w + vc * d.x),
                    m[1] + (mc[1] * w + vc * d.y),
                    m[2] + (mc[2] * w + vc * d.z),
                ];
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
        self.setup.params.close_rows && !self.setup.params.gauss_seidel && !self.clustering()
    }
}

impl Closure {
    /// Decide which input patches of `scene` are enclosed (once per scene and seed).
    pub(super) fn prepare(&mut self, scene: &Scene, accel: &Accel, seed: u64) {
        if self.enclosed.len() != scene.patches.len() || self.seed != seed {
            self.enclosed = enclosed_patches(scene, accel, seed);
            self.seed = seed;
        }
    }

    /// Forget the balance (the links are gone); which patches are enclosed stays.
    pub(super) fn reset(&mut self) {
        self.scale.clear();
        self.row.clear();
        self.sent.clear();
        self.sent_moment.clear();
        self.balanced = false;
    }

    /// Is the balance in use now (links exist and some patch is enclosed)?
    pub(super) fn active(&self) -> bool {
        !self.scale.is_empty()
    }

    /// One application of the leaves' operator to the leaf values `v` (by element id): each
    /// leaf's (K v)_x / A_x into `out`, the same sums in the same order as a gather and a push
    /// (pull, per receiver Σ F·V v plus the source moments' terms, push with the slopes).
    fn apply_operator(
        els: &[Element],
        slopes: bool,
        plan: &GatherPlan,
        v: &[f64],
        out: &mut [(f64, f64)],
        scratch: &mut OperatorScratch,
    ) {
        let OperatorScratch { value, world, moment, gathered, basis } = scratch;
        value.clear();
        value.extend_from_slice(v);
        pull(els, value, world, moment, slopes);
        for (x, e) in value.iter_mut().zip(els) {
            if e.is_leaf() {
                *x = own_scale(*x);
            }
        }
        let (value, moment) = (&*value, &*moment);
        gathered.clear();
        gathered.par_extend(
            (0..els.len()).into_par_iter().with_min_len(256).map(|r| plan.gather_scalar(r, value, moment)),
        );
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

    /// Balance the rows of the enclosed leaves for the current links (`plan`): the iteration of
    /// the module doc from the last scale, until every enclosed leaf's row r(d) is within the
    /// tolerance of 1 ([`CLOSURE_TOL_SHARE`]; leaves whose scale reached its reach,
    /// [`SCALE_REACH`], aside) or [`CLOSURE_MAX_ITERATIONS`]. Then every leaf's balanced row is
    /// kept for the power balance.
    pub(super) fn balance_rows(&mut self, els: &[Element], params: &HierarchicalParams, plan: &GatherPlan) {
        let n = els.len();
        let enclosed = &self.enclosed;
        let part: Vec<u32> = els
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_leaf() && enclosed.get(e.patch as usize).copied().unwrap_or(false))
            .map(|(i, _)| i as u32)
            .collect();
        if part.is_empty() {
            self.reset();
            self.balanced = true;
            return;
        }
        // Each enclosed leaf's reach ([`SCALE_REACH`]) from its row as it is (the chain's Σ F·V):
        // the row's log over its log-derivative in d, how far this leaf's scale alone would move
        // to close it, stored as the equivalent row.
        let mut raw = vec![0.0; n];
        let each = |i: usize, e: &Element, _: Rgb, row: f64| {
            let up = row - e.fv_sum;
            let slope = if row > 0.0 { (OWN_EXPONENT * e.fv_sum + up) / row } else { 1.0 };
            raw[i] = if row > 0.0 && slope > 0.0 { (row.ln() / slope).exp() } else { 0.0 };
        };
        if params.push_slopes {
            for_each_leaf_row(els, &mut Vec::<Chain>::new(), each);
        } else {
            for_each_leaf_row(els, &mut Vec::<FlatChain>::new(), each);
        }
        let bounds: Vec<(f64, f64)> = part
            .iter()
            .map(|&x| {
                let row = raw[x as usize];
                let reach = if row > 0.0 {
                    (SCALE_REACH * row.ln().abs().max(SCALE_FLOOR)).min(SCALE_RANGE.ln())
                } else {
                    SCALE_RANGE.ln()
                };
                ((-reach).exp(), reach.exp())
            })
            .collect();
        let mut d = std::mem::take(&mut self.scale);
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
        let mut scratch = OperatorScratch {
            basis: els
                .iter()
                .map(|e| {
                    let (t1, t2) = crate::math::orthonormal_basis(e.normal);
                    [t1, t2]
                })
                .collect(),
            ..OperatorScratch::default()
        };
        let tol = (CLOSURE_TOL_SHARE * params.tolerance).clamp(CLOSURE_TOL_MIN, CLOSURE_TOL_MAX);
        let mut r = vec![(0.0, 0.0); n];
        // The row with scale d: d^γ own + d inherited.
        let row_of = |dx: f64, (own, up): (f64, f64)| own_scale(dx) * own + dx * up;
        let mut iterations = 0;
        let mut anderson = Anderson::default();
        // Leaves the step would carry past their reach stay there for the rest of the balance
        // (the others then balance against them; extrapolating past a bound stalls the
        // acceleration, so its history restarts).
        let mut held = vec![false; part.len()];
        loop {
            Self::apply_operator(els, params.push_slopes, plan, &d, &mut r, &mut scratch);
            let worst = part
                .iter()
                .zip(&held)
                .map(|(&x, &h)| if h { 0.0 } else { (row_of(d[x as usize], r[x as usize]) - 1.0).abs() })
                .fold(0.0, f64::max);
            if worst <= tol || iterations >= CLOSURE_MAX_ITERATIONS {
                break;
            }
            // The step in ln d, x ← x − ω ln r / s (s = ∂ ln r / ∂ ln d), accelerated.
            let xs: Vec<f64> = part.iter().map(|&x| d[x as usize].ln()).collect();
            let fs: Vec<f64> = part
                .iter()
                .zip(&held)
                .map(|(&x, &h)| {
                    let dx = d[x as usize];
                    let (own, up) = r[x as usize];
                    let (mine, theirs) = (own_scale(dx) * own, dx * up);
                    let row = mine + theirs;
                    let slope = if row > 0.0 { (OWN_EXPONENT * mine + theirs) / row } else { 0.0 };
                    if h || row <= 0.0 || slope <= 0.0 { 0.0 } else { -CLOSURE_STEP * row.ln() / slope }
                })
                .collect();
            let mut newly_held = false;
            for (((&x, &(lo, hi)), h), v) in
                part.iter().zip(&bounds).zip(&mut held).zip(anderson.step(xs, fs, worst))
            {
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
        }
        let mut row = std::mem::take(&mut self.row);
        row.clear();
        row.extend(d.iter().zip(&r).map(|(&dx, &rx)| row_of(dx, rx)));
        (self.scale, self.row, self.balanced) = (d, row, true);
    }

    /// What every element sends through a link while the rows are balanced (`Closure::sent`).
    pub(super) fn pull_sent(&mut self, els: &[Element], slopes: bool) {
        self.sent.clear();
        self.sent.extend(
            els.iter().zip(&self.scale).map(|(e, d)| if e.is_leaf() { e.radiosity * *d } else { Rgb::ZERO }),
        );
        pull(els, &mut self.sent, &mut self.world, &mut self.sent_moment, slopes);
        for ((x, e), d) in self.sent.iter_mut().zip(els).zip(&self.scale) {
            if e.is_leaf() {
                *x = e.radiosity * own_scale(*d);
            }
        }
    }
}

/// Buffers of [`Closure::apply_operator`], kept over a balance's iterations.
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
            // Normal equations (ΔFᵀΔF + εI) g = ΔFᵀ f, by Gaussian elimination with pivoting.
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let mut m: Vec<Vec<f64>> = self
                .df
                .iter()
                .map(|di| self.df.iter().map(|dj| dot(di, dj)).chain([dot(di, &f)]).collect())
                .collect();
            let scale = m.iter().enumerate().map(|(i, row)| row[i]).fold(0.0, f64::max);
            for (i, row) in m.iter_mut().enumerate() {
                row[i] += 1e-10 * scale + f64::MIN_POSITIVE;
            }
            if let Some(g) = solve_small(m) {
                for ((gi, dx), df) in g.iter().zip(&self.dx).zip(&self.df) {
                    for (v, (a, b)) in next.iter_mut().zip(dx.iter().zip(df)) {
                        *v -= gi * (a + b);
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
        let (top, below) = m.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in below {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
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
