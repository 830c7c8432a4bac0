//! A time budget's deadline ([`super::HierarchicalSolver::set_deadline`]): refinement stops
//! early enough to leave the gathers that converge its mesh their estimated time, and those
//! gathers stop at the deadline.
//!
//! ```text
//!  refine pass ──► refine pass ──► … ──► stop: now + next pass + reserve(links) > deadline
//!  (refining cluster links: now + the last chunk's time + reserve(links) > deadline)
//!                                         └─► gather sweeps until converged or the deadline
//!  reserve(links) = RESERVED_SWEEPS × (seconds per link of a sweep) × links
//! ```
//!
//! The estimates come from the solver's own timings ([`Pace`]): the last gather sweep's seconds
//! per link, and the refinement passes' seconds and links added per link they replace. Before a
//! sweep has been timed, a prior per link and thread stands in.

use std::time::Instant;

/// Gather sweeps reserved for converging a stopped refinement's mesh and closing its power
/// balance: budgeted solves of splash_room and furnished-10k take 14 to 22.
pub const RESERVED_SWEEPS: f64 = 20.0;

/// Seconds a gather sweep takes per link on one thread until a sweep has been timed: about
/// twice what splash_room and furnished-10k measure, as the first sweep after a refinement also
/// flattens the links into the gather plan.
pub const PRIOR_SWEEP_S_PER_LINK: f64 = 2e-7;

/// What the solver has measured of its own speed, for the deadline's estimates.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pace {
    /// Seconds per link (element and cluster links) of the last gather sweep.
    pub sweep_s_per_link: Option<f64>,
    /// Refinement passes: seconds spent making and installing replacement links, the links
    /// they replaced, and the links they added net.
    pub replace_s: f64,
    pub replaced: u64,
    pub added: f64,
}

impl Pace {
    /// Estimated seconds of one gather sweep over `links` links on `threads` threads.
    #[must_use]
    pub fn sweep_s(&self, links: usize, threads: usize) -> f64 {
        let per_link = self.sweep_s_per_link.unwrap_or(PRIOR_SWEEP_S_PER_LINK / threads.max(1) as f64);
        per_link * links as f64
    }

    /// Seconds to reserve for the converging gathers over `links` links.
    #[must_use]
    pub fn reserve_s(&self, links: usize, threads: usize) -> f64 {
        RESERVED_SWEEPS * self.sweep_s(links, threads)
    }

    /// Estimated seconds and links added of a refinement pass that replaces `replacing` links
    /// (nothing before a pass has been timed).
    #[must_use]
    pub fn pass(&self, replacing: usize) -> (f64, f64) {
        if self.replaced == 0 {
            return (0.0, 0.0);
        }
        let per = replacing as f64 / self.replaced as f64;
        (self.replace_s * per, self.added.max(0.0) * per)
    }

    /// Whether work of `work_s` seconds that leaves `links` links, and the converging gathers'
    /// reserve after it, fit before `deadline` (from `now`).
    #[must_use]
    pub fn fits(&self, deadline: Instant, now: Instant, work_s: f64, links: usize, threads: usize) -> bool {
        let left = deadline.saturating_duration_since(now).as_secs_f64();
        work_s + self.reserve_s(links, threads) < left
    }

    /// Whether a refinement pass that replaces `replacing` of `links` links fits before
    /// `deadline` (from `now`) with the converging gathers' reserve after it.
    #[must_use]
    pub fn pass_fits(
        &self,
        deadline: Instant,
        now: Instant,
        links: usize,
        replacing: usize,
        threads: usize,
    ) -> bool {
        let (pass_s, added) = self.pass(replacing);
        self.fits(deadline, now, pass_s, links + added.round() as usize, threads)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_reserve_scales_with_the_links_and_the_measured_sweep() {
        let mut pace = Pace::default();
        // Before a sweep is timed the prior stands in, shared among the threads.
        assert!((pace.reserve_s(1_000_000, 2) - RESERVED_SWEEPS * 0.1).abs() < 1e-9);
        pace.sweep_s_per_link = Some(1e-6);
        assert!((pace.reserve_s(1000, 8) - RESERVED_SWEEPS * 1e-3).abs() < 1e-12);
        assert!((pace.reserve_s(2000, 8) - 2.0 * pace.reserve_s(1000, 8)).abs() < 1e-12);
    }

    #[test]
    fn a_pass_fits_only_with_the_gathers_reserve_after_it() {
        let now = Instant::now();
        let deadline = now + Duration::from_secs(10);
        let mut pace = Pace { sweep_s_per_link: Some(1e-7), ..Pace::default() };
        // 1 M links: a sweep takes 0.1 s, the reserve 2 s; no pass timed yet, so it costs nothing.
        assert!(pace.pass_fits(deadline, now, 1_000_000, 500_000, 1));
        assert!(!pace.pass_fits(deadline, now, 5_000_000, 0, 1), "a 10 s reserve leaves no time");
        // Passes so far: 4 s and 1 M links added for 500 k replaced.
        pace.replace_s = 4.0;
        pace.replaced = 500_000;
        pace.added = 1_000_000.0;
        // The next pass, as large: 4 s, then 2 M links, a 4 s reserve: 8 s of the 10 left.
        assert!(pace.pass_fits(deadline, now, 1_000_000, 500_000, 1));
        // Twice as large: 8 s, then 3 M links, a 6 s reserve: past the deadline.
        assert!(!pace.pass_fits(deadline, now, 1_000_000, 1_000_000, 1));
        // Past the deadline nothing fits.
        assert!(!pace.pass_fits(now, now + Duration::from_millis(1), 1, 0, 1));
    }
}
