//! What the viewer points at: the outlines of a hovered element or link (receiver, source and
//! the line between them), and picking, the nearest leaf hit by a ray through the cursor.

use super::{ElementView, LineList};
use crate::math::DVec3;

/// What the viewer highlights in 3-D and in the blocking matrix: one link (a block of the
/// matrix hovered) or one element (hovered or picked in the viewport).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Highlight {
    /// Receiver p gathers from source q.
    Link {
        receiver: u32,
        source: u32,
    },
    Element(u32),
}

/// Outline colour of a highlighted receiver (orange).
pub const HIGHLIGHT_RECEIVER: [f32; 4] = [1.0, 0.55, 0.1, 1.0];
/// Outline colour of a highlighted source (cyan).
pub const HIGHLIGHT_SOURCE: [f32; 4] = [0.2, 0.85, 1.0, 1.0];
/// Colour of a highlighted link's line.
pub const HIGHLIGHT_LINK: [f32; 4] = [1.0, 1.0, 1.0, 1.0];

/// The lines of a highlight: each element's outline (receiver orange, source cyan, a lone
/// element orange), then for a link the line between the two centroids (white). Ids outside
/// `elements` draw nothing.
#[must_use]
pub fn highlight_lines(elements: &[ElementView], h: Highlight) -> LineList {
    let mut out = LineList::default();
    let mut outline = |id: u32, color: [f32; 4]| {
        let Some(e) = elements.get(id as usize) else { return false };
        let v = e.verts();
        for i in 0..v.len() {
            out.push(v[i], v[(i + 1) % v.len()], color);
        }
        true
    };
    match h {
        Highlight::Element(id) => {
            outline(id, HIGHLIGHT_RECEIVER);
        }
        Highlight::Link { receiver, source } => {
            if outline(receiver, HIGHLIGHT_RECEIVER) & outline(source, HIGHLIGHT_SOURCE) {
                let (r, s) = (&elements[receiver as usize], &elements[source as usize]);
                out.push(r.centroid(), s.centroid(), HIGHLIGHT_LINK);
            }
        }
    }
    out
}

/// Relative tolerance of the inside test (fraction of the element's edge length), so a ray
/// through a shared edge hits one of the two elements.
const PICK_EDGE_EPS: f64 = 1e-9;

/// The nearest leaf hit by the ray `origin + t·dir` (t > 0), either side; `(id, t)`.
#[must_use]
pub fn pick(elements: &[ElementView], leaves: &[u32], origin: DVec3, dir: DVec3) -> Option<(u32, f64)> {
    let mut best: Option<(u32, f64)> = None;
    for &l in leaves {
        let e = &elements[l as usize];
        let v = e.verts();
        if v.len() < 3 {
            continue;
        }
        let n = e.normal();
        let denom = n.dot(dir);
        if denom.abs() < 1e-300 {
            continue;
        }
        let t = n.dot(v[0] - origin) / denom;
        if t.is_nan() || t <= 0.0 || best.is_some_and(|(_, bt)| t >= bt) {
            continue;
        }
        let p = origin + dir * t;
        let inside = (0..v.len()).all(|i| {
            let a = v[i];
            let b = v[(i + 1) % v.len()];
            let edge = b - a;
            edge.cross(p - a).dot(n) >= -PICK_EDGE_EPS * edge.length_squared()
        });
        if inside {
            best = Some((e.id, t));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::overlay::test_support::quad;

    #[test]
    fn highlight_outlines_both_elements_and_draws_the_link() {
        let e = vec![quad(0, 0, 0.0, 0.0, 1.0, 0.5), quad(1, 0, 2.0, 0.0, 1.0, 0.5)];
        let l = highlight_lines(&e, Highlight::Link { receiver: 0, source: 1 });
        assert_eq!(l.segments(), 4 + 4 + 1, "two quads' edges and the link");
        assert_eq!(l.colors[0], HIGHLIGHT_RECEIVER);
        assert_eq!(l.colors[8], HIGHLIGHT_SOURCE);
        let n = l.points.len();
        assert_eq!((l.points[n - 2], l.points[n - 1]), (e[0].centroid(), e[1].centroid()));
        assert_eq!(l.colors[n - 1], HIGHLIGHT_LINK);
        assert_eq!(highlight_lines(&e, Highlight::Element(1)).segments(), 4);
        assert_eq!(
            highlight_lines(&e, Highlight::Link { receiver: 0, source: 7 }).segments(),
            4,
            "no link line to a missing element"
        );
    }

    #[test]
    fn pick_nearest_leaf_either_side() {
        let mut far = quad(1, 0, 0.0, 0.0, 1.0, 1.0);
        for v in &mut far.vertices {
            v.z = -1.0;
        }
        let els = vec![quad(0, 0, 0.0, 0.0, 1.0, 1.0), far];
        let down = DVec3::new(0.0, 0.0, -1.0);
        assert_eq!(pick(&els, &[0, 1], DVec3::new(0.5, 0.5, 2.0), down).map(|h| h.0), Some(0));
        assert_eq!(pick(&els, &[1], DVec3::new(0.5, 0.5, 2.0), down).map(|h| h.0), Some(1));
        // From below the front faces of both still count; the nearest is element 1.
        assert_eq!(pick(&els, &[0, 1], DVec3::new(0.5, 0.5, -3.0), -down).map(|h| h.0), Some(1));
        assert_eq!(pick(&els, &[0, 1], DVec3::new(1.5, 0.5, 2.0), down), None);
    }
}
