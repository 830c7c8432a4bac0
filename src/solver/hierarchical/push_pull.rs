//! Push-pull (HSA91, sec. 4): push each element's gathered irradiance down to its leaves (with the
//! links' slopes when `push_slopes` is on), reflect there, and pull the area-weighted average
//! back up, so every level holds a consistent radiosity:
//!
//! ```text
//! push: H_leaf = Σ_{a = leaf or an ancestor} [ gathered_a + slope_a · (c_leaf − c_a) ]
//!       B_leaf = E_leaf + ρ_leaf H_leaf
//! pull: B_parent = Σ_children (A_child / A_parent) B_child
//! ```
//! Both moves are area-weighted and exact: a gather followed by push-pull moves no power
//! between levels. The same sweep sums the power balance (`EnergyBalance`): absorbed
//! Σ A (1 − ρ) H and escaped Σ A B (1 − Σ F·V of the leaf's row).

use super::closure::Closure;
use super::oracle::{self, Kernels};
use super::parts::PushPullState;
use super::{HierarchicalSolver, LeafRow, StepKind, StepReport};
use crate::math::{DVec3, Rgb};
use crate::solver::hierarchy::{Element, Hierarchy, NONE};
use crate::solver::link::LinkStore;
use rayon::prelude::*;
use std::time::Instant;

/// Sums an element inherits in push-pull, its own included.
#[derive(Copy, Clone, Debug, Default)]
pub(super) struct Chain {
    /// Irradiance through fully visible links, at `at`.
    pub(super) full: Rgb,
    /// The other irradiance, at `at` (with the slopes' shift to `at`).
    pub(super) rest: Rgb,
    /// World gradient of the irradiance (x, y, z components, each per channel).
    pub(super) slope: [Rgb; 3],
    /// The point the sums are evaluated at: the centroid of the chain's last element.
    pub(super) at: DVec3,
    pub(super) f: f64,
    pub(super) fv_partial: f64,
    /// World gradient of the row Σ F·V (the own links' `fv_slope`s), and the inherited rows'
    /// shift along it to `at` (included in the energy balance's Σ F·V).
    pub(super) fv_slope: DVec3,
    pub(super) fv_shift: f64,
}

impl Chain {
    /// `then` without slopes (`push_slopes` off: SPLASH-2's constants), at the cost it had
    /// before slopes existed.
    fn then_flat(self, e: &Element) -> Chain {
        Chain {
            full: self.full + e.gathered_full,
            rest: self.rest + (e.gathered - e.gathered_full),
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
            ..Chain::default()
        }
    }

    /// `then` or `then_flat`.
    pub(super) fn step(self, e: &Element, slopes: bool) -> Chain {
        if slopes { self.then(e) } else { self.then_flat(e) }
    }

    /// The sums of element `e`, whose parent's are `self`: the inherited irradiance moved along
    /// its slope from the parent's centroid to e's, plus e's own.
    fn then(self, e: &Element) -> Chain {
        let d = e.centroid - self.at;
        let shift = self.slope[0] * d.x + self.slope[1] * d.y + self.slope[2] * d.z;
        let [su, sv] = e.gathered_slope;
        let [fu, fv] = e.fv_slope;
        let (t1, t2) = if su == Rgb::ZERO && sv == Rgb::ZERO && fu == 0.0 && fv == 0.0 {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            crate::math::orthonormal_basis(e.normal)
        };
        Chain {
            full: self.full + e.gathered_full,
            rest: self.rest + shift + (e.gathered - e.gathered_full),
            slope: [
                self.slope[0] + su * t1.x + sv * t2.x,
                self.slope[1] + su * t1.y + sv * t2.y,
                self.slope[2] + su * t1.z + sv * t2.z,
            ],
            at: e.centroid,
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
            fv_slope: self.fv_slope + t1 * fu + t2 * fv,
            fv_shift: self.fv_shift + self.fv_slope.dot(d),
        }
    }
}

