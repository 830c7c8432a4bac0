//! Critical segments on a receiver plane: where the radiosity from one emitter is discontinuous
//! in value (D0), first derivative (D1) or second derivative (D2) [Lischinski, Tampieri &
//! Greenberg 1992, "Discontinuity meshing for accurate radiosity", IEEE CG&A 12(6); Heckbert
//! 1992, "Discontinuity meshing for radiosity", 3rd Eurographics Workshop on Rendering].
//!
//! The visible part of a polygonal emitter seen from a receiver point x changes topology where x
//! crosses an *event surface*. With polygonal occluders the surfaces of the two kinds that
//! involve the emitter are planar wedges:
//!
//! ```text
//! EV: emitter vertex v, occluder edge [p, q]:  W = { v + τ (x − v) : x ∈ [p, q], τ ≥ 1 }
//! VE: emitter edge [a, b], occluder vertex w:  W = { c + τ (w − c) : c ∈ [a, b], τ ≥ 1 }
//! ```
//!
//! and the critical segment is `W ∩ receiver plane ∩ receiver polygon`. D0 (a jump in value)
//! lies where another surface touches or crosses the receiver: the line of the two planes,
//! clipped to both polygons.
//!
//! ## How it works: the wedge as a projective segment
//! With `h(x) = n_r·x − d_r` the height over the receiver plane, the ray from a centre c through a
//! point t meets the plane at
//!
//! ```text
//! P = (h(c) t − h(t) c) / (h(c) − h(t)) = N / D
//! ```
//!
//! Along a wedge one of c, t is fixed and the other runs along an edge with a parameter
//! s ∈ [0, 1], so N(s) and D(s) are affine in s, and so is every half-plane test on P after
//! multiplying by D > 0: `m·P ≥ k  ⇔  m·N(s) − k D(s) ≥ 0`. The segment's extent is then one
//! interval of s ([`super::clip_interval`]) under these affine constraints, with no division
//! until the end points:
//!
//! ```text
//! h(c(s)) > 0          the emitter point is in front of the (one-sided) receiver
//! h(t(s)) ≥ 0          the occluder point is not behind the receiver
//! D(s) = h(c) − h(t) > 0   the occluder point is nearer the receiver than the emitter point
//! g(t(s)) ≥ 0          the occluder point is in front of the (one-sided) emitter, g = n_e·x − d_e
//! m_k·N − k_k D ≥ 0    P inside the receiver polygon (one per edge)
//! ```
//!
//! A point at infinity (D → 0) cannot lie inside the bounded receiver, so the interval stays
//! finite; an interval whose D at an end is still ≤ 0 (degenerate input) is dropped.
//!
//! ## D1 or D2
//! An EV or VE event is generically D2 (the visible area is C¹ across it). It is D1 when the
//! wedge plane also contains an edge of the other polygon — an emitter edge and an occluder edge
//! in one plane (the EE degeneracy, e.g. parallel edges of axis-aligned squares): the occluder
//! edge's shadow then sweeps across a whole emitter edge at once [Heckbert 1992, sec. 3].
//!
//! ## Limiting the work
//! [`occluder_matters`] keeps an occluder only if it can block a segment from the emitter to the
//! receiver (a vertex in front of each plane, and a bounding box meeting that of emitter ∪
//! receiver, which holds their convex hull): conservative, it never culls a shadow. A scene costs
//! O(receivers × emitters × kept occluders), `|V_e|·|E_o| + |E_e|·|V_o|` wedges each;
//! [`SegmentCounts`] reports what was kept.
//!
//! ## Left out
//! EEE events (quadric surfaces, conic curves), events between occluders, the visibility of the
//! segments (a wedge hidden by another occluder is not clipped, so the output is a superset of
//! the events found), D0 between coplanar polygons and secondary emitters: docs/meshing.md,
//! "What is left out" [Teller 1992; Heckbert 1992, sec. 3; Lischinski et al., sec. 4].

use super::{ReceiverPlane, clip_interval};
use crate::math::DVec3;
use crate::scene::Patch;
use serde::Serialize;

/// How abrupt the radiosity is across a critical segment.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Discontinuity {
    /// A jump in value: surfaces touch or intersect.
    D0,
    /// A jump in the first derivative (an EE-degenerate EV/VE event).
    D1,
    /// A jump in the second derivative (a generic EV/VE event).
    D2,
}

