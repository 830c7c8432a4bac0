//! The viewport's geometry: the newest display build shown, what it was asked for, and the
//! numbers that came with it (links drawn, colour scales, critical edges, the auto exposure).
//!
//! A build is asked for only when its [`BuildKey`] changes (the solver state, the true error,
//! the artifact samples or the display settings); it runs on the `radlab-display` thread
//! ([`super::builder`]) and the viewport keeps showing the previous geometry until it is done.
//! A build that panicked keeps the previous geometry too, and says why once
//! ([`ShownGeometry::take_failure`]).

use super::builder::{self, BuildFailed, Builder, Built, Request, Settings};
use crate::mesh::discontinuity::SegmentCounts;
use crate::present::mesh_overlay::Artifact;
use crate::present::overlay::LogScale;
use crate::render::Geometry;
use std::sync::Arc;

/// What a display build depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildKey {
    pub view_seq: u64,
    /// With the error heatmap, the address of the state (`Arc` identity; else 0): it changes,
    /// not its number, when the state's error estimates arrive.
    pub view: usize,
    /// Address of the true-error list (`Arc` identity), if any.
    pub true_error: Option<usize>,
    /// The artifact overlay drawn and the address of its samples (`Arc` identity), if any.
    pub artifacts: Option<(Artifact, usize)>,
    pub settings: Settings,
}

/// The geometry shown and the thread that builds the next.
pub struct ShownGeometry {
    pub geometry: Arc<Geometry>,
    /// Bumped when `geometry` changes (the renderer uploads only then).
    pub generation: u64,
    /// The display builder thread (`None`: build on the UI thread).
    builder: Option<Builder>,
    /// What the newest build was requested for, and its sequence number.
    key: Option<BuildKey>,
    seq: u64,
    /// Sequence number of the build shown now.
    shown_seq: u64,
    /// The solver state whose auto exposure was applied last.
    exposure_view_seq: u64,
    /// (links drawn, links that pass the filter).
    pub link_stats: (usize, usize),
    /// (cluster links drawn, cluster links carried that pass the filter), when drawn.
    pub cluster_link_stats: Option<(usize, usize)>,
    /// The critical edges drawn, by kind.
    pub critical_counts: Option<SegmentCounts>,
    pub link_scale: Option<LogScale>,
    pub error_scale: Option<LogScale>,
    /// How the mesh shown is coloured (`None`: nothing built yet).
    pub coloring: Option<builder::Coloring>,
    /// How long the last build took, seconds.
    pub rebuild_s: f64,
    /// Why the newest failed build failed, until taken.
    failure: Option<String>,
}

impl ShownGeometry {
    /// Nothing shown yet; builds run on `builder` (`None`: on the caller's thread).
    #[must_use]
    pub fn new(builder: Option<Builder>) -> ShownGeometry {
        ShownGeometry {
            geometry: Arc::new(Geometry::default()),
            generation: 0,
            builder,
            key: None,
            seq: 0,
            shown_seq: 0,
            exposure_view_seq: 0,
            link_stats: (0, 0),
            cluster_link_stats: None,
            critical_counts: None,
            link_scale: None,
            error_scale: None,
            coloring: None,
            rebuild_s: 0.0,
            failure: None,
        }
    }

    /// Ask for a build for `key` unless it was the last asked for (`request` makes the request
    /// from its sequence number). Returns the auto exposure to apply (EV) when the build ran
    /// here and `auto_exposure` is on.
    pub fn request(
        &mut self,
        key: BuildKey,
        auto_exposure: bool,
        request: impl FnOnce(u64) -> Request,
    ) -> Option<f32> {
        if self.key.as_ref() == Some(&key) {
            return None;
        }
        self.seq += 1;
        let req = request(self.seq);
        self.key = Some(key);
        match &mut self.builder {
            Some(b) => {
                b.request(req);
                None
            }
            None => match builder::try_build(&req) {
                Ok(built) => self.show(built, auto_exposure),
                Err(f) => {
                    self.fail(f);
                    None
                }
            },
        }
    }

    /// Pick up a finished build (`wait`: block for it; tests, scripted runs); returns the auto
    /// exposure to apply, as [`ShownGeometry::request`].
    pub fn poll(&mut self, wait: bool, auto_exposure: bool) -> Option<f32> {
        let b = self.builder.as_mut()?;
        let built = if wait { b.wait() } else { b.poll() };
        let failed = b.take_failure();
        let ev = built.and_then(|built| self.show(built, auto_exposure));
        if let Some(f) = failed {
            self.fail(f);
        }
        ev
    }

    /// A build failed: the geometry shown stays, and the request counts as answered.
    fn fail(&mut self, f: BuildFailed) {
        self.shown_seq = self.shown_seq.max(f.seq);
        self.failure = Some(f.message);
    }

    /// Why the newest failed build failed (once; `None` when none failed since the last call).
    pub fn take_failure(&mut self) -> Option<String> {
        self.failure.take()
    }

    fn show(&mut self, b: Built, auto_exposure: bool) -> Option<f32> {
        if b.seq <= self.shown_seq && self.shown_seq != 0 {
            return None;
        }
        self.shown_seq = b.seq;
        self.geometry = b.geometry;
        self.generation += 1;
        self.link_stats = b.link_stats;
        self.cluster_link_stats = b.cluster_link_stats;
        self.critical_counts = b.critical;
        self.link_scale = b.link_scale;
        self.error_scale = b.error_scale;
        self.coloring = Some(b.coloring);
        self.rebuild_s = b.build_s;
        if auto_exposure
            && b.view_seq != self.exposure_view_seq
            && let Some(ev) = b.auto_ev
        {
            self.exposure_view_seq = b.view_seq;
            return Some(ev);
        }
        None
    }

    /// True when the geometry shown is the newest requested (scripted runs wait for it).
    #[must_use]
    pub fn current(&self) -> bool {
        self.key.is_some() && self.shown_seq == self.seq
    }
}
