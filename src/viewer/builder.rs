//! The display builder: turns a solver state ([`ViewData`]) and the display settings into
//! ready-made GPU vertex arrays ([`Geometry`]) on its own thread, `radlab-display`, so the UI
//! thread only uploads them: with 20 000+ elements the conforming mesh, the link lines and the
//! colour scales take tens of milliseconds, more than a frame.
//!
//! ```text
//!  UI ── Request {seq, view, settings} ──► "radlab-display" ── Built {seq, geometry} ──► UI
//!        (only when the key changes)        builds the newest       (uploads it, keeps the
//!                                           queued request only      old one until then)
//! ```
//!
//! A build that panics is answered with [`BuildFailed`] ([`super::panics`]): the request counts
//! as answered (nothing waits for it), the picture shown stays, and the thread goes on with the
//! next request.

use super::panics;
use super::worker::ViewData;
use crate::eval::artifacts::ArtifactSamples;
use crate::math::DVec3;
use crate::mesh::discontinuity::SegmentCounts;
use crate::present::mesh_overlay::{Artifact, CriticalEdges, artifact_lines, critical_edges, critical_lines};
use crate::present::overlay::{self, LinkFilter, LogScale};
use crate::render::Geometry;
use crate::render::geometry::{self, MeshColors};
use crate::scene::Scene;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::time::Instant;

/// How the mesh is coloured.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Coloring {
    Flat,
    Smooth,
    /// The element's own function: p = 1 where the state has vertex values (a p = 1 mesh
    /// solve), else its constant (as `Flat`).
    Nodal,
    /// Error heatmap (true error when given, else the solver's estimate).
    Error,
}

/// Everything besides the solver state that the geometry depends on.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Settings {
    pub coloring: Coloring,
    /// The links overlay, when shown: its filter (with the picked element already applied).
    pub links: Option<LinkFilter>,
    pub link_alpha: f32,
    pub links_xray: bool,
    /// With the links overlay (not one element's links): the view's cluster links too, dashed.
    pub cluster_links: bool,
    /// Scene centre subtracted from every position.
    pub origin: DVec3,
    /// Draw the quadtree down to this depth only: deeper leaves are drawn as their ancestor at
    /// this depth (its pulled radiosity), links between deeper elements are left out. `None`:
    /// the leaves.
    pub depth_limit: Option<u8>,
    /// Draw the critical edges (D0/D1/D2) of the request's scene.
    pub critical: bool,
    /// Draw the cluster boxes of these depths (first, last).
    pub clusters: Option<(u8, u8)>,
    /// The picked cluster (an index into the view's clusters): its box is drawn in
    /// [`PICKED_CLUSTER_RGBA`], and with "picked element only" (a `links` filter naming an
    /// element) its cluster links are drawn in place of the element's.
    pub picked_cluster: Option<u32>,
}

/// The picked cluster's box: orange, apart from the boxes' viridis.
pub const PICKED_CLUSTER_RGBA: [f32; 4] = [1.0, 0.45, 0.05, 1.0];

/// One build job.
#[derive(Clone, Debug)]
pub struct Request {
    /// Increases with every request; results carry it back.
    pub seq: u64,
    pub view: Arc<ViewData>,
    /// Identifies `view` (the UI counts the solver states it receives).
    pub view_seq: u64,
    /// Per-element true error (indexed like `view.elements`), when a reference exists.
    pub true_error: Option<Arc<Vec<f64>>>,
    pub settings: Settings,
    /// The scene, for the overlays that read it (critical edges, artifacts); `None`: none of
    /// them.
    pub scene: Option<Arc<Scene>>,
    /// An artifact overlay and the samples measured on `view`.
    pub artifacts: Option<(Artifact, Arc<ArtifactSamples>)>,
}

/// What the UI receives.
#[derive(Clone, Debug)]
pub struct Built {
    pub seq: u64,
    /// The request's `view_seq`.
    pub view_seq: u64,
    pub geometry: Arc<Geometry>,
    /// Links drawn, links matching the filter.
    pub link_stats: (usize, usize),
    /// Cluster links drawn, of those carried that match the filter (when drawn).
    pub cluster_link_stats: Option<(usize, usize)>,
    pub link_scale: Option<LogScale>,
    pub error_scale: Option<LogScale>,
    /// How the mesh was coloured (the request's).
    pub coloring: Coloring,
    /// Auto exposure of this solver state ([`auto_exposure`]).
    pub auto_ev: Option<f32>,
    /// The critical edges drawn, by kind (for the legend).
    pub critical: Option<SegmentCounts>,
    /// Wall time of the build, seconds.
    pub build_s: f64,
}