/// What made a critical segment.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub enum Event {
    /// Another surface touches or crosses the receiver.
    Contact,
    /// Emitter vertex `vertex` with occluder edge `edge` (from vertex `edge` to `edge + 1`).
    EmitterVertexOccluderEdge { vertex: usize, edge: usize },
    /// Emitter edge `edge` with occluder vertex `vertex`.
    EmitterEdgeOccluderVertex { edge: usize, vertex: usize },
}

/// One critical segment on the receiver plane (inside the receiver polygon).
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct CriticalSegment {
    pub a: DVec3,
    pub b: DVec3,
    pub order: Discontinuity,
    pub event: Event,
    /// Index of the occluder (or touching surface) in the caller's list (a patch index for
    /// [`scene_segments`]).
    pub occluder: usize,
    /// Index of the emitter in the caller's list (`None` for D0).
    pub emitter: Option<usize>,
}

/// What [`receiver_segments`] and [`scene_segments`] found.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SegmentCounts {
    pub d0: usize,
    pub d1: usize,
    pub d2: usize,
    /// Segments from EV and from VE events (D1 + D2 = ev + ve).
    pub ev: usize,
    pub ve: usize,
    /// (emitter, occluder) pairs kept and culled by [`occluder_matters`].
    pub occluders_kept: usize,
    pub occluders_culled: usize,
}

impl SegmentCounts {
    /// All segments.
    #[must_use]
    pub fn total(&self) -> usize {
        self.d0 + self.d1 + self.d2
    }

    fn count(&mut self, s: &CriticalSegment) {
        match s.order {
            Discontinuity::D0 => self.d0 += 1,
            Discontinuity::D1 => self.d1 += 1,
            Discontinuity::D2 => self.d2 += 1,
        }
        match s.event {
            Event::Contact => {}
            Event::EmitterVertexOccluderEdge { .. } => self.ev += 1,
            Event::EmitterEdgeOccluderVertex { .. } => self.ve += 1,
        }
    }

    /// Sum of two counts.
    #[must_use]
    pub fn plus(self, o: SegmentCounts) -> SegmentCounts {
        SegmentCounts {
            d0: self.d0 + o.d0,
            d1: self.d1 + o.d1,
            d2: self.d2 + o.d2,
            ev: self.ev + o.ev,
            ve: self.ve + o.ve,
            occluders_kept: self.occluders_kept + o.occluders_kept,
            occluders_culled: self.occluders_culled + o.occluders_culled,
        }
    }
}

/// The critical segments of one receiver and their counts.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CriticalSet {
    pub segments: Vec<CriticalSegment>,
    pub counts: SegmentCounts,
}

impl CriticalSet {
    fn push(&mut self, s: CriticalSegment) {
        self.counts.count(&s);
        self.segments.push(s);
    }

    /// The segments as end-point pairs (what the meshers take).
    #[must_use]
    pub fn endpoints(&self) -> Vec<[DVec3; 2]> {
        self.segments.iter().map(|s| [s.a, s.b]).collect()
    }
}

/// Length scale of two polygons (for relative tolerances).
fn scale(a: &Patch, b: &Patch) -> f64 {
    a.diameter().max(b.diameter()).max(a.centroid.distance(b.centroid))
}

/// Signed height of `x` over a patch's plane.
fn height(p: &Patch, x: DVec3) -> f64 {
    p.normal.dot(x - p.centroid)
}

