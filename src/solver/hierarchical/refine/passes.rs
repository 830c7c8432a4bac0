//! `Refine` as passes over the link lists, until nothing splits [HSA91, sec. 4]:
//! ```text
//! A (parallel, read-only)  a verdict per receiver: keep / split source / split receiver
//! B (sorted ids)           split the chosen elements → deterministic element ids
//! C (parallel)             the replacement links (coupling, visibility, verdicts)
//! D (receiver order)       install them; the next pass examines exactly the new links
//! ```
//! Before the first pass a refinement links the input patches (or clusters) once, or refines
//! the cluster links; after the last it records why each leaf stopped and updates the sums
//! and the gather plan where the link lists changed.

use super::replace::Replaced;
use super::verdict::{IdSet, ReceiverDecision, Split, Verdict};
use crate::solver::hierarchical::gather::update_sums;
use crate::solver::hierarchical::{HierarchicalSolver, StepKind, StepReport, disjoint_mut, oracle};
use crate::solver::hierarchy::StopReason;
use crate::solver::link::Link;
use crate::solver::params::Oracle;
use rayon::prelude::*;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// The share of the links a budget has left that the pass reaching it plans to add
/// (`cut_to_budget`).
const BUDGET_MARGIN: f64 = 0.95;

/// Receivers whose link lists the oracle's first pass loads together (see `decide_all`).
pub(super) const TOUCH_AHEAD: usize = 16;

/// What one refinement carries from pass to pass.
struct Refinement {
    /// Links created, and elements split, by this refinement.
    new_links: usize,
    refined: usize,
    /// Links in all the lists now (the budget's count).
    total_links: usize,
    /// Receivers whose link lists changed (their sums and gather plan are updated at the end).
    changed: IdSet,
    /// The gather plan was whole before this refinement (it is then updated, not rebuilt).
    plan_whole: bool,
    /// Per element, the strongest reason among the links it keeps, over all passes.
    kept_reason: Vec<StopReason>,
    /// The verdicts on the links made by the last pass (None: the first pass, which examines
    /// every link, as B has changed since the last refinement).
    pending: Option<Vec<ReceiverDecision>>,
    /// The error oracle's field, kept up to date pass by pass (`update_error_field`), and the
    /// receivers whose link lists the last pass changed (tracked for the error oracle only).
    err_field: Option<oracle::ErrorField>,
    pass_changed: Vec<u32>,
    /// Per element, the indices (ascending) of the links the last pass put in its list (error
    /// oracle only): a receiver whose list changed but whose verdict inputs did not decides only
    /// these (`oracle::ErrorField::fresh`).
    born: Vec<Vec<u32>>,
    born_ids: Vec<u32>,
    track: bool,
}

impl HierarchicalSolver {
    /// One refinement pass: on the first call, link every mutually visible pair of input
    /// patches; then apply the oracle to every link until nothing splits.
    pub fn refine_step(&mut self) -> StepReport {
        self.setup.cancel.store(false, Ordering::Relaxed);
        self.refine_inner()
    }

