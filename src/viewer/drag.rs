//! A slider drag as one run of the history ([`SliderDrag`]): while a drag changes the solver
//! settings, each solve that finishes replaces the drag's run instead of adding one, until the
//! slider is released and its last value's solve is in.

/// The drag going on and the run its solves replace.
#[derive(Clone, Debug, Default)]
pub struct SliderDrag {
    /// A drag has changed the settings and its solves are not all in.
    open: bool,
    /// The run of the history the drag's solves replace (the first solve records it).
    run: Option<usize>,
    /// A widget is being dragged (as of the last frame).
    pub(super) dragging: bool,
}

impl SliderDrag {
    /// A drag changed the settings: it opens (a run of its own from its first solve), or goes on.
    pub fn changed(&mut self) {
        if !self.open {
            self.run = None;
        }
        self.open = true;
    }

    /// The run a finished solve replaces (`None`: a new run).
    #[must_use]
    pub fn run_over(&self) -> Option<usize> {
        self.run.filter(|_| self.open)
    }

    /// A finished solve was recorded as run `n`: while the drag is open, its next solves
    /// replace it. True while the drag is open.
    pub fn recorded(&mut self, n: usize) -> bool {
        if self.open {
            self.run = Some(n);
        }
        self.open
    }

    /// The drag is over once released and its last value's solve is in (`settled`: nothing
    /// left to solve): the next solve is a run of its own.
    pub fn end_when_done(&mut self, settled: bool) {
        if self.open && !self.dragging && settled {
            self.open = false;
            self.run = None;
        }
    }
}