/// The conservative culling test of the module docs: can `occluder` block any segment from
/// `emitter` to `receiver`?
#[must_use]
pub fn occluder_matters(receiver: &Patch, emitter: &Patch, occluder: &Patch) -> bool {
    let tol = 1e-9 * scale(receiver, emitter);
    let in_front = |p: &Patch| occluder.vertices.iter().any(|x| height(p, *x) > tol);
    if !(in_front(receiver) && in_front(emitter)) {
        return false;
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for x in receiver.vertices.iter().chain(&emitter.vertices) {
        lo = lo.min(*x);
        hi = hi.max(*x);
    }
    let (mut olo, mut ohi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for x in &occluder.vertices {
        olo = olo.min(*x);
        ohi = ohi.max(*x);
    }
    (olo - tol).cmple(hi).all() && (ohi + tol).cmpge(lo).all()
}

/// D0: the segment where `other` touches or crosses `receiver` (their planes' line clipped to
/// both polygons; an edge of `other` along the line is moved out by a small tolerance, so that
/// an edge resting exactly on the receiver counts). `None` for parallel planes and for polygons that do not meet.
#[must_use]
pub fn contact_segment(receiver: &Patch, plane: &ReceiverPlane, other: &Patch) -> Option<[DVec3; 2]> {
    let (nr, no) = (receiver.normal, other.normal);
    let dir = nr.cross(no);
    let sin2 = dir.length_squared();
    if !(sin2 > 1e-18) {
        return None;
    }
    // A point on both planes, relative to the receiver's centroid (precision far from the origin).
    let origin = receiver.centroid;
    let d_o = no.dot(other.centroid - origin);
    let c = nr.dot(no);
    let p0 = origin + no * (d_o / sin2) - nr * (d_o * c / sin2);
    let dir = dir / sin2.sqrt();
    let tol = 1e-9 * scale(receiver, other);
    // Inward in-plane normals of both polygons' edges; the line is p0 + τ dir.
    let constraints = |p: &Patch, grow: f64| {
        let n = p.vertices.len();
        (0..n)
            .map(|k| {
                let (a, b) = (p.vertices[k], p.vertices[(k + 1) % n]);
                let m = p.normal.cross(b - a).normalize_or_zero();
                // Only an edge along the line is grown: crossing edges keep the ends exact.
                let along = m.dot(dir).abs() < 1e-6;
                (m.dot(p0 - a) + if along { grow } else { 0.0 }, m.dot(dir))
            })
            .collect::<Vec<_>>()
    };
    let big = 1e3 * scale(receiver, other) + p0.distance(origin);
    let (t0, t1) =
        clip_interval(-big, big, constraints(receiver, 0.0).into_iter().chain(constraints(other, tol)))?;
    let (a, b) = (p0 + t0 * dir, p0 + t1 * dir);
    let s = plane.clip(plane.to_2d(a), plane.to_2d(b))?;
    Some([plane.to_3d(s.a), plane.to_3d(s.b)])
}

/// An affine function of s ∈ [0, 1] given by its values at 0 and 1, as a `(c0, c1)` constraint.
fn affine(at0: f64, at1: f64) -> (f64, f64) {
    (at0, at1 - at0)
}

/// The segment of one wedge: centre c(s) and through point t(s) affine in s (one of them fixed),
/// clipped by the constraints of the module docs. `None` if empty or degenerate.
fn wedge_segment(
    receiver: &Patch,
    plane: &ReceiverPlane,
    emitter: &Patch,
    centre: [DVec3; 2],
    through: [DVec3; 2],
) -> Option<[DVec3; 2]> {
    let h = |x: DVec3| height(receiver, x);
    let g = |x: DVec3| height(emitter, x);
    // N and D at s = 0 and s = 1 (affine in s because one of c, t is constant).
    let num = |i: usize| {
        h(centre[i]) * (through[i] - receiver.centroid) - h(through[i]) * (centre[i] - receiver.centroid)
    };
    let den = |i: usize| h(centre[i]) - h(through[i]);
    let (n0, n1, d0, d1) = (num(0), num(1), den(0), den(1));
    let mut constraints = vec![
        affine(h(centre[0]), h(centre[1])),
        affine(h(through[0]), h(through[1])),
        affine(d0, d1),
        affine(g(through[0]), g(through[1])),
    ];
    let n = receiver.vertices.len();
    for k in 0..n {
        let (a, b) = (receiver.vertices[k], receiver.vertices[(k + 1) % n]);
        let m = receiver.normal.cross(b - a).normalize_or_zero();
        let off = m.dot(a - receiver.centroid);
        constraints.push(affine(m.dot(n0) - off * d0, m.dot(n1) - off * d1));
    }
    let (s0, s1) = clip_interval(0.0, 1.0, constraints)?;
    let at = |s: f64| {
        let d = d0 + s * (d1 - d0);
        let tiny = 1e-12 * (d0.abs() + d1.abs());
        (d > tiny).then(|| receiver.centroid + (n0 + s * (n1 - n0)) / d)
    };
    let (a, b) = (at(s0)?, at(s1)?);
    let s = plane.clip(plane.to_2d(a), plane.to_2d(b))?;
    Some([plane.to_3d(s.a), plane.to_3d(s.b)])
}

/// True if the plane through `points` (three of them, the wedge's) contains the segment [a, b].
fn plane_contains(plane_points: [DVec3; 3], a: DVec3, b: DVec3) -> bool {
    let [p, q, r] = plane_points;
    let w = (q - p).cross(r - p);
    let len = w.length();
    if !(len > 0.0) {
        return false;
    }
    let w = w / len;
    let tol = 1e-9 * (q - p).length().max((r - p).length()).max((b - a).length());
    w.dot(a - p).abs() <= tol && w.dot(b - p).abs() <= tol
}

/// EV and VE segments of one (emitter, occluder) pair on the receiver, appended to `out`.
pub fn event_segments(
    receiver: &Patch,
    plane: &ReceiverPlane,
    (emitter_id, emitter): (usize, &Patch),
    (occluder_id, occluder): (usize, &Patch),
    out: &mut CriticalSet,
) {
    let (ev, ov) = (&emitter.vertices, &occluder.vertices);
    let (ne, no) = (ev.len(), ov.len());
    // An edge of `poly` adjacent to vertex i lies in the plane.
    let adjacent_in_plane = |poly: &[DVec3], i: usize, pts: [DVec3; 3]| {
        let m = poly.len();
        plane_contains(pts, poly[i], poly[(i + 1) % m]) || plane_contains(pts, poly[(i + m - 1) % m], poly[i])
    };
    let mut push = |seg: Option<[DVec3; 2]>, d1: bool, event: Event| {
        if let Some([a, b]) = seg {
            let order = if d1 { Discontinuity::D1 } else { Discontinuity::D2 };
            out.push(CriticalSegment {
                a,
                b,
                order,
                event,
                occluder: occluder_id,
                emitter: Some(emitter_id),
            });
        }
    };
    for (vertex, &v) in ev.iter().enumerate() {
        for edge in 0..no {
            let (p, q) = (ov[edge], ov[(edge + 1) % no]);
            let seg = wedge_segment(receiver, plane, emitter, [v, v], [p, q]);
            let d1 = seg.is_some() && adjacent_in_plane(ev, vertex, [v, p, q]);
            push(seg, d1, Event::EmitterVertexOccluderEdge { vertex, edge });
        }
    }
    for edge in 0..ne {
        let (a, b) = (ev[edge], ev[(edge + 1) % ne]);
        for (vertex, &w) in ov.iter().enumerate() {
            let seg = wedge_segment(receiver, plane, emitter, [a, b], [w, w]);
            let d1 = seg.is_some() && adjacent_in_plane(ov, vertex, [a, b, w]);
            push(seg, d1, Event::EmitterEdgeOccluderVertex { edge, vertex });
        }
    }
}

/// The critical segments of `receiver` lit by `emitter` past `occluders`: D0 with every
/// occluder that touches or crosses it, EV/VE with every occluder that [`occluder_matters`].
/// Segment `occluder` fields index `occluders`; `emitter` is `Some(0)`.
pub fn receiver_segments(
    receiver: &Patch,
    emitter: &Patch,
    occluders: &[&Patch],
    snap: f64,
) -> Result<CriticalSet, super::MeshError> {
    let plane = ReceiverPlane::new(&receiver.vertices, snap)?;
    let mut out = CriticalSet::default();
    let others: Vec<(usize, &Patch)> = occluders.iter().copied().enumerate().collect();
    contacts(receiver, &plane, &others, &mut out);
    events(receiver, &plane, (0, emitter), &others, &mut out);
    Ok(out)
}

fn contacts(receiver: &Patch, plane: &ReceiverPlane, others: &[(usize, &Patch)], out: &mut CriticalSet) {
    for &(id, other) in others {
        if let Some([a, b]) = contact_segment(receiver, plane, other) {
            let order = Discontinuity::D0;
            out.push(CriticalSegment { a, b, order, event: Event::Contact, occluder: id, emitter: None });
        }
    }
}

fn events(
    receiver: &Patch,
    plane: &ReceiverPlane,
    emitter: (usize, &Patch),
    occluders: &[(usize, &Patch)],
    out: &mut CriticalSet,
) {
    for &occluder in occluders {
        if occluder_matters(receiver, emitter.1, occluder.1) {
            out.counts.occluders_kept += 1;
            event_segments(receiver, plane, emitter, occluder, out);
        } else {
            out.counts.occluders_culled += 1;
        }
    }
}

/// A receiver's plane, every other patch with its index, and the segments found so far.
type Receiver<'a> = (ReceiverPlane, Vec<(usize, &'a Patch)>, CriticalSet);