    pub(in crate::solver::hierarchical) fn refine_inner(&mut self) -> StepReport {
        let t = Instant::now();
        self.log.settled = false;
        let mut run = self.begin_refinement();
        self.log.stats.refine_initial_s += t.elapsed().as_secs_f64();
        // The row check reads the rows of the links the last solution gathered through (none
        // before the first gather). Not with cluster links: their transfer is a bounded
        // approximation whose share of a row no element link's split corrects (with them, the
        // check only spends the link budget: docs/solver.md, "The row check").
        self.oracle.row_floor = if self.log.gathered_once && self.cluster.links.is_empty() {
            self.row_floors()
        } else {
            Vec::new()
        };
        while !self.cancelled() {
            if self.link_room(&run) == 0 {
                self.log.stats.budget_hit = true;
                break;
            }
            if !self.pass_fits(0) {
                break;
            }
            // A: decide, in parallel, read-only.
            let phase = Instant::now();
            let mut decisions = self.decide_pass(&mut run);
            self.log.stats.refine_passes += 1;
            self.log.stats.refine_decided += decisions.len();
            if decisions.is_empty() {
                break;
            }
            // Under the error oracle, a pass that would overrun the link budget splits the
            // pairs of the largest errors only, and is the last.
            let cut = run.track && self.cut_to_budget(&mut decisions, &run);
            self.log.stats.budget_hit |= cut;
            let mut to_split =
                chosen_elements(&self.graph.links.by_receiver, &decisions, self.hier.len(), &mut run);
            self.log.stats.refine_decide_s += phase.elapsed().as_secs_f64();
            if to_split.is_empty() {
                break;
            }
            // A deadline stops the refinement, as the cancel flag does, before a pass that would
            // leave the gathers after it too little time.
            let replacing: usize = decisions.iter().map(|(_, v)| v.splits.len()).sum();
            if !self.pass_fits(replacing) {
                break;
            }
            let links_before = self.graph.links.len();
            // B: split, in id order (children computed in parallel).
            let phase = Instant::now();
            run.refined += self.hier.split_many(&to_split.take_sorted());
            self.graph.links.grow(self.hier.len());
            self.sync_oracle_b();
            self.log.stats.refine_split_s += phase.elapsed().as_secs_f64();
            // C: replacement links, in parallel.
            let phase = Instant::now();
            let replace_start = phase;
            let work: Vec<ReceiverDecision> =
                decisions.into_iter().filter(|(_, v)| !v.splits.is_empty()).collect();
            let results: Vec<Replaced> =
                work.par_iter().map(|(r, v)| self.replace_links(*r, &v.splits)).collect();
            self.graph.pair_memo.clear();
            self.log.stats.refine_links_s += phase.elapsed().as_secs_f64();
            // D: install, in receiver order.
            let phase = Instant::now();
            self.install(results, &mut run);
            self.log.stats.refine_install_s += phase.elapsed().as_secs_f64();
            let pace = &mut self.log.pace;
            pace.replace_s += replace_start.elapsed().as_secs_f64();
            pace.replaced += replacing as u64;
            pace.added += self.graph.links.len() as f64 - links_before as f64;
            if cut {
                break;
            }
        }
        self.finish_refinement(run, t)
    }

    /// How many more links `max_links` allows.
    fn link_room(&self, run: &Refinement) -> usize {
        self.setup.params.max_links.saturating_sub(run.total_links)
    }

    /// If splitting every link of `decisions` would take more links than the budget allows
    /// (estimated from the links the passes so far added per link they replaced; 3 before any),
    /// keep only the splits of the pairs whose larger receiver error is largest, as many as fit
    /// in [`BUDGET_MARGIN`] of the room,
    /// and mark the receivers that lose splits as stopped by the budget. A pair's two links
    /// share that key, so they stay mirror images. Returns whether anything was cut.
    fn cut_to_budget(&self, decisions: &mut [ReceiverDecision], run: &Refinement) -> bool {
        let Some(field) = run.err_field.as_ref() else { return false };
        let replacing: usize = decisions.iter().map(|(_, v)| v.splits.len()).sum();
        let pace = &self.log.pace;
        let per = if pace.replaced > 0 { (pace.added / pace.replaced as f64).max(1.0) } else { 3.0 };
        let room = self.link_room(run) as f64;
        if replacing as f64 * per <= room {
            return false;
        }
        let lists = &self.graph.links.by_receiver;
        let key = |r: u32, i: u32| {
            let q = lists[r as usize][i as usize].source;
            field.err[r as usize].max(field.err[q as usize])
        };
        let mut keys: Vec<f64> =
            decisions.iter().flat_map(|(r, v)| v.splits.iter().map(move |&(i, _)| key(*r, i))).collect();
        // The estimate is a mean over the passes before: a margin keeps the pass under the budget
        // (a state of at most `max_links` fits where the solver keeps solved states).
        let fit = (BUDGET_MARGIN * room / per) as usize;
        let cutoff = if fit < keys.len() {
            keys.select_nth_unstable_by(fit, |a, b| b.total_cmp(a));
            keys[fit]
        } else {
            return false;
        };
        for (r, v) in decisions.iter_mut() {
            let before = v.splits.len();
            v.splits.retain(|&(i, _)| key(*r, i) > cutoff);
            if v.splits.len() < before {
                v.keep(StopReason::LinkBudget);
            }
        }
        true
    }

    /// The state a refinement starts from: the oracle's threshold and its copy of B, and the
    /// first links (input patches or clusters) or the cluster links refined.
    fn begin_refinement(&mut self) -> Refinement {
        let mut new_links = 0;
        if self.setup.params.oracle == Oracle::Error && self.setup.params.bf_relative {
            self.setup.bf_eps = self.error_eps();
        }
        self.oracle.b.clear();
        self.sync_oracle_b();
        // The gather plan is updated where the link lists change (`install`), if it was whole.
        let plan_whole = self.gather.plan_valid;
        self.gather.plan_valid = false;
        let mut changed = IdSet::default();
        if !self.graph.linked {
            new_links += if self.clustering() { self.cluster_linking() } else { self.initial_linking() };
            self.graph.linked = true;
            for r in 0..self.hier.roots as u32 {
                changed.insert(r);
            }
        } else if !self.cluster.links.is_empty() {
            let (created, touched) = self.cluster_refine();
            new_links += created;
            if touched {
                for r in 0..self.hier.roots as u32 {
                    changed.insert(r);
                }
            }
        }
        Refinement {
            new_links,
            refined: 0,
            total_links: self.graph.links.len(),
            changed,
            plan_whole,
            kept_reason: Vec::new(),
            pending: None,
            err_field: None,
            pass_changed: Vec::new(),
            born: Vec::new(),
            born_ids: Vec::new(),
            track: self.setup.params.oracle == Oracle::Error,
        }
    }