/// A build that panicked: its request's sequence number and what happened.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BuildFailed {
    pub seq: u64,
    /// One line: "the display thread panicked at …".
    pub message: String,
}

/// Name of the builder thread in its panic messages.
const THREAD: &str = "display";

/// [`build`], a panic in it caught: the build, or why there is none.
pub fn try_build(req: &Request) -> Result<Built, BuildFailed> {
    panics::catching(THREAD, || build(req)).map_err(|message| BuildFailed { seq: req.seq, message })
}

/// A scene's critical edges, kept between builds (found once per scene).
pub type CriticalCache = Option<(usize, Arc<CriticalEdges>)>;

/// Build the geometry of one request (the builder thread runs [`build_cached`]; tests may call
/// this directly).
#[must_use]
pub fn build(req: &Request) -> Built {
    build_cached(req, &mut None)
}

/// [`build`], reusing the critical edges of `cache` when they are the request scene's.
#[must_use]
pub fn build_cached(req: &Request, cache: &mut CriticalCache) -> Built {
    let started = Instant::now();
    let v = &req.view;
    let s = &req.settings;
    let true_error = req.true_error.as_deref().filter(|e| e.len() == v.elements.len());
    let (heat, error_scale) = match true_error {
        Some(e) => overlay::heatmap_colors(e),
        None => overlay::heatmap_colors(&v.elements.iter().map(|e| e.error_estimate).collect::<Vec<_>>()),
    };
    let own = match s.coloring {
        Coloring::Nodal => v.own_coefficients(),
        _ => None,
    };
    let colors = match s.coloring {
        Coloring::Error => MeshColors::Display(&heat),
        Coloring::Smooth => MeshColors::Smooth,
        Coloring::Flat => MeshColors::Flat,
        // Each element's own function: its p = 1 vertex values or its value with its slope;
        // without either, its constant.
        Coloring::Nodal => own.as_deref().map_or(MeshColors::Flat, MeshColors::Nodal),
    };
    // Cut at a depth: the elements that tile the scene there, the links between them and above.
    let (cut_leaves, cut_links);
    let (leaves, links): (&[u32], &[_]) = match s.depth_limit {
        Some(d) => {
            cut_leaves = cut_at_depth(&v.elements, d);
            let within = |id: u32| v.elements.get(id as usize).is_some_and(|e| e.depth <= d);
            cut_links = v
                .links
                .iter()
                .filter(|l| within(l.receiver) && within(l.source))
                .copied()
                .collect::<Vec<_>>();
            (&cut_leaves, &cut_links)
        }
        None => (&v.leaves, &v.links),
    };
    let mesh = geometry::mesh(&v.elements, leaves, colors, s.origin);
    let (mut links, link_stats, link_scale) = match &s.links {
        Some(filter) => {
            let ll = overlay::link_lines(&v.elements, links, filter, s.link_alpha);
            (geometry::lines(&ll.lines, s.origin), (ll.shown, ll.matched), ll.scale)
        }
        None => (Vec::new(), (0, 0), None),
    };
    // Cluster links on the element links' colour scale (their own when no element link shows).
    let mut cluster_link_stats = None;
    let mut link_scale = link_scale;
    if let Some(filter) = s.links.as_ref().filter(|_| s.cluster_links)
        && !v.cluster_links.is_empty()
    {
        // "Picked element only": the links of the picked cluster; else those of the element's
        // patch and of the clusters holding it.
        let picked = filter.element.map(|id| match s.picked_cluster {
            Some(c) => vec![crate::solver::hierarchical::ClusterEnd::Cluster(c)],
            None => {
                let patch = v.elements.get(id as usize).map_or(u32::MAX, |e| e.patch);
                overlay::cluster_chain(&v.clusters, &v.patch_cluster, patch)
            }
        });
        let cl = overlay::cluster_link_lines(
            &v.cluster_links,
            filter,
            picked.as_deref(),
            link_scale,
            s.link_alpha,
        );
        links.extend(geometry::lines(&cl.lines, s.origin));
        cluster_link_stats = Some((cl.shown, cl.matched));
        link_scale = link_scale.or(cl.scale);
    }
    let (mut overlay, critical) = match (&req.scene, s.critical) {
        (Some(scene), true) => {
            let key = Arc::as_ptr(scene) as usize;
            let edges = match cache {
                Some((k, e)) if *k == key => Arc::clone(e),
                _ => {
                    let e = Arc::new(critical_edges(scene));
                    *cache = Some((key, Arc::clone(&e)));
                    e
                }
            };
            (geometry::lines(&critical_lines(scene, &edges), s.origin), Some(edges.counts))
        }
        _ => (Vec::new(), None),
    };
    if let (Some(scene), Some((which, samples))) = (&req.scene, &req.artifacts) {
        overlay.extend(geometry::lines(&artifact_lines(scene, samples, *which), s.origin));
    }
    if let Some(depths) = &s.clusters {
        overlay.extend(geometry::lines(
            &overlay::cluster_lines(&v.clusters, depths.0..=depths.1, 0.9),
            s.origin,
        ));
    }
    if let Some(c) = s.picked_cluster.and_then(|c| v.clusters.get(c as usize)) {
        let mut edges = overlay::cluster_lines(std::slice::from_ref(c), c.depth..=c.depth, 1.0);
        edges.colors.fill(PICKED_CLUSTER_RGBA);
        overlay.extend(geometry::lines(&edges, s.origin));
    }
    Built {
        seq: req.seq,
        view_seq: req.view_seq,
        geometry: Arc::new(Geometry { mesh, links, links_xray: s.links_xray, overlay }),
        link_stats,
        cluster_link_stats,
        link_scale,
        error_scale,
        coloring: s.coloring,
        auto_ev: auto_exposure(v),
        critical,
        build_s: started.elapsed().as_secs_f64(),
    }
}

