//! Links: "receiver gathers from source" interactions of hierarchical radiosity.
//!
//! A link records the form factor F (receiver ← source), the visible fraction V and the oracle's
//! estimate of the link's error [Hanrahan, Salzman, Aupperle 1991, sec. 4]. Links are stored per
//! receiver (`Vec<Link>` indexed by element id), so the receiver id is implicit and a link takes
//! 44 bytes: gather runs in parallel over receivers without locks.
//! In the lecture's notation the receiver is p and the source is q.

use serde::Serialize;

/// One link, stored in its receiver's list.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct Link {
    /// Element the receiver gathers from.
    pub source: u32,
    /// Form factor receiver → source (fraction of the receiver's hemisphere covered by the source).
    pub ff: f32,
    /// The pair's Galerkin coupling A_r F_rs = A_s F_sr: the same number in the link and its
    /// mirror (`ff` is it over each receiver's area, rounded apart), so quantities both
    /// directions derive from it agree to the bit (the error oracle's decisions).
    pub g: f32,
    /// Visible fraction in [0, 1].
    pub vis: f32,
    /// The oracle's geometric estimate max(F_pq, F_qp) (disk formula), fixed for the link's life.
    pub fmax: f32,
    /// Relative error bound of the link's transfer when fully visible, (diam_p + diam_q) /
    /// distance capped at 1 (a partially visible link's bound is 1).
    pub bound: f32,
    /// Refine splits the source (F_pq > F_qp), else the receiver.
    pub split_source: bool,
    /// V was not fully measured: the rays stopped once they showed that the next refinement
    /// pass replaces the link whatever V's exact value is (see `HierarchicalSolver::make_link`).
    #[serde(skip)]
    pub unmeasured: bool,
    /// `slope` is computed (the hierarchical solver fills it before a gather reads it).
    #[serde(skip)]
    pub slope_set: bool,
    /// The pair's shaft is empty (`Accel::shaft_clear`): V = 1 exactly, for this pair and for
    /// every pair of their descendants (their shafts lie inside this one).
    #[serde(skip)]
    pub clear: bool,
    /// How the link's transfer F(x → source)·V varies across the receiver: the gradient in x,
    /// per unit length, in the receiver's tangent basis [`crate::math::orthonormal_basis`] of its
    /// normal. The gather pushes it down with the irradiance, so a descendant of the receiver
    /// gathers the transfer at its own centroid instead of the receiver's average (see
    /// `solver::hierarchical`, "push-pull"). Limited so that F + slope·(x − centroid) ≥ 0 over
    /// the receiver; zero where the solver does not push slopes (SPLASH-2's preset).
    pub slope: [f32; 2],
    /// The mirror link's `slope`: how F(y → receiver)·V varies across the source, in the
    /// source's tangent basis. The gather adds it against the first moment of the source's
    /// radiosity, so a coarse source sends what its bright and dark parts send, not its average
    /// through its centroid's coupling (energy conservation, `solver::hierarchical`).
    pub src_slope: [f32; 2],
}

const _: () = assert!(std::mem::size_of::<Link>() == 44);

impl Link {
    /// The oracle's error estimate of this link for a source of radiosity `b_source` (units of
    /// B): B_source · max(F_pq, F_qp) · error bound.
    #[must_use]
    pub fn bf_error(&self, b_source: f64) -> f64 {
        let bound = if self.class() == VisClass::Partial { 1.0 } else { f64::from(self.bound) };
        b_source * f64::from(self.fmax) * bound
    }
}

/// Visibility class of a link.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum VisClass {
    Full,
    Partial,
    None,
}

impl Link {
    #[must_use]
    pub fn class(&self) -> VisClass {
        if self.vis >= 1.0 {
            VisClass::Full
        } else if self.vis > 0.0 {
            VisClass::Partial
        } else {
            VisClass::None
        }
    }
}

/// All links, grouped by receiver.
#[derive(Clone, Debug, Default)]
pub struct LinkStore {
    pub by_receiver: Vec<Vec<Link>>,
}

impl LinkStore {
    /// An empty store for `n` elements.
    #[must_use]
    pub fn new(n: usize) -> LinkStore {
        LinkStore { by_receiver: vec![Vec::new(); n] }
    }
    /// Make room for elements up to `n`.
    pub fn grow(&mut self, n: usize) {
        if self.by_receiver.len() < n {
            self.by_receiver.resize_with(n, Vec::new);
        }
    }
    #[must_use]
    pub fn len(&self) -> usize {
        self.by_receiver.iter().map(Vec::len).sum()
    }
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.by_receiver.iter().all(Vec::is_empty)
    }
    /// Bytes held (link payload plus per-receiver vector headers and spare capacity).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.by_receiver.iter().map(|v| v.capacity() * std::mem::size_of::<Link>()).sum::<usize>()
            + self.by_receiver.capacity() * std::mem::size_of::<Vec<Link>>()
    }
}