    /// Phase A: the verdicts of this pass. The error oracle examines, after its first pass, the
    /// links of the receivers whose error the last pass changed (their own or an ancestor's
    /// links changed) and their mirrors; the other oracles take the verdicts made with the new
    /// links, or examine every link in their first pass.
    fn decide_pass(&mut self, run: &mut Refinement) -> Vec<ReceiverDecision> {
        let decisions = if self.setup.params.oracle == Oracle::Error {
            self.decide_error_pass(run)
        } else {
            match run.pending.take() {
                Some(d) => d,
                None => self.decide_all(),
            }
        };
        run.pass_changed.clear();
        for &r in &run.born_ids {
            run.born[r as usize].clear();
        }
        run.born_ids.clear();
        decisions
    }

    /// The error oracle's verdicts: from its field, updated where the last pass changed the
    /// lists (or built whole in the first pass, or every pass with `full_error_passes`).
    fn decide_error_pass(&mut self, run: &mut Refinement) -> Vec<ReceiverDecision> {
        let ids: Vec<u32> = match run.err_field.as_mut() {
            Some(f) if !self.setup.full_error_passes => self.update_error_field(f, &run.pass_changed),
            _ => {
                let known = run
                    .err_field
                    .take()
                    .map_or_else(|| std::mem::take(&mut self.oracle.error_kernels), |f| f.kernels);
                run.err_field = Some(self.error_field(&known));
                (0..self.hier.len() as u32).collect()
            }
        };
        let field = run.err_field.as_ref();
        let born = &run.born;
        ids.into_par_iter()
            .filter(|&r| !self.graph.links.by_receiver[r as usize].is_empty())
            .map(|r| self.decide_receiver(r, field, born.get(r as usize).map_or(&[][..], Vec::as_slice)))
            .collect()
    }

    /// The oracle on every link, receiver by receiver.
    fn decide_all(&self) -> Vec<ReceiverDecision> {
        let lists = &self.graph.links.by_receiver;
        let ids: Vec<u32> = (0..self.hier.len() as u32).collect();
        ids.par_chunks(TOUCH_AHEAD)
            .flat_map_iter(|chunk| {
                // Each list is its own allocation: load the first link of all of the chunk's
                // lists at once, so their cache misses overlap instead of stalling one receiver
                // after the other.
                let touched = chunk
                    .iter()
                    .fold(0u32, |acc, &r| acc ^ lists[r as usize].first().map_or(0, |l| l.source));
                std::hint::black_box(touched);
                chunk
                    .iter()
                    .filter(|&&r| !lists[r as usize].is_empty())
                    .map(|&r| self.decide_receiver(r, None, &[]))
            })
            .collect()
    }