/// The elements that tile the scene when the quadtrees are cut at depth `d`: those at depth `d`
/// and the leaves above it (ascending ids).
#[must_use]
pub fn cut_at_depth(elements: &[crate::present::overlay::ElementView], d: u8) -> Vec<u32> {
    elements.iter().filter(|e| e.depth == d || (e.leaf && e.depth < d)).map(|e| e.id).collect()
}

/// Target display value of the 95th-percentile radiosity under auto exposure.
const AUTO_EXPOSURE_TARGET: f64 = 0.8;

/// Exposure (EV) that maps the 95th percentile of the non-emitting leaves' luminance to
/// `AUTO_EXPOSURE_TARGET`; `None` while everything is dark (before the first gather). On a mesh
/// solve the percentile is of area (a discontinuity mesh packs its many small pieces into the
/// shadows, so a count would over-expose); on the quadtree, of leaves.
#[must_use]
pub fn auto_exposure(view: &ViewData) -> Option<f32> {
    let by_area = view.mesh.is_some();
    let mut lum: Vec<(f64, f64)> = view
        .leaves
        .iter()
        .map(|&l| &view.elements[l as usize])
        .filter(|e| e.emission.is_zero())
        .map(|e| (e.radiosity.luminance(), if by_area { e.area } else { 1.0 }))
        .filter(|(l, _)| *l > 0.0 && l.is_finite())
        .collect();
    if lum.is_empty() {
        return None;
    }
    lum.sort_by(|a, b| a.0.total_cmp(&b.0));
    let p95 = if by_area {
        let total: f64 = lum.iter().map(|x| x.1).sum();
        let mut acc = 0.0;
        lum.iter()
            .find(|x| {
                acc += x.1;
                acc >= 0.95 * total
            })
            .map_or(lum[lum.len() - 1].0, |x| x.0)
    } else {
        lum[(lum.len() - 1) * 95 / 100].0
    };
    // Rounded to the exposure slider's 0.1 EV step, so the slider does not see a change.
    let ev = ((AUTO_EXPOSURE_TARGET / p95).log2() * 10.0).round() / 10.0;
    Some((ev as f32).clamp(-12.0, 12.0))
}