/// What push-pull carries down a chain of ancestors: [`Chain`] with slopes, [`FlatChain`]
/// without (`push_slopes` off: a quarter of the bytes written per element, which is what
/// SPLASH-2's push-pull costs).
pub(super) trait Sums: Copy + Default {
    /// The sums of element `e`, whose parent's are `self`.
    fn down(self, e: &Element) -> Self;
    /// The irradiance at the element (full + rest).
    fn irradiance(&self) -> Rgb;
    /// Σ F·V inherited from the ancestors (full F plus partial F·V).
    fn inherited_fv(&self) -> f64;
    /// The slopes' shift of the inherited row to the element's centroid.
    fn fv_shift(&self) -> f64;
}

impl Sums for Chain {
    fn down(self, e: &Element) -> Self {
        self.then(e)
    }
    fn irradiance(&self) -> Rgb {
        self.full + self.rest
    }
    fn inherited_fv(&self) -> f64 {
        self.f + self.fv_partial
    }
    fn fv_shift(&self) -> f64 {
        self.fv_shift
    }
}

/// [`Chain`] without slopes.
#[derive(Copy, Clone, Debug, Default)]
pub(super) struct FlatChain {
    full: Rgb,
    rest: Rgb,
    f: f64,
    fv_partial: f64,
}

impl Sums for FlatChain {
    fn down(self, e: &Element) -> Self {
        FlatChain {
            full: self.full + e.gathered_full,
            rest: self.rest + (e.gathered - e.gathered_full),
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
        }
    }
    fn irradiance(&self) -> Rgb {
        self.full + self.rest
    }
    fn inherited_fv(&self) -> f64 {
        self.f + self.fv_partial
    }
    fn fv_shift(&self) -> f64 {
        0.0
    }
}

/// The down sweep of push-pull over the whole forest (parents before children): each
/// element's sums from its parent's; each leaf's radiosity B = E + ρ·H and, with `energy`, its
/// absorbed and escaped power. With the rows closed (`super::closure`; both slices by element
/// id, empty otherwise) a leaf's H is its chain's scaled by [`leaf_irradiance`], and its row is
/// `rows`'.
/// Returns (largest leaf change against `before` or the old value, largest reflected
/// radiosity, absorbed, escaped).
pub(super) fn push_down<S: Sums>(
    els: &mut [Element],
    chain: &mut Vec<S>,
    before: Option<&[Rgb]>,
    energy: bool,
    (scale, rows): (&[f64], &[f64]),
) -> (f64, f64, Rgb, Rgb) {
    let mut max_change: f64 = 0.0;
    let mut max_reflected: f64 = 0.0;
    let mut absorbed = Rgb::ZERO;
    let mut escaped = Rgb::ZERO;
    chain.clear();
    chain.reserve(els.len());
    for (i, e) in els.iter_mut().enumerate() {
        let up = if e.parent == NONE { S::default() } else { chain[e.parent as usize] };
        let own = up.down(e);
        chain.push(own);
        if e.is_leaf() {
            let h = leaf_irradiance(own.irradiance(), e.gathered, scale, i);
            let b = e.emission + e.reflectance.mul_rgb(h);
            let old = before.and_then(|v| v.get(i).copied()).unwrap_or(e.radiosity);
            max_change = max_change.max(b.abs_diff_max(old));
            max_reflected = max_reflected.max((b - e.emission).max_channel());
            if energy {
                absorbed += (Rgb::ONE - e.reflectance).mul_rgb(h) * e.area;
                let fv =
                    rows.get(i).copied().unwrap_or_else(|| up.inherited_fv() + e.fv_sum + own.fv_shift());
                escaped += b * (e.area * (1.0 - fv));
            }
            e.radiosity = b;
            e.b_max = b.max_channel();
        }
    }
    (max_change, max_reflected, absorbed, escaped)
}

/// Every leaf of the elements as they are, with its irradiance H and its row Σ F·V (own and
/// inherited links, with the slopes' shift): `f(id, leaf, H, row)`, leaves in id order.
pub(super) fn for_each_leaf_row<S: Sums>(
    els: &[Element],
    chain: &mut Vec<S>,
    mut f: impl FnMut(usize, &Element, Rgb, f64),
) {
    chain.clear();
    chain.reserve(els.len());
    for (i, e) in els.iter().enumerate() {
        let up = if e.parent == NONE { S::default() } else { chain[e.parent as usize] };
        let own = up.down(e);
        chain.push(own);
        if e.is_leaf() {
            f(i, e, own.irradiance(), up.inherited_fv() + e.fv_sum + own.fv_shift());
        }
    }
}

