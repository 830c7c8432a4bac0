//! What a refinement pass decides: a verdict per receiver (the links it splits, which side,
//! and the strongest reason among those it keeps), and the set of elements to split, read
//! back in id order so that the new elements' ids do not depend on the thread count.

use crate::solver::hierarchy::StopReason;

/// An [`IdSet`] holding at least 1/this of the ids up to its largest is read off its marks.
pub(super) const DENSE_ID_SET: usize = 16;

/// A set of element ids, read back in ascending order (marks instead of sorting duplicates).
#[derive(Default)]
pub(in crate::solver::hierarchical) struct IdSet {
    mark: Vec<bool>,
    ids: Vec<u32>,
}

impl IdSet {
    pub(in crate::solver::hierarchical) fn insert(&mut self, id: u32) {
        let i = id as usize;
        if i >= self.mark.len() {
            self.mark.resize(i + 1, false);
        }
        if !self.mark[i] {
            self.mark[i] = true;
            self.ids.push(id);
        }
    }

    pub(in crate::solver::hierarchical) fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The ids, ascending; the set is left empty. A dense set is read off its marks (one pass,
    /// no sort).
    pub(in crate::solver::hierarchical) fn take_sorted(&mut self) -> Vec<u32> {
        let mut ids = std::mem::take(&mut self.ids);
        if ids.len() >= self.mark.len() / DENSE_ID_SET {
            ids.clear();
            for (i, m) in self.mark.iter_mut().enumerate() {
                if *m {
                    *m = false;
                    ids.push(i as u32);
                }
            }
        } else {
            for &i in &ids {
                self.mark[i as usize] = false;
            }
            ids.sort_unstable();
        }
        ids
    }
}

/// The oracle's verdict on some new links of one list, made when they were created (its
/// inputs do not change during a refinement): the strongest reason among the kept ones, and
/// the ones to split (index in the list, which side).
#[derive(Default)]
pub(super) struct Verdict {
    pub(super) reason: StopReason,
    pub(super) splits: Vec<(u32, Split)>,
}

impl Verdict {
    /// Record link `index`'s verdict.
    pub(super) fn note(&mut self, index: usize, v: Decision) {
        match v {
            Ok(side) => self.splits.push((index as u32, side)),
            Err(why) => self.keep(why),
        }
    }

    /// Record a kept link's reason (the strongest one stands).
    pub(super) fn keep(&mut self, why: StopReason) {
        if why.rank() > self.reason.rank() {
            self.reason = why;
        }
    }

    /// Add the verdict on links that follow this verdict's in the same list.
    pub(super) fn absorb(&mut self, mut later: Verdict) {
        self.keep(later.reason);
        self.splits.append(&mut later.splits);
    }
}

/// What refinement does with one link.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Split {
    Source,
    Receiver,
}

/// The oracle's decision on one link: `Ok(side to split)` or `Err(why it is kept)`.
pub(super) type Decision = Result<Split, StopReason>;

/// One receiver's verdict in pass A.
pub(super) type ReceiverDecision = (u32, Verdict);
