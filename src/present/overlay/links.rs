//! The links overlay: a line between receiver and source centroids per link (B_p gathers
//! ρ_p F_pq V_pq B_q through it; lecture 17's p/q), coloured by log₁₀ F, filtered by element
//! (with its ancestors' links), minimum F and visibility class and decimated to a few thousand;
//! cluster links as dashed lines; cluster bounding boxes coloured by depth.

use super::colors::{LogScale, Palette};
use super::{ElementView, LineList, LinkView, VisClass};
use crate::math::DVec3;
use crate::solver::hierarchical::ClusterEnd;

/// Default decimation of the links overlay: beyond a few thousand lines a room is a solid
/// fan of lines.
pub const DEFAULT_MAX_LINKS: usize = 3000;

/// How the links overlay thins out when more links pass the filter than `max_lines`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Decimation {
    /// Every k-th link in receiver order: a representative sample of the whole hierarchy.
    Strided,
    /// The largest form factors (often the tiny elements along shared corners).
    LargestF,
}

/// Which links to draw.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LinkFilter {
    /// Only the links this element gathers through: those whose receiver is the element or one
    /// of its ancestors (an element also gathers through the links of the elements above it).
    /// The links it shoots through (it as source) are the reverse links of other elements.
    pub element: Option<u32>,
    pub min_ff: f32,
    pub full: bool,
    pub partial: bool,
    pub none: bool,
    /// Decimation: at most this many lines, chosen by `decimation`.
    pub max_lines: usize,
    pub decimation: Decimation,
}

impl Default for LinkFilter {
    fn default() -> Self {
        LinkFilter {
            element: None,
            min_ff: 0.0,
            full: true,
            partial: true,
            none: false,
            max_lines: DEFAULT_MAX_LINKS,
            decimation: Decimation::Strided,
        }
    }
}

impl LinkFilter {
    /// Whether links of visibility class `class` pass.
    fn shows(&self, class: VisClass) -> bool {
        match class {
            VisClass::Full => self.full,
            VisClass::Partial => self.partial,
            VisClass::None => self.none,
        }
    }
}

/// Link lines and what was kept.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkLines {
    pub lines: LineList,
    /// Links passing the filter.
    pub matched: usize,
    /// Links drawn (after decimation).
    pub shown: usize,
    /// The colour scale of F over the matched links.
    pub scale: Option<LogScale>,
}

/// The element and its ancestors (an element gathers through its own links and its ancestors').
#[must_use]
pub fn ancestors(elements: &[ElementView], id: u32) -> Vec<u32> {
    let mut out = vec![id];
    let mut cur = elements.get(id as usize).and_then(|e| e.parent);
    while let Some(p) = cur {
        if out.len() > 64 {
            break; // a cycle would be a solver bug; never loop forever on display
        }
        out.push(p);
        cur = elements.get(p as usize).and_then(|e| e.parent);
    }
    out
}

/// Lines between link endpoints' centroids, coloured by log₁₀ F (viridis), `alpha` each.
#[must_use]
pub fn link_lines(
    elements: &[ElementView],
    links: &[LinkView],
    filter: &LinkFilter,
    alpha: f32,
) -> LinkLines {
    let chain = filter.element.map(|id| ancestors(elements, id));
    let mut kept: Vec<&LinkView> = links
        .iter()
        .filter(|l| {
            (l.receiver as usize) < elements.len()
                && (l.source as usize) < elements.len()
                && l.ff >= filter.min_ff
                && filter.shows(l.class())
                && chain.as_ref().is_none_or(|c| c.contains(&l.receiver))
        })
        .collect();
    let matched = kept.len();
    let scale = LogScale::spanning(kept.iter().map(|l| f64::from(l.ff)));
    if kept.len() > filter.max_lines {
        match filter.decimation {
            Decimation::LargestF => {
                kept.sort_by(|a, b| {
                    b.ff.total_cmp(&a.ff).then(a.receiver.cmp(&b.receiver)).then(a.source.cmp(&b.source))
                });
                kept.truncate(filter.max_lines);
            }
            Decimation::Strided => {
                let stride = kept.len().div_ceil(filter.max_lines.max(1));
                kept = kept.into_iter().step_by(stride).collect();
            }
        }
    }
    let mut lines = LineList::default();
    for l in &kept {
        let t = scale.map_or(0.0, |s| s.t(f64::from(l.ff)));
        let [r, g, b] = Palette::Viridis.at(t);
        lines.push(
            elements[l.receiver as usize].centroid(),
            elements[l.source as usize].centroid(),
            [r, g, b, alpha],
        );
    }
    LinkLines { shown: kept.len(), lines, matched, scale }
}