/// A leaf's irradiance `h` (its chain's), of which `own` came through its own links: where the
/// rows are closed (`scale` by element id; empty: none are), the own part times d^γ and the
/// inherited rest times d (`super::closure`).
pub(super) fn leaf_irradiance(h: Rgb, own: Rgb, scale: &[f64], id: usize) -> Rgb {
    match scale.get(id) {
        Some(&d) => own * super::closure::own_scale(d) + (h - own) * d,
        None => h,
    }
}

/// The absorbed and escaped power of the elements as they are (see `energy_pass`), with the
/// closed rows' `scale` and `rows` as in [`push_down`].
pub(super) fn energy_sums<S: Sums>(
    els: &[Element],
    chain: &mut Vec<S>,
    (scale, rows): (&[f64], &[f64]),
) -> (Rgb, Rgb) {
    let mut absorbed = Rgb::ZERO;
    let mut escaped = Rgb::ZERO;
    for_each_leaf_row(els, chain, |i, e, h, fv| {
        let h = leaf_irradiance(h, e.gathered, scale, i);
        let fv = rows.get(i).copied().unwrap_or(fv);
        absorbed += (Rgb::ONE - e.reflectance).mul_rgb(h) * e.area;
        escaped += e.radiosity * (e.area * (1.0 - fv));
    });
    (absorbed, escaped)
}

/// Rows within this of 1 are never flagged by the row check (rounding of f32 form factors and
/// the quadrature's tolerance).
pub(super) const ROW_SLACK: f64 = 1e-3;

/// The row check's excess (see `HierarchicalParams::row_tol`): per inner element, the largest
/// Σ F·V − 1 over the leaves below it (the same row as the energy balance's) where that exceeds
/// [`ROW_SLACK`] and adds more than `eps` to the leaf's answer (ρ · H · excess / row: a dim
/// corner's excess moves little light), else 0; 0 for leaves.
pub(super) fn row_excess<S: Sums>(els: &[Element], chain: &mut Vec<S>, eps: f64) -> Vec<f32> {
    // A leaf marks its parent; a leaf keeps no excess of its own: its own links are its exact
    // averages, and splitting them would not move the inherited ones.
    let mut ex = vec![0.0f32; els.len()];
    for_each_leaf_row(els, chain, |_, e, h, row| {
        let over = row - 1.0;
        // What the excess adds to the leaf's answer: ρ times its share of the irradiance.
        let err = e.reflectance.max_channel() * h.max_channel() * over / row;
        if over > ROW_SLACK && err > eps && e.parent != NONE {
            let p = &mut ex[e.parent as usize];
            *p = p.max(over as f32);
        }
    });
    // Up the ancestors (parents have smaller ids than their children).
    for i in (0..els.len()).rev() {
        let p = els[i].parent;
        if p != NONE && ex[i] > ex[p as usize] {
            ex[p as usize] = ex[i];
        }
    }
    ex
}

impl HierarchicalSolver {
    /// The row check's excess of every element now (empty when `row_tol` is 0).
    pub(super) fn row_excess_now(&mut self) -> Vec<f32> {
        let eps = self.setup.params.row_tol * self.mean_reflected();
        self.push_pull.row_excess(&self.hier.elements, self.setup.params.push_slopes, eps)
    }

    /// Every leaf's row of F·V as the power balance reads it, in id order ([`LeafRow`]): with
    /// the rows closed, the balanced row d_x r_x (`super::closure`).
    #[must_use]
    pub fn leaf_rows(&self) -> Vec<LeafRow> {
        let mut rows = Vec::new();
        let cluster = &self.cluster.fv;
        let closed = &self.closure.row;
        let mut each = |i: usize, e: &Element, _: Rgb, row: f64| {
            let cluster = cluster.get(e.patch as usize).copied().unwrap_or(0.0);
            let row = closed.get(i).copied().unwrap_or(row);
            rows.push(LeafRow { id: i as u32, row, cluster });
        };
        if self.setup.params.push_slopes {
            for_each_leaf_row(&self.hier.elements, &mut Vec::<Chain>::new(), &mut each);
        } else {
            for_each_leaf_row(&self.hier.elements, &mut Vec::<FlatChain>::new(), &mut each);
        }
        rows
    }