/// Handle of the builder thread (it ends when this is dropped).
pub struct Builder {
    tx: Sender<Request>,
    rx: Receiver<Result<Built, BuildFailed>>,
    /// Sequence number of the newest request sent.
    pub requested: Option<u64>,
    /// Sequence number of the newest answer received (a build handed out, or a failure).
    received: Option<u64>,
    /// The newest failed build not taken yet ([`Builder::take_failure`]).
    failed: Option<BuildFailed>,
}

impl Builder {
    /// Start the thread; `notify` is called after each build (the UI's repaint request).
    pub fn spawn(notify: impl Fn() + Send + 'static) -> Result<Builder, String> {
        let (tx, job_rx) = channel::<Request>();
        let (done_tx, rx) = channel::<Result<Built, BuildFailed>>();
        std::thread::Builder::new()
            .name("radlab-display".into())
            .spawn(move || {
                let mut cache: CriticalCache = None;
                while let Ok(mut req) = job_rx.recv() {
                    // Only the newest queued request matters.
                    loop {
                        match job_rx.try_recv() {
                            Ok(newer) => req = newer,
                            Err(TryRecvError::Empty) => break,
                            Err(TryRecvError::Disconnected) => return,
                        }
                    }
                    let seq = req.seq;
                    let answer = panics::catching(THREAD, || build_cached(&req, &mut cache));
                    let answer = answer.map_err(|message| {
                        cache = None; // possibly half written
                        BuildFailed { seq, message }
                    });
                    if done_tx.send(answer).is_err() {
                        return;
                    }
                    notify();
                }
            })
            .map_err(|e| format!("cannot start the display thread: {e}"))?;
        Ok(Builder { tx, rx, requested: None, received: None, failed: None })
    }

    /// Queue a build.
    pub fn request(&mut self, req: Request) {
        let seq = req.seq;
        if self.tx.send(req).is_ok() {
            self.requested = Some(seq);
        }
    }