/// Patch `receiver`'s plane, every other patch with its index, and the receiver's D0 contacts
/// with them ([`contact_segment`]).
fn with_contacts(patches: &[Patch], receiver: usize, snap: f64) -> Result<Receiver<'_>, super::MeshError> {
    let r = &patches[receiver];
    let plane = ReceiverPlane::new(&r.vertices, snap)?;
    let mut out = CriticalSet::default();
    let others: Vec<(usize, &Patch)> = patches.iter().enumerate().filter(|&(i, _)| i != receiver).collect();
    contacts(r, &plane, &others, &mut out);
    Ok((plane, others, out))
}

/// Largest gap, as a fraction of the scene's diagonal, between a receiver and an edge of another
/// patch for [`scene_contacts`] to count the edge's shadow as a contact.
pub const NEAR_CONTACT_GAP: f64 = 0.01;

/// The D0 segments of patch `receiver` of a scene alone: where every other patch touches or
/// crosses it (an object standing on it, a wall meeting it). The radiosity jumps there from the
/// hidden side's to the lit side's whatever the emitters, and no refinement of elements that
/// straddle the line removes the jump (their error falls only as √h); the EV/VE events bound
/// penumbrae, which a hierarchical oracle refines by itself.
///
/// *Near* contacts count too: an edge of another patch that runs within `gap` of the receiver
/// (in front of it, at a height at most a tenth of the edge's length), e.g. a panel hung 7 units
/// off splash_room's wall or a shelf's back, casts a shadow whose penumbra is a sliver of the gap
/// wide whatever the emitters; its orthogonal projection onto the receiver stands for that
/// line. (With `gap` 0 only true contacts are found.)
pub fn scene_contacts(
    patches: &[Patch],
    receiver: usize,
    snap: f64,
    gap: f64,
) -> Result<CriticalSet, super::MeshError> {
    let r = &patches[receiver];
    let (plane, others, mut out) = with_contacts(patches, receiver, snap)?;
    if gap > 0.0 {
        for &(id, other) in &others {
            for [a, b] in near_contact_segments(r, &plane, other, gap) {
                let order = Discontinuity::D0;
                out.push(CriticalSegment { a, b, order, event: Event::Contact, occluder: id, emitter: None });
            }
        }
    }
    Ok(out)
}