/// Each cluster link is drawn as this many dashes (with as many gaps), so it reads apart from
/// the element links' solid lines.
pub const CLUSTER_LINK_DASHES: usize = 6;

/// Dashed lines between the two ends' centres of the cluster links (clustered solves) that pass
/// `filter`'s minimum F and visibility classes, coloured by log₁₀ F on `scale`
/// (the element links' scale, so both read on one colour bar; `None`: the cluster links' own),
/// at most `filter.max_lines` of them, taken in the order given (the viewer keeps them largest
/// F first). `picked`, when given, keeps only the links with an end among those nodes: the
/// picked element's patch and the clusters holding it ([`cluster_chain`]), whose links the
/// element gathers through (`filter.element` itself names an element, not a cluster).
#[must_use]
pub fn cluster_link_lines(
    links: &[crate::solver::hierarchical::ClusterLinkView],
    filter: &LinkFilter,
    picked: Option<&[ClusterEnd]>,
    scale: Option<LogScale>,
    alpha: f32,
) -> LinkLines {
    let class = |vis: f32| LinkView { receiver: 0, source: 0, ff: 0.0, vis }.class();
    let kept: Vec<_> = links
        .iter()
        .filter(|l| {
            picked.is_none_or(|on| l.ends.iter().any(|e| on.contains(e)))
                && l.ff >= f64::from(filter.min_ff)
                && filter.shows(class(l.vis))
        })
        .collect();
    let matched = kept.len();
    let scale = scale.or_else(|| LogScale::spanning(kept.iter().map(|l| l.ff)));
    let mut lines = LineList::default();
    for l in kept.iter().take(filter.max_lines) {
        let [r, g, b] = Palette::Viridis.at(scale.map_or(0.0, |s| s.t(l.ff)));
        let at = |k: usize| l.from.lerp(l.to, k as f64 / (2 * CLUSTER_LINK_DASHES - 1) as f64);
        for dash in 0..CLUSTER_LINK_DASHES {
            lines.push(at(2 * dash), at(2 * dash + 1), [r, g, b, alpha]);
        }
    }
    LinkLines { shown: matched.min(filter.max_lines), lines, matched, scale }
}

/// The cluster-link ends an element of input patch `patch` gathers through: the patch itself,
/// then the clusters holding it, smallest first (`clusters` and `patch_cluster` as
/// [`crate::solver::hierarchical::Snapshot`] has them; only the patch when it has none).
#[must_use]
pub fn cluster_chain(
    clusters: &[crate::solver::hierarchical::ClusterInfo],
    patch_cluster: &[u32],
    patch: u32,
) -> Vec<ClusterEnd> {
    let mut chain = vec![ClusterEnd::Patch(patch)];
    let mut at = patch_cluster.get(patch as usize).copied().filter(|&c| c != u32::MAX);
    while let Some(i) = at {
        chain.push(ClusterEnd::Cluster(i));
        at = clusters.get(i as usize).and_then(|c| c.parent);
    }
    chain
}