    /// The newest finished build, if any (never blocks). A failed build is kept for
    /// [`Builder::take_failure`].
    pub fn poll(&mut self) -> Option<Built> {
        let mut last = None;
        loop {
            match self.rx.try_recv() {
                Ok(answer) => last = self.receive(answer).or(last),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.stopped();
                    break;
                }
            }
        }
        last
    }

    /// Block until the newest request is answered, and return its build unless it was handed
    /// out already or failed (tests and scripted runs only; never in `ui`).
    pub fn wait(&mut self) -> Option<Built> {
        let want = self.requested?;
        let answered = |r: Option<u64>| r.is_some_and(|r| r >= want);
        if answered(self.received) {
            return None;
        }
        loop {
            match self.rx.recv() {
                Ok(answer) => {
                    let built = self.receive(answer);
                    if answered(self.received) {
                        return built;
                    }
                }
                Err(_) => {
                    self.stopped();
                    return None;
                }
            }
        }
    }

    /// The newest build that failed since the last call, if any.
    pub fn take_failure(&mut self) -> Option<BuildFailed> {
        self.failed.take()
    }

    /// Note an answer: a build is handed out, a failure kept.
    fn receive(&mut self, answer: Result<Built, BuildFailed>) -> Option<Built> {
        match answer {
            Ok(b) => {
                self.received = Some(b.seq);
                Some(b)
            }
            Err(f) => {
                self.received = Some(f.seq);
                self.failed = Some(f);
                None
            }
        }
    }

    /// The thread is gone: the newest request will not be answered, so it failed.
    fn stopped(&mut self) {
        if let Some(want) = self.requested
            && self.received.is_none_or(|r| r < want)
        {
            self.received = Some(want);
            self.failed = Some(BuildFailed { seq: want, message: format!("the {THREAD} thread stopped") });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;
    use crate::present::overlay::{ElementCore, ElementView, LinkView};

    fn view() -> Arc<ViewData> {
        let sq = |id: u32, x: f64| ElementView {
            core: ElementCore {
                id,
                patch: id,
                parent: None,
                depth: 0,
                vertices: [
                    DVec3::new(x, 0.0, 0.0),
                    DVec3::new(x + 1.0, 0.0, 0.0),
                    DVec3::new(x + 1.0, 1.0, 0.0),
                    DVec3::new(x, 1.0, 0.0),
                ],
                n_vertices: 4,
                area: 1.0,
                reflectance: Rgb::splat(0.5),
                emission: Rgb::ZERO,
                radiosity: Rgb::splat(0.5),
                error_estimate: 0.1 * f64::from(id + 1),
            },
            leaf: true,
            stop: "",
        };
        Arc::new(ViewData {
            elements: vec![sq(0, 0.0), sq(1, 2.0)],
            leaves: vec![0, 1],
            links: vec![LinkView { receiver: 0, source: 1, ff: 0.1, vis: 1.0 }],
            ..ViewData::default()
        })
    }

    fn settings() -> Settings {
        Settings {
            coloring: Coloring::Smooth,
            links: Some(LinkFilter::default()),
            link_alpha: 1.0,
            links_xray: false,
            cluster_links: true,
            origin: DVec3::ZERO,
            depth_limit: None,
            critical: false,
            clusters: None,
            picked_cluster: None,
        }
    }

    #[test]
    fn builds_on_its_thread_newest_request_wins() {
        let mut b = Builder::spawn(|| {}).unwrap();
        assert!(b.wait().is_none(), "nothing requested");
        for seq in 1..=3 {
            b.request(Request {
                seq,
                view: view(),
                view_seq: 0,
                true_error: None,
                settings: settings(),
                scene: None,
                artifacts: None,
            });
        }
        let built = b.wait().unwrap();
        assert_eq!(built.seq, 3);
        assert!(b.wait().is_none(), "handed out already: does not block");
        assert_eq!(built.geometry.mesh.triangles(), 4);
        assert_eq!(built.geometry.links.len(), 2);
        assert_eq!(built.link_stats, (1, 1));
        assert!(built.auto_ev.is_some());
    }

    #[test]
    fn a_build_that_panics_is_answered_and_the_thread_goes_on() {
        let mut b = Builder::spawn(|| {}).unwrap();
        let request = |seq: u64, view: Arc<ViewData>| Request {
            seq,
            view,
            view_seq: 0,
            true_error: None,
            settings: settings(),
            scene: None,
            artifacts: None,
        };
        // A leaf index past the element list: the mesh build panics.
        let broken = Arc::new(ViewData { leaves: vec![0, 9], ..(*view()).clone() });
        b.request(request(1, Arc::clone(&broken)));
        assert!(b.wait().is_none(), "no build");
        let f = b.take_failure().expect("the failure is kept");
        assert_eq!(f.seq, 1);
        assert!(f.message.starts_with("the display thread panicked"), "{}", f.message);
        assert!(b.wait().is_none() && b.take_failure().is_none(), "answered once: nothing waits for it");
        // The thread survived: the next request builds.
        b.request(request(2, view()));
        assert_eq!(b.wait().map(|built| built.seq), Some(2));
        // Without waiting: the failure comes with the poll that sees it.
        b.request(request(3, broken));
        let deadline = Instant::now() + std::time::Duration::from_secs(60);
        while b.received < Some(3) {
            assert!(b.poll().is_none());
            assert!(Instant::now() < deadline, "no answer");
            std::thread::yield_now();
        }
        assert_eq!(b.take_failure().map(|f| f.seq), Some(3));
        assert!(try_build(&request(4, view())).is_ok());
        assert!(
            try_build(&request(5, Arc::new(ViewData { leaves: vec![7], ..ViewData::default() }))).is_err()
        );
    }

    #[test]
    fn true_error_replaces_the_estimate_when_it_fits() {
        let mut s = settings();
        s.coloring = Coloring::Error;
        s.links = None;
        let est = build(&Request {
            seq: 0,
            view: view(),
            view_seq: 0,
            true_error: None,
            settings: s,
            scene: None,
            artifacts: None,
        });
        let err = build(&Request {
            seq: 0,
            view: view(),
            view_seq: 0,
            true_error: Some(Arc::new(vec![1.0, 100.0])),
            settings: s,
            scene: None,
            artifacts: None,
        });
        assert!(est.error_scale.is_some() && err.error_scale.is_some());
        assert_ne!(est.error_scale, err.error_scale, "the true error sets the scale");
        // A list of the wrong length (a stale reference) is ignored.
        let bad = build(&Request {
            seq: 0,
            view: view(),
            view_seq: 0,
            true_error: Some(Arc::new(vec![1.0])),
            settings: s,
            scene: None,
            artifacts: None,
        });
        assert_eq!(bad.error_scale, est.error_scale);
        assert!(err.geometry.links.is_empty());
    }
}