    /// The radiosity of every element (indexed by id) that `push_pull_step` would give now, the
    /// solver's state untouched: what a viewer shows right after a gather. The same chain sums
    /// (with the links' slopes) and area averages as `push_pull_flat`.
    #[must_use]
    pub fn push_pull_preview(&self) -> Vec<Rgb> {
        let els = &self.hier.elements;
        let scale = &self.closure.scale;
        let mut b: Vec<Rgb> = els
            .iter()
            .zip(self.chains())
            .enumerate()
            .map(|(i, (e, c))| {
                if e.is_leaf() {
                    e.emission + e.reflectance.mul_rgb(leaf_irradiance(c.full + c.rest, e.gathered, scale, i))
                } else {
                    Rgb::ZERO
                }
            })
            .collect();
        for i in (0..els.len()).rev() {
            let first = els[i].first_child;
            if first != NONE {
                let area = els[i].area;
                b[i] = (first as usize..first as usize + 4)
                    .fold(Rgb::ZERO, |s, c| s + b[c] * (els[c].area / area));
            }
        }
        b
    }

    /// Push gathered irradiance down to the leaves (B = E + ρ·H), pull area averages up.
    pub fn push_pull_step(&mut self) -> StepReport {
        let t = Instant::now();
        self.push_pull_flat(None, true);
        self.log.stats.push_pull_s += t.elapsed().as_secs_f64();
        self.report(StepKind::PushPull, t, 0, 0)
    }

    /// Push-pull over the whole forest ([`PushPullState::run`]), its residual and power sums
    /// into the log.
    pub(super) fn push_pull_flat(&mut self, before: Option<&[Rgb]>, energy: bool) {
        let pushed = self.push_pull.run(
            &mut self.hier.elements,
            &self.closure,
            self.setup.params.push_slopes,
            before,
            energy,
        );
        self.log.record_push(pushed, self.setup.params.tolerance);
    }

    /// The absorbed and escaped power of the current state, as the last push-pull would have
    /// summed them: for `solve`, whose iterations skip these sums until the end.
    pub(super) fn energy_pass(&mut self) {
        let (absorbed, escaped) =
            self.push_pull.energy(&self.hier.elements, &self.closure, self.setup.params.push_slopes);
        self.log.energy.absorbed = absorbed;
        self.log.energy.escaped = escaped;
    }
}

/// Fill `Link::slope` of every link of `links` that has none yet (parallel over receivers; a link's
/// slope depends on its two elements and V only, so it is computed once per link).
pub(super) fn fill_slopes(
    hier: &mut Hierarchy,
    links: &mut LinkStore,
    kernels: &[Kernels],
    vis: Option<&VisSlopes<'_>>,
) -> u64 {
    // Each element's frame, made once for all the links it is an end of.
    let frames: Vec<oracle::SlopeFrame> = hier.elements.par_iter().map(oracle::SlopeFrame::of).collect();
    let sums: Vec<([f64; 2], u64)> = links
        .by_receiver
        .par_iter_mut()
        .enumerate()
        .with_min_len(64)
        .map(|(r, ls)| {
            let re = hier.get(r as u32);
            let mut cast = 0;
            let mut last = crate::geometry::accel::NO_HIT;
            for l in ls.iter_mut().filter(|l| !l.slope_set) {
                let v = f64::from(l.vis).clamp(0.0, 1.0);
                let se = hier.get(l.source);
                let g = f64::from(l.g);
                let s = l.source;
                let partial = v > 0.0 && v < 1.0 && !l.unmeasured;
                // Both sides from the same inputs as the mirror link's: bit-identical. A side's
                // slope reads V at its child points where the link's penumbra matters to it
                // (`VisSlopes`).
                let mut side = |x: u32, xe: &Element, ye: &Element, y: u32| {
                    let (frame, known) = (&frames[x as usize], oracle::known_kernel(kernels, x, y));
                    let read = vis
                        .filter(|_| partial)
                        .and_then(|vs| vs.read(frame, (x, xe), (y, ye), v, g, &mut cast, &mut last));
                    oracle::kernel_slope(frame, xe, ye, v, g / xe.area, known, read.as_ref())
                        .map(|x| x as f32)
                };
                (l.slope, l.src_slope) = if v > 0.0 {
                    (side(r as u32, re, se, s), side(s, se, re, r as u32))
                } else {
                    ([0.0; 2], [0.0; 2])
                };
                l.slope_set = true;
            }
            // Over every own link (a split may have removed some since the last fill).
            (
                ls.iter().fold([0.0; 2], |[u, v], l| [u + f64::from(l.slope[0]), v + f64::from(l.slope[1])]),
                cast,
            )
        })
        .collect();
    let mut cast = 0;
    for (e, (s, c)) in hier.elements.iter_mut().zip(sums) {
        e.fv_slope = s;
        cast += c;
    }
    cast
}

