//! What is picked and hovered ([`Pick`]): the element picked (in the current solution or in a
//! split pane's run), the cluster around it, a pick waiting for a solve (`--pick`, a figure's),
//! and what the matrix window and the viewport hover this frame (each highlights it in the
//! other).

use super::clusters;
use super::history::RunHistory;
use super::worker::ViewData;
use crate::present::overlay::Highlight;
use std::sync::Arc;

/// The pick and the hovers.
#[derive(Clone, Debug, Default)]
pub struct Pick {
    /// The element picked (an id of the current solution, or of `selected_run`'s).
    pub selected: Option<u32>,
    /// The run whose solution `selected` belongs to when it was picked in a split view's pane
    /// (`None`: the current solution).
    pub selected_run: Option<usize>,
    /// The cluster picked (an index into the current solution's `clusters`), reached from the
    /// picked element: it counts only while it holds that element's patch ([`Pick::cluster`]).
    pub(super) cluster: Option<u32>,
    /// Pick the element under this viewport point (fractions, y down) once a solve is shown
    /// (`--pick`, a figure's pick).
    pub(super) pending: Option<[f32; 2]>,
    /// The link of the matrix block hovered this frame (highlighted in the viewport).
    pub(super) matrix_hover: Option<Highlight>,
    /// The leaf under the pointer in the viewport, while the matrix window is open (its row and
    /// column are highlighted there).
    pub(super) viewport_hover: Option<u32>,
}

impl Pick {
    /// Pick `id` of the current solution (`None`: nothing) and, while the cluster boxes are
    /// drawn down to level `deepest`, the cluster around it at the levels shown
    /// ([`clusters::at_shown_level`]).
    pub fn element(&mut self, id: Option<u32>, view: &ViewData, deepest: Option<u8>) {
        self.selected = id;
        self.selected_run = None;
        self.cluster = id.zip(deepest).and_then(|(id, deepest)| clusters::at_shown_level(view, id, deepest));
    }

    /// Pick `element` of run `run`'s solution (a split view's pane), or nothing.
    pub fn in_run(&mut self, run: usize, element: Option<u32>) {
        self.selected = element;
        self.selected_run = element.map(|_| run);
    }

    /// Forget the pick (another scene).
    pub fn clear(&mut self) {
        self.selected = None;
        self.selected_run = None;
        self.cluster = None;
    }

    /// The picked element when it is one of the current solution (not a split pane's run's).
    #[must_use]
    pub fn here(&self) -> Option<u32> {
        self.selected.filter(|_| self.selected_run.is_none())
    }

    /// The picked element and the solution it belongs to (`view`, the current one, or a split
    /// pane's run's while that run keeps its solution).
    #[must_use]
    pub fn with_solution<'a>(
        &self,
        view: &'a Arc<ViewData>,
        history: &'a RunHistory,
    ) -> Option<(u32, &'a Arc<ViewData>)> {
        let id = self.selected?;
        match self.selected_run {
            None => Some((id, view)),
            Some(n) => history.runs().iter().find(|r| r.number == n)?.view.as_ref().map(|v| (id, v)),
        }
    }

    /// The picked cluster: an index into `view`'s (the current solution's) `clusters` that
    /// holds the picked element's patch (`None` without one, or when the element is a split
    /// pane's run's).
    #[must_use]
    pub fn cluster(&self, view: &ViewData) -> Option<u32> {
        let c = self.cluster?;
        self.here().filter(|&id| clusters::chain_of_element(view, id).contains(&c)).map(|_| c)
    }

    /// Pick cluster `c` of `view` (`None`: the element alone); ignored unless it holds the
    /// picked element's patch.
    pub fn set_cluster(&mut self, c: Option<u32>, view: &ViewData) {
        self.cluster = c;
        if c.is_some() && self.cluster(view).is_none() {
            self.cluster = None;
        }
    }

    /// What the viewport highlights this frame: the link of the matrix block hovered, else (while
    /// the matrix is open) the element under the pointer.
    #[must_use]
    pub fn highlight(&self) -> Option<Highlight> {
        self.matrix_hover.or(self.viewport_hover.map(Highlight::Element))
    }
}