    /// Phase D: install the replacement links, in receiver order: every receiver's own list
    /// first, then the links pushed down to children (a child may itself have been a receiver
    /// in this pass). The verdicts on the new links become the next pass's (`pending`).
    fn install(&mut self, results: Vec<Replaced>, run: &mut Refinement) {
        let mut next: Vec<ReceiverDecision> = Vec::new();
        let mut pushed_down = Vec::new();
        let mut owns = Vec::with_capacity(results.len());
        if run.track {
            run.born.resize_with(self.hier.len(), Vec::new);
        }
        for rep in results {
            let r = rep.receiver;
            self.log.stats.rays += rep.rays;
            if rep.own_changed {
                next.push((r, rep.own_verdict));
            }
            run.new_links += rep.created;
            let pushed: usize = rep.kids.iter().map(Vec::len).sum();
            run.total_links =
                run.total_links + rep.own.len() + pushed - self.graph.links.by_receiver[r as usize].len();
            run.changed.insert(r);
            if run.track {
                run.pass_changed.push(r);
                if !rep.own_new.is_empty() {
                    run.born[r as usize] = rep.own_new;
                    run.born_ids.push(r);
                }
            }
            owns.push((r, rep.own));
            if pushed > 0 {
                let first = rep.first_child;
                for (k, (ls, v)) in rep.kids.into_iter().zip(rep.kid_verdicts).enumerate() {
                    if !ls.is_empty() {
                        pushed_down.push((first + k as u32, ls, v));
                    }
                }
            }
        }
        // The new own lists replace the old ones in parallel (freeing them is most of it).
        let slots = disjoint_mut(&mut self.graph.links.by_receiver, owns.iter().map(|o| o.0));
        slots.into_par_iter().zip(owns).with_min_len(64).for_each(|(slot, (_, own))| *slot = own);
        for (c, ls, mut v) in pushed_down {
            let list = &mut self.graph.links.by_receiver[c as usize];
            // The child's list may hold links already (its own, just replaced, or earlier ones).
            let offset = list.len() as u32;
            if run.track {
                run.pass_changed.push(c);
                let born = &mut run.born[c as usize];
                if born.is_empty() {
                    run.born_ids.push(c);
                }
                born.extend(offset..offset + ls.len() as u32);
            }
            if list.is_empty() {
                *list = ls;
            } else {
                list.extend(ls);
            }
            for (i, _) in &mut v.splits {
                *i += offset;
            }
            next.push((c, v));
            run.changed.insert(c);
        }
        merge_by_receiver(&mut next);
        run.pending = (self.setup.params.oracle != Oracle::Error).then_some(next);
    }

    /// Whether a pass that replaces `replacing` links, and the gathers that converge the mesh
    /// after it, fit before the deadline (always, without one); where they do not, the cancel
    /// flag is set, so that the solve stops as a cancelled one does.
    fn pass_fits(&self, replacing: usize) -> bool {
        if self.setup.deadline.is_none() {
            return true;
        }
        let (pass_s, added) = self.log.pace.pass(replacing);
        self.fits_deadline(pass_s, self.gather_links() + added.round() as usize)
    }

    /// After the last pass: measure what was left unmeasured, record on each leaf why it
    /// stopped, update the sums and the gather plan where the lists changed.
    fn finish_refinement(&mut self, run: Refinement, t: Instant) -> StepReport {
        if self.log.stats.budget_hit || self.cancelled() {
            self.measure_unmeasured();
        }
        for (r, kept) in run.kept_reason.iter().enumerate() {
            let e = &mut self.hier.elements[r];
            if *kept != StopReason::Unrefined && e.is_leaf() {
                e.stop = *kept;
            }
        }
        self.oracle.row_floor = Vec::new();
        // The error oracle's kernels serve the next refinement's field (`oracle::ErrorField`).
        if let Some(f) = run.err_field {
            self.oracle.error_kernels = f.kernels;
        }
        let mut changed = run.changed;
        let changed = changed.take_sorted();
        update_sums(&mut self.hier, &self.graph.links, &self.cluster.fv, &changed);
        if run.plan_whole {
            self.gather.plan_changed.extend_from_slice(&changed);
            self.gather.plan_valid = true;
        }
        self.log.converged = false;
        self.log.stats.links_created += run.new_links as u64;
        self.log.stats.refine_s += t.elapsed().as_secs_f64();
        self.oracle.b.clear();
        self.report(StepKind::Refine, t, run.refined, run.new_links)
    }
}

/// The elements the verdicts split (a split source's or receiver's id); also records, per
/// receiver, the strongest reason over all the links it keeps, examined now or in an earlier
/// pass (written to the leaves once, after the last pass).
fn chosen_elements(
    lists: &[Vec<Link>],
    decisions: &[ReceiverDecision],
    elements: usize,
    run: &mut Refinement,
) -> IdSet {
    run.kept_reason.resize(elements, StopReason::Unrefined);
    let mut to_split = IdSet::default();
    for (r, Verdict { reason, splits }) in decisions {
        for &(i, side) in splits {
            to_split.insert(match side {
                Split::Source => lists[*r as usize][i as usize].source,
                Split::Receiver => *r,
            });
        }
        let kept = &mut run.kept_reason[*r as usize];
        if reason.rank() > kept.rank() {
            *kept = *reason;
        }
    }
    to_split
}

/// Sort the next pass's verdicts by receiver and merge each receiver's: a child that was a
/// receiver in this pass too has its own list's verdict first (lower indices), then its
/// parent's pushed links'.
fn merge_by_receiver(next: &mut Vec<ReceiverDecision>) {
    next.sort_by_key(|d| d.0);
    next.dedup_by(|later, first| {
        let same = later.0 == first.0;
        if same {
            first.1.absorb(std::mem::take(&mut later.1));
        }
        same
    });
}