/// Where a partially visible link's slope reads V at the receiver's child points
/// ([`oracle::kernel_slope`]): on a side whose answer the link's penumbra can make wrong,
/// ρ_x F_x B_y 2 min(V, 1 − V) > `floor`, with `rays` kernel-weighted rays from each point.
pub(super) struct VisSlopes<'a> {
    pub accel: &'a crate::geometry::accel::Accel,
    pub seed: u64,
    pub rays: u32,
    pub floor: f64,
}

impl VisSlopes<'_> {
    /// V at x's child points towards y, and x's irradiance in units of y's radiosity (what
    /// keeps x's total ≥ 0), if the link matters enough to x (else None).
    #[allow(clippy::too_many_arguments)]
    fn read(
        &self,
        frame: &oracle::SlopeFrame,
        (x, xe): (u32, &Element),
        (y, ye): (u32, &Element),
        v: f64,
        g: f64,
        cast: &mut u64,
        last: &mut u32,
    ) -> Option<oracle::VisRead> {
        let weight = 2.0 * v.min(1.0 - v);
        let matters =
            xe.reflectance.max_channel() * (g / xe.area) * ye.radiosity.max_channel() * weight > self.floor;
        if !matters {
            return None;
        }
        let (at, c) = crate::geometry::visibility::point_fractions(
            self.accel,
            oracle::frame_points(frame),
            (xe.patch, xe.normal),
            (ye.vertices(), ye.patch, ye.normal),
            self.rays,
            self.seed,
            super::refine::pair_key(x, y),
            last,
        );
        *cast += c;
        let h = (xe.radiosity - xe.emission).max_channel() / xe.reflectance.max_channel().max(1e-12);
        Some(oracle::VisRead { at, rest: h / ye.radiosity.max_channel().max(1e-300) })
    }
}

/// Push-pull of the subtree of `id` (recursive): `up`, the irradiance inherited from the
/// ancestors (`Chain`); `slopes`: with the links' slopes. Returns the element's radiosity.
pub(super) fn push_pull_rec(els: &mut [Element], id: u32, up: Chain, slopes: bool) -> Rgb {
    let e = &els[id as usize];
    let own = up.step(e, slopes);
    if let Some(kids) = e.children() {
        let area = e.area;
        let mut b = Rgb::ZERO;
        let mut b_max: f64 = 0.0;
        for c in kids {
            let bc = push_pull_rec(els, c, own, slopes);
            let child = &els[c as usize];
            b += bc * (child.area / area);
            b_max = b_max.max(child.b_max);
        }
        let e = &mut els[id as usize];
        e.radiosity = b;
        e.b_max = b_max;
        b
    } else {
        let b = e.emission + e.reflectance.mul_rgb(own.full + own.rest);
        let e = &mut els[id as usize];
        e.radiosity = b;
        e.b_max = b.max_channel();
        b
    }
}

/// What one push-pull found: the residual (the largest leaf change relative to the largest
/// reflected radiosity) and, when summed, the absorbed and escaped power.
#[derive(Copy, Clone, Debug)]
pub(super) struct Pushed {
    pub(super) residual: f64,
    pub(super) energy: Option<(Rgb, Rgb)>,
}

