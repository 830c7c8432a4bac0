//! The state shown against its ruler ([`Comparison`]): the reference thread's client, where the
//! scene's reference stands, and what scoring the state shown gave (its per-element true error,
//! its pointwise relative L2 error and the penumbra band's).

use super::history::Ruler;
use super::reference::RefClient;
use super::reference_panel::RefState;
use crate::scene::Scene;
use std::sync::Arc;

/// The reference of the scene shown and the scores of the state shown.
pub struct Comparison {
    /// The reference thread (what it was sent, the scene's reference solution).
    pub(super) reference: RefClient,
    /// Where the current scene's reference stands.
    pub(super) state: RefState,
    /// Per-element true error (against a reference); replaces the solver's estimate when set.
    pub(super) true_error: Option<Arc<Vec<f64>>>,
    /// The pointwise relative L2 error of state `.0` against the closed form or the reference,
    /// and over the penumbra band (the closed form's).
    pub(super) state_error: Option<(u64, f64, Option<f64>)>,
}

impl Comparison {
    /// Scores from `reference`, nothing known yet.
    #[must_use]
    pub fn new(reference: RefClient) -> Comparison {
        Comparison { reference, state: RefState::None, true_error: None, state_error: None }
    }

    /// Forget the last scene's scores and reference, and look up the reference of `scene` (the
    /// state says it is being looked up, where there is a reference thread).
    pub fn open_scene(&mut self, scene: &Arc<Scene>) {
        self.true_error = None;
        self.state_error = None;
        self.reference.view = None;
        if self.reference.load(scene, false) {
            self.state = RefState::Looking;
        }
    }

    /// The reference is known: the states can be scored.
    #[must_use]
    pub fn ready(&self) -> bool {
        matches!(self.state, RefState::Ready { .. })
    }

    /// The pointwise relative L2 error of state `view_seq`, once scored.
    #[must_use]
    pub fn state_error(&self, view_seq: u64) -> Option<f64> {
        self.state_error.filter(|e| e.0 == view_seq).map(|e| e.1)
    }

    /// The same over the penumbra band, where the closed form gives the band.
    #[must_use]
    pub fn band_error(&self, view_seq: u64) -> Option<f64> {
        self.state_error.filter(|e| e.0 == view_seq).and_then(|e| e.2)
    }

    /// The true error list, when it matches a solver state of `elements` elements.
    #[must_use]
    pub fn true_error(&self, elements: usize) -> Option<&Arc<Vec<f64>>> {
        self.true_error.as_ref().filter(|e| e.len() == elements)
    }

    /// What the scene's errors are measured against: its closed form (a single-bounce scene) or
    /// its reference.
    #[must_use]
    pub fn ruler(&self) -> Ruler {
        match &self.state {
            RefState::Ready { how, .. } if how == super::reference::CLOSED_FORM => Ruler::ClosedForm,
            _ => Ruler::Reference,
        }
    }

    /// Where the reference stands, as a number (the caption's numbers are read again when it
    /// changes).
    #[must_use]
    pub fn stage(&self) -> u8 {
        match self.state {
            RefState::None => 0,
            RefState::Looking => 1,
            RefState::Missing => 2,
            RefState::Computing { .. } => 3,
            RefState::Ready { .. } => 4,
            RefState::Failed(_) => 5,
        }
    }
}