/// The twelve edges of every cluster's bounding box whose depth is in `depths` (inclusive),
/// coloured by depth (viridis over the range shown): the cluster overlay.
#[must_use]
pub fn cluster_lines(
    clusters: &[crate::solver::hierarchical::ClusterInfo],
    depths: std::ops::RangeInclusive<u8>,
    alpha: f32,
) -> LineList {
    let mut lines = LineList::default();
    let span = f64::from(depths.end().saturating_sub(*depths.start()).max(1));
    for c in clusters.iter().filter(|c| depths.contains(&c.depth)) {
        let t = f64::from(c.depth - depths.start()) / span;
        let [r, g, b] = Palette::Viridis.at(t);
        let corner = |k: usize| {
            DVec3::new(
                if k & 1 == 0 { c.bmin.x } else { c.bmax.x },
                if k & 2 == 0 { c.bmin.y } else { c.bmax.y },
                if k & 4 == 0 { c.bmin.z } else { c.bmax.z },
            )
        };
        // Corners differing in one bit share an edge.
        for k in 0..8 {
            for bit in [1, 2, 4] {
                if k & bit == 0 {
                    lines.push(corner(k), corner(k | bit), [r, g, b, alpha]);
                }
            }
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::overlay::test_support::{EXACT, quad};

    #[test]
    fn cluster_boxes_draw_twelve_edges_in_the_depths_asked_for() {
        use crate::solver::hierarchical::ClusterInfo;
        let c = |depth: u8, lo: f64| ClusterInfo {
            depth,
            bmin: DVec3::splat(lo),
            bmax: DVec3::splat(lo + 1.0),
            patches: 2,
            links: 0,
            parent: None,
        };
        let clusters = [c(0, 0.0), c(1, 2.0), c(2, 4.0), c(2, 6.0)];
        let all = cluster_lines(&clusters, 0..=2, 1.0);
        assert_eq!(all.segments(), 4 * 12);
        // Every edge is axis-aligned and one box side long.
        for seg in all.points.chunks(2) {
            let d = (seg[1] - seg[0]).abs();
            assert!((d.x + d.y + d.z - 1.0).abs() < 1e-12 && d.max_element() == 1.0, "{seg:?}");
        }
        let deep = cluster_lines(&clusters, 2..=2, 1.0);
        assert_eq!(deep.segments(), 2 * 12);
        assert!(deep.points.iter().all(|p| p.x >= 4.0));
        // Colour by depth: the root and the deepest level differ.
        assert_ne!(all.colors[0], all.colors[all.colors.len() - 1]);
    }

    /// Three unit squares side by side along x, B = 1.
    fn three_in_a_row() -> Vec<ElementView> {
        (0..3).map(|i| quad(i, 0, f64::from(i), 0.0, 1.0, 1.0)).collect()
    }

    fn links() -> Vec<LinkView> {
        vec![
            LinkView { receiver: 0, source: 1, ff: 0.2, vis: 1.0 },
            LinkView { receiver: 1, source: 0, ff: 0.002, vis: 0.5 },
            LinkView { receiver: 2, source: 1, ff: 0.02, vis: 0.0 },
        ]
    }

    #[test]
    fn link_filter_and_log_colours() {
        let els = three_in_a_row();
        let all = LinkFilter { none: true, ..LinkFilter::default() };
        let r = link_lines(&els, &links(), &all, 1.0);
        assert_eq!((r.matched, r.shown), (3, 3));
        let s = r.scale.unwrap();
        assert!((s.lo - 0.002).abs() < 1e-9 && (s.hi - 0.2).abs() < 1e-7);
        // Largest F gets the top colour, smallest the bottom one.
        assert_eq!(r.lines.colors[0][..3], Palette::Viridis.at(1.0));
        assert_eq!(r.lines.colors[2][..3], Palette::Viridis.at(0.0));
        // Default filter hides invisible links.
        assert_eq!(link_lines(&els, &links(), &LinkFilter::default(), 1.0).matched, 2);
        // Minimum F and element filters.
        let f = LinkFilter { min_ff: 0.01, none: true, ..LinkFilter::default() };
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 2);
        let f = LinkFilter { element: Some(2), none: true, ..LinkFilter::default() };
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 1);
        // Decimation: the strongest, or every k-th.
        let f = LinkFilter {
            max_lines: 1,
            none: true,
            decimation: Decimation::LargestF,
            ..LinkFilter::default()
        };
        let r = link_lines(&els, &links(), &f, 1.0);
        assert_eq!((r.matched, r.shown), (3, 1));
        assert!((r.lines.points[0].x - 0.5).abs() < EXACT, "the F=0.2 link starts at element 0's centre");
        let f = LinkFilter { max_lines: 2, none: true, ..LinkFilter::default() };
        let r = link_lines(&els, &links(), &f, 1.0);
        assert_eq!((r.matched, r.shown), (3, 2), "stride 2 keeps links 0 and 2");
        assert!((r.lines.points[2].x - 2.5).abs() < EXACT, "the second kept link starts at element 2");
    }

    #[test]
    fn element_filter_includes_ancestors_links() {
        let mut els = three_in_a_row();
        els[2].parent = Some(0);
        let f = LinkFilter { element: Some(2), none: true, ..LinkFilter::default() };
        // Element 2 gathers through its own link (receiver 2) and its parent 0's (receiver 0),
        // not through the link 0 shoots through (source 0, receiver 1).
        assert_eq!(link_lines(&els, &links(), &f, 1.0).matched, 2);
    }
}