impl PushPullState {
    /// Push-pull over the whole forest in two flat sweeps (parents have smaller ids than their
    /// children): down in id order, each element's inherited sums from its parent's, leaves'
    /// radiosity B = E + ρ·(H_full + H_rest) and their energy terms; then up in reverse
    /// order, area averages. The same values as `push_pull_rec` from every root. The residual is
    /// the largest leaf change against `before` (default: the values before this call), and the
    /// power sums are made only with `energy`. The `closure`'s scales apply where it is active.
    pub(super) fn run(
        &mut self,
        els: &mut [Element],
        closure: &Closure,
        slopes: bool,
        before: Option<&[Rgb]>,
        energy: bool,
    ) -> Pushed {
        let n = els.len();
        // Per element: its own and inherited sums (full-visibility irradiance, other irradiance,
        // full-visibility F, other F·V; with slopes, their gradients).
        let closed = (&closure.scale[..], &closure.row[..]);
        let (max_change, max_reflected, absorbed, escaped) = if slopes {
            push_down(els, &mut self.chain, before, energy, closed)
        } else {
            push_down(els, &mut self.flat_chain, before, energy, closed)
        };
        // With the rows closed the gather pulls its own moments, of the scaled B (`pull_sent`).
        let slopes = slopes && !closure.active();
        // World moments Σ_leaves A B (c − c_e) / A_e while pulling (leaves: 0), then each in its
        // element's tangent basis.
        let world = &mut self.moment_world;
        world.clear();
        world.resize(if slopes { n } else { 0 }, [Rgb::ZERO; 3]);
        for i in (0..n).rev() {
            let first = els[i].first_child;
            if first == NONE {
                continue;
            }
            let (area, at) = (els[i].area, els[i].centroid);
            let mut b = Rgb::ZERO;
            let mut b_max: f64 = 0.0;
            let mut m = [Rgb::ZERO; 3];
            for (k, c) in els[first as usize..first as usize + 4].iter().enumerate() {
                let w = c.area / area;
                b += c.radiosity * w;
                b_max = b_max.max(c.b_max);
                if slopes {
                    let d = (c.centroid - at) * w;
                    let mc = world[first as usize + k];
                    m[0] += mc[0] * w + c.radiosity * d.x;
                    m[1] += mc[1] * w + c.radiosity * d.y;
                    m[2] += mc[2] * w + c.radiosity * d.z;
                }
            }
            els[i].radiosity = b;
            els[i].b_max = b_max;
            if slopes {
                world[i] = m;
            }
        }
        self.moment.clear();
        if slopes {
            self.moment.par_extend(els.par_iter().zip(world.par_iter()).with_min_len(1024).map(|(e, m)| {
                if e.is_leaf() {
                    return [Rgb::ZERO; 2];
                }
                let (t1, t2) = crate::math::orthonormal_basis(e.normal);
                [m[0] * t1.x + m[1] * t1.y + m[2] * t1.z, m[0] * t2.x + m[1] * t2.y + m[2] * t2.z]
            }));
        }
        let residual = if max_reflected > 0.0 { max_change / max_reflected } else { max_change };
        Pushed { residual, energy: energy.then_some((absorbed, escaped)) }
    }

    /// The absorbed and escaped power of the elements as they are, as the last push-pull would
    /// have summed them (the same terms in the same order, with each leaf's B as it left them).
    pub(super) fn energy(&mut self, els: &[Element], closure: &Closure, slopes: bool) -> (Rgb, Rgb) {
        let closed = (&closure.scale[..], &closure.row[..]);
        if slopes {
            energy_sums(els, &mut self.chain, closed)
        } else {
            energy_sums(els, &mut self.flat_chain, closed)
        }
    }

    /// The row check's excess of every element of `els` ([`row_excess`]; empty when `eps` ≤ 0).
    pub(super) fn row_excess(&mut self, els: &[Element], slopes: bool, eps: f64) -> Vec<f32> {
        if eps <= 0.0 {
            Vec::new()
        } else if slopes {
            row_excess(els, &mut self.chain, eps)
        } else {
            row_excess(els, &mut self.flat_chain, eps)
        }
    }
}