/// The orthogonal projections onto `receiver` of the edges of `other` that run within `gap` in
/// front of it, no higher than a tenth of their own length, and not on it (those are
/// [`contact_segment`]'s), clipped to the receiver.
#[must_use]
pub fn near_contact_segments(
    receiver: &Patch,
    plane: &ReceiverPlane,
    other: &Patch,
    gap: f64,
) -> Vec<[DVec3; 2]> {
    let tol = 1e-9 * scale(receiver, other);
    let n = other.vertices.len();
    let mut out = Vec::new();
    for k in 0..n {
        let (a, b) = (other.vertices[k], other.vertices[(k + 1) % n]);
        let (ha, hb) = (height(receiver, a), height(receiver, b));
        let top = ha.max(hb);
        let near = ha >= -tol && hb >= -tol && top <= gap && top <= 0.1 * a.distance(b);
        if !near || top <= tol {
            continue;
        }
        let (pa, pb) = (a - receiver.normal * ha, b - receiver.normal * hb);
        if let Some(s) = plane.clip(plane.to_2d(pa), plane.to_2d(pb)) {
            out.push([plane.to_3d(s.a), plane.to_3d(s.b)]);
        }
    }
    out
}

/// The critical segments of patch `receiver` of a scene: D0 with every other patch, EV/VE with
/// every emitter (other than the receiver) and every other patch as a potential occluder.
/// Segment `occluder` and `emitter` fields are patch indices.
pub fn scene_segments(
    patches: &[Patch],
    receiver: usize,
    snap: f64,
) -> Result<CriticalSet, super::MeshError> {
    let r = &patches[receiver];
    let (plane, others, mut out) = with_contacts(patches, receiver, snap)?;
    for &(e, emitter) in others.iter().filter(|(_, p)| p.is_emitter()) {
        let occluders: Vec<(usize, &Patch)> = others.iter().copied().filter(|&(i, _)| i != e).collect();
        events(r, &plane, (e, emitter), &occluders, &mut out);
    }
    Ok(out)
}
