//! An independent reference: Monte Carlo estimates of radiosity at points ([`points`], the
//! pointwise ruler) or averaged over elements, each with its standard error, cached on disk.
//!
//! For a diffuse surface the radiance leaving a point is L = B/π, and
//!
//! ```text
//! B(x) = E(x) + ρ(x) H(x),   H(x) = ∫_Ω L_in(x, ω) cos θ dω = ∫_Ω B(y(x, ω))/π cos θ dω
//! ```
//!
//! [Kajiya 1986, "The Rendering Equation"; Cohen & Wallace 1993, sec. 2.4; the lecture, slide
//! "Radiosity equation"]. H is estimated by a path from x:
//! - **next-event estimation**: one emitter point y, emitter k chosen ∝ its power Φ_k = E_k A_k,
//!   y uniform on its area (solid-angle pdf p_light = P(k) r² / (A_k cosθ_y));
//! - **cosine sampling**: a cosine-distributed direction (p_cos = cosθ_x/π) to the first surface y;
//!   if y emits, its E_y counts too, and the two estimates of the direct part are combined by
//!   multiple importance sampling with the balance heuristic [Veach & Guibas 1995]:
//!   NEE adds `E_k p_cos/(p_light + p_cos)`, the hit adds `E_y p_cos/(p_cos + p_light)`.
//!   Plain area sampling has infinite variance where the kernel cosθ_x cosθ_y / r² is singular
//!   (an emitter sharing an edge with its receiver); the MIS terms are bounded by E.
//! - **indirect**: y's reflected radiosity ρ_y H(y) is estimated the same way, recursively.
//!   The throughput ∏ρ is kept per channel;
//!   after [`ReferenceParams::min_bounces`] bounces Russian roulette ends the path with probability
//!   1 − max ρ, and every path stops after [`ReferenceParams::max_bounces`].
//!
//! An element's average is the mean of `samples` such estimates at stratified, area-uniform points
//! inside it; its standard error is the sample standard deviation / √samples. Stratification
//! lowers the true variance, but the sample variance of skewed path sums runs low at small counts:
//! on the furnace the mean squared z-score is 2.0 at 64 paths, 1.36 at 1024, 1.01 at 16384 — so
//! below ~1000 paths read the standard error as optimistic by up to 40 % (tests/reference.rs).
//!
//! ## Independence
//! This module uses the BVH ([`crate::geometry::accel`]) for ray casts and nothing else of the solvers: its
//! own polygon sampling, its own cosine sampling, its own meshing ([`reference_mesh`]), no form
//! factors, no hierarchy. A bug in a solver's kernel therefore cannot hide in its reference.
//!
//! Patches are one-sided: a path that reaches the back of a patch ends there (the back neither
//! emits nor reflects, but it blocks light), as in every solver.
//!
//! Each element has its own random stream `Pcg32::keyed(seed, element index)`; elements run in
//! parallel (rayon) and the result is identical for any thread count. A [`Control`] reports
//! progress (elements finished) and cancels a long estimate without changing any result.

use crate::geometry::accel::Accel;
use crate::geometry::area_map::AreaMap;
use crate::math::{DVec3, Pcg32, Rgb, orthonormal_basis, polygon_area, splitmix64};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

pub mod points;
pub use points::{CachedPoints, Cell, PointParams, PointSet, RefPoint, estimate_at, reference_points};

/// Version of the cache file format and of the estimator; bump it when either changes.
/// Version 2: the pointwise reference ([`points`]) joined the element averages.
pub const FORMAT_VERSION: u32 = 2;

/// Errors of the reference estimator and its cache.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    #[error("reference: {0} must be at least 1")]
    ZeroSamples(&'static str),
    #[error("reference: element size {0} must be a finite number > 0")]
    BadElementSize(f64),
    #[error("reference: element {index} lies on patch {patch}, but the scene has {patches} patches")]
    BadElement { index: usize, patch: usize, patches: usize },
    #[error("reference: element {index} has {n} vertices (3 or 4 expected) or zero area")]
    DegenerateElement { index: usize, n: usize },
    #[error("reference: cancelled")]
    Cancelled,
    #[error("reference cache {dir}: cannot create: {source}")]
    CacheDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("reference cache {file}: cannot write: {source}")]
    CacheWrite {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Settings of the estimator.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceParams {
    /// Stratified sample points (one path each) per element.
    pub samples: u32,
    /// Bounces before Russian roulette may end a path.
    pub min_bounces: u32,
    /// Hard cap on the path length (bounces); the bias it leaves is ≤ ρ_max^max_bounces of B.
    pub max_bounces: u32,
    pub seed: u64,
}

impl ReferenceParams {
    /// Quick and rough: for tests and `--quick` runs.
    #[must_use]
    pub const fn quick() -> Self {
        ReferenceParams { samples: 64, min_bounces: 3, max_bounces: 10_000, seed: 0 }
    }
    /// The default of `radlab reference` and of the bench.
    #[must_use]
    pub const fn standard() -> Self {
        ReferenceParams { samples: 1024, min_bounces: 3, max_bounces: 10_000, seed: 0 }
    }
}

impl Default for ReferenceParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// A region of one patch whose average radiosity is estimated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefElement {
    pub patch: usize,
    /// 3 or 4 vertices (convex, planar, on the patch).
    pub vertices: Vec<DVec3>,
}

impl From<&crate::solver::SolvedElement> for RefElement {
    fn from(e: &crate::solver::SolvedElement) -> Self {
        RefElement { patch: e.patch, vertices: e.vertices.clone() }
    }
}

/// An element average with its standard error (per channel, same unit as B).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub radiosity: Rgb,
    pub std_error: Rgb,
}

/// Mesh every patch into a near-uniform grid of elements no larger than `element_size` across
/// (in scene units). Quads are split bilinearly into n×m sub-quads; triangles into n² similar
/// sub-triangles. Independent of the solvers' meshing.
pub fn reference_mesh(scene: &Scene, element_size: f64) -> Result<Vec<RefElement>, ReferenceError> {
    if !(element_size.is_finite() && element_size > 0.0) {
        return Err(ReferenceError::BadElementSize(element_size));
    }
    // Grids finer than this per patch side would only follow a degenerate input (slivers).
    const MAX_SPLIT: f64 = 256.0;
    let count = |len: f64| (len / element_size).ceil().clamp(1.0, MAX_SPLIT) as usize;
    let mut out = Vec::new();
    for (pi, p) in scene.patches.iter().enumerate() {
        let v = &p.vertices;
        if v.len() == 4 {
            let nu = count(v[0].distance(v[1]).max(v[3].distance(v[2])));
            let nv = count(v[0].distance(v[3]).max(v[1].distance(v[2])));
            let at = |i: usize, j: usize| {
                let (u, w) = (i as f64 / nu as f64, j as f64 / nv as f64);
                v[0].lerp(v[1], u).lerp(v[3].lerp(v[2], u), w)
            };
            for j in 0..nv {
                for i in 0..nu {
                    out.push(RefElement {
                        patch: pi,
                        vertices: vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)],
                    });
                }
            }
        } else {
            let n = count(p.diameter());
            // Barycentric grid: point (i, j) = v0 + i/n (v1 − v0) + j/n (v2 − v0), i + j ≤ n.
            let at = |i: usize, j: usize| {
                v[0] + (v[1] - v[0]) * (i as f64 / n as f64) + (v[2] - v[0]) * (j as f64 / n as f64)
            };
            for j in 0..n {
                for i in 0..n - j {
                    out.push(RefElement { patch: pi, vertices: vec![at(i, j), at(i + 1, j), at(i, j + 1)] });
                    if i + j + 1 < n {
                        out.push(RefElement {
                            patch: pi,
                            vertices: vec![at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)],
                        });
                    }
                }
            }
        }
    }
    Ok(out)
}

/// Cosine-distributed direction about `n`: Malley's method (uniform disk, lifted).
fn cosine_direction(n: DVec3, u: f64, v: f64) -> DVec3 {
    let r = u.sqrt();
    let phi = std::f64::consts::TAU * v;
    let (t, b) = orthonormal_basis(n);
    let z = (1.0 - u).max(0.0).sqrt();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalize()
}

/// Emitter sampling table: emitters with cumulative power (sum of channels).
struct Emitters {
    patches: Vec<usize>,
    maps: Vec<AreaMap>,
    cdf: Vec<f64>,
    total: f64,
}

impl Emitters {
    fn new(scene: &Scene) -> Self {
        let mut patches = Vec::new();
        let mut maps = Vec::new();
        let mut cdf = Vec::new();
        let mut total = 0.0;
        for (i, p) in scene.patches.iter().enumerate() {
            let w = p.power().0.iter().sum::<f64>();
            if w > 0.0 {
                total += w;
                patches.push(i);
                maps.push(AreaMap::new(&p.vertices));
                cdf.push(total);
            }
        }
        Emitters { patches, maps, cdf, total }
    }
    /// Pick an emitter ∝ power: its list index.
    fn pick(&self, u: f64) -> usize {
        let x = u * self.total;
        self.cdf.partition_point(|&c| c <= x).min(self.cdf.len() - 1)
    }
    /// Probability that [`Emitters::pick`] returns `k`.
    fn prob(&self, k: usize) -> f64 {
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        (self.cdf[k] - lo) / self.total
    }
    /// List index of a patch if it is an emitter.
    fn index_of(&self, patch: usize) -> Option<usize> {
        self.patches.binary_search(&patch).ok()
    }
}

/// What the per-path estimator needs about the scene, built once.
struct Tracer<'a> {
    scene: &'a Scene,
    accel: &'a Accel,
    emitters: Emitters,
    params: ReferenceParams,
}

impl Tracer<'_> {
    /// Solid-angle density with which next-event estimation picks the point y of emitter `k`
    /// seen from distance² `r2` at cosine `cos_y`.
    fn light_pdf(&self, k: usize, r2: f64, cos_y: f64) -> f64 {
        let e = &self.scene.patches[self.emitters.patches[k]];
        self.emitters.prob(k) * r2 / (e.area * cos_y)
    }

    /// Next-event part of the irradiance H at x (patch `patch`, normal n), MIS-weighted against
    /// cosine sampling (balance heuristic): `E_k/π cosθ_x V / (p_light + p_cos)`, bounded by E_k
    /// even where the kernel is singular (a shared edge), unlike plain area sampling.
    fn direct(&self, x: DVec3, n: DVec3, patch: usize, rng: &mut Pcg32) -> Rgb {
        if self.emitters.patches.is_empty() {
            return Rgb::ZERO;
        }
        let k = self.emitters.pick(rng.next_f64());
        let ep = self.emitters.patches[k];
        let y = self.emitters.maps[k].point(rng.next_f64(), rng.next_f64());
        if ep == patch {
            return Rgb::ZERO; // a planar patch does not see itself
        }
        let e = &self.scene.patches[ep];
        let d = y - x;
        let r2 = d.length_squared();
        if r2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Rgb::ZERO;
        }
        let w = d / r2.sqrt();
        let cos_x = n.dot(w);
        let cos_y = -e.normal.dot(w);
        if cos_x <= 0.0 || cos_y <= 0.0 {
            return Rgb::ZERO;
        }
        if self.accel.occluded(x, y, [patch as u32, ep as u32]) {
            return Rgb::ZERO;
        }
        let p_light = self.light_pdf(k, r2, cos_y);
        let p_cos = cos_x / std::f64::consts::PI;
        e.emission * (p_cos / (p_light + p_cos))
    }

    /// One-path estimate of B(x) at a point x of `patch`.
    fn radiosity_at(&self, x: DVec3, patch: usize, rng: &mut Pcg32) -> Rgb {
        let p0 = &self.scene.patches[patch];
        let mut b = p0.emission;
        let mut throughput = p0.reflectance;
        let mut x = x;
        let mut cur = patch;
        let mut n = p0.normal;
        for bounce in 0..self.params.max_bounces {
            if throughput.max_channel() <= 0.0 {
                break;
            }
            b += throughput.mul_rgb(self.direct(x, n, cur, rng));
            let w = cosine_direction(n, rng.next_f64(), rng.next_f64());
            let Some((hit, t)) = self.accel.first_hit(x, w, cur as u32) else { break };
            let hp = &self.scene.patches[hit as usize];
            let cos_y = -hp.normal.dot(w);
            if cos_y <= 0.0 {
                break; // the back of a one-sided patch: black
            }
            // The cosine-sampled half of the MIS pair: an emitter hit counts E_y p_cos/(p_cos + p_light).
            if let Some(k) = self.emitters.index_of(hit as usize) {
                let p_cos = n.dot(w) / std::f64::consts::PI;
                let p_light = self.light_pdf(k, t * t, cos_y);
                b += throughput.mul_rgb(hp.emission * (p_cos / (p_cos + p_light)));
            }
            // Snap the hit onto its plane: the BVH's f32 distance is not exact.
            let y = x + w * t;
            x = y - hp.normal * (hp.normal.dot(y) - hp.plane_d());
            cur = hit as usize;
            n = hp.normal;
            throughput = throughput.mul_rgb(hp.reflectance);
            if bounce + 1 >= self.params.min_bounces {
                let q = throughput.max_channel().min(1.0);
                if q <= 0.0 || rng.next_f64() >= q {
                    break;
                }
                throughput = throughput / q;
            }
        }
        b
    }

    fn element(&self, el: &RefElement, key: u64) -> Estimate {
        let mut rng = Pcg32::keyed(self.params.seed, key);
        let map = AreaMap::new(&el.vertices);
        let n = self.params.samples;
        let cols = (f64::from(n).sqrt().ceil() as u32).max(1);
        let rows = n.div_ceil(cols);
        let mut sum = Rgb::ZERO;
        let mut sum2 = Rgb::ZERO;
        for k in 0..n {
            // Stratum k of a cols×rows grid (the last row may be partial), jittered inside.
            let (i, j) = (k % cols, k / cols);
            let u = (f64::from(i) + rng.next_f64()) / f64::from(cols);
            let v = (f64::from(j) + rng.next_f64()) / f64::from(rows);
            let x = map.point(u, v);
            let b = self.radiosity_at(x, el.patch, &mut rng);
            sum += b;
            sum2 += b.mul_rgb(b);
        }
        let nf = f64::from(n);
        let mean = sum / nf;
        let var = if n > 1 {
            (sum2 / nf - mean.mul_rgb(mean)).map(|v| v.max(0.0)) * (nf / (nf - 1.0))
        } else {
            Rgb::ZERO
        };
        Estimate { radiosity: mean, std_error: (var / nf).map(f64::sqrt) }
    }
}

/// Progress and cancellation of a long estimate, shared with another thread (the viewer's
/// progress bar and Cancel button, the CLI's progress bar). Elements are counted as they finish;
/// setting `cancel` stops the estimate at the next element boundary. Neither changes the result:
/// each element keeps its own random stream.
#[derive(Debug, Default)]
pub struct Control {
    done: AtomicUsize,
    total: AtomicUsize,
    cancel: AtomicBool,
}

impl Control {
    /// Ask the running estimate to stop ([`ReferenceError::Cancelled`]).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
    #[must_use]
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
    /// (elements finished, elements in the estimate); (0, 0) before it starts.
    #[must_use]
    pub fn progress(&self) -> (usize, usize) {
        (self.done.load(Ordering::Relaxed), self.total.load(Ordering::Relaxed))
    }
}

/// Estimate the average radiosity of each element, in order, with standard errors.
pub fn estimate_elements(
    scene: &Scene,
    accel: &Accel,
    elements: &[RefElement],
    params: &ReferenceParams,
) -> Result<Vec<Estimate>, ReferenceError> {
    estimate_elements_with(scene, accel, elements, params, &Control::default())
}

/// [`estimate_elements`] reporting progress to, and stopping on request of, `control`.
/// The estimates are bit-identical to [`estimate_elements`]'s.
pub fn estimate_elements_with(
    scene: &Scene,
    accel: &Accel,
    elements: &[RefElement],
    params: &ReferenceParams,
    control: &Control,
) -> Result<Vec<Estimate>, ReferenceError> {
    if params.samples == 0 {
        return Err(ReferenceError::ZeroSamples("samples"));
    }
    if params.max_bounces == 0 {
        return Err(ReferenceError::ZeroSamples("max-bounces"));
    }
    for (index, e) in elements.iter().enumerate() {
        if e.patch >= scene.patches.len() {
            return Err(ReferenceError::BadElement { index, patch: e.patch, patches: scene.patches.len() });
        }
        if !(3..=4).contains(&e.vertices.len())
            || polygon_area(&e.vertices).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        {
            return Err(ReferenceError::DegenerateElement { index, n: e.vertices.len() });
        }
    }
    let tracer = Tracer { scene, accel, emitters: Emitters::new(scene), params: *params };
    control.done.store(0, Ordering::Relaxed);
    control.total.store(elements.len(), Ordering::Relaxed);
    elements
        .par_iter()
        .enumerate()
        .map(|(i, e)| {
            if control.cancelled() {
                return None;
            }
            let estimate = tracer.element(e, i as u64);
            control.done.fetch_add(1, Ordering::Relaxed);
            Some(estimate)
        })
        .collect::<Option<Vec<Estimate>>>()
        .ok_or(ReferenceError::Cancelled)
}

/// Combine K independent estimates of the same elements (e.g. batches with seeds s, s+1, …, each
/// with the same number of paths): the mean of the batch means, standard error √(Σ_b σ_b²) / K.
/// Batches of equal size make this the estimate of one run with K× the paths; the pooled
/// variance is also steadier than one run's (the sample variance of skewed path sums runs low at
/// small counts, see the module docs). Empty input or batches of unequal length give `None`.
#[must_use]
pub fn merge_batches(batches: &[Vec<Estimate>]) -> Option<Vec<Estimate>> {
    let n = batches.first()?.len();
    if batches.iter().any(|b| b.len() != n) {
        return None;
    }
    let k = batches.len() as f64;
    Some(
        (0..n)
            .map(|i| {
                let mean = batches.iter().map(|b| b[i].radiosity).sum::<Rgb>() / k;
                let var = batches.iter().map(|b| b[i].std_error.mul_rgb(b[i].std_error)).sum::<Rgb>();
                Estimate { radiosity: mean, std_error: var.map(f64::sqrt) / k }
            })
            .collect(),
    )
}

/// The reference a solution is scored against, from the batches of one point layout (batch 0
/// placed the points, the others re-estimated them): the merge of the batches after the first
/// when there are any, else the first alone. The layout batch split its cells where its own
/// estimates varied, so at the points it placed its errors are correlated with the placement
/// and smaller than its standard errors say; a debiased score against it subtracts more noise
/// than it holds and reads low near the reference's resolution (cornell's contact mesh at the
/// `fine` step: 0.29 % against the layout batch, 0.94 % against an independent path tracer at
/// the same points, docs/reference_crosscheck.md). The later batches are independent of the
/// layout. Returns the estimates and how many batches they merge; `None` as [`merge_batches`].
#[must_use]
pub fn scoring_batches(batches: &[Vec<Estimate>]) -> Option<(Vec<Estimate>, usize)> {
    let independent = if batches.len() > 1 { &batches[1..] } else { batches };
    Some((merge_batches(independent)?, independent.len()))
}

/// Estimate B at single points (each on `patch`), `samples` paths each: (point, patch) pairs.
pub fn estimate_points(
    scene: &Scene,
    accel: &Accel,
    points: &[(DVec3, usize)],
    params: &ReferenceParams,
) -> Result<Vec<Estimate>, ReferenceError> {
    if params.samples == 0 {
        return Err(ReferenceError::ZeroSamples("samples"));
    }
    let tracer = Tracer { scene, accel, emitters: Emitters::new(scene), params: *params };
    points
        .par_iter()
        .enumerate()
        .map(|(i, &(x, patch))| {
            if patch >= scene.patches.len() {
                return Err(ReferenceError::BadElement { index: i, patch, patches: scene.patches.len() });
            }
            let mut rng = Pcg32::keyed(params.seed, i as u64);
            let n = f64::from(params.samples);
            let mut sum = Rgb::ZERO;
            let mut sum2 = Rgb::ZERO;
            for _ in 0..params.samples {
                let b = tracer.radiosity_at(x, patch, &mut rng);
                sum += b;
                sum2 += b.mul_rgb(b);
            }
            let mean = sum / n;
            let var = (sum2 / n - mean.mul_rgb(mean)).map(|v| v.max(0.0)) * (n / (n - 1.0).max(1.0));
            Ok(Estimate { radiosity: mean, std_error: (var / n).map(f64::sqrt) })
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Hashing and the on-disk cache.

/// FNV-1a over bytes, finished with SplitMix64: a stable 64-bit content hash (not cryptographic;
/// it keys a cache and detects corruption, nothing adversarial).
#[derive(Clone, Copy, Debug)]
pub struct Hasher64(u64);

impl Default for Hasher64 {
    fn default() -> Self {
        Hasher64(0xcbf2_9ce4_8422_2325)
    }
}

impl Hasher64 {
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }
    pub fn f64(&mut self, x: f64) -> &mut Self {
        self.bytes(&x.to_bits().to_le_bytes())
    }
    pub fn u64(&mut self, x: u64) -> &mut Self {
        self.bytes(&x.to_le_bytes())
    }
    pub fn vec3(&mut self, v: DVec3) -> &mut Self {
        self.f64(v.x).f64(v.y).f64(v.z)
    }
    pub fn rgb(&mut self, c: Rgb) -> &mut Self {
        self.f64(c.0[0]).f64(c.0[1]).f64(c.0[2])
    }
    #[must_use]
    pub fn finish(&self) -> u64 {
        splitmix64(self.0)
    }
}

/// Hash of everything the reference depends on: the patches' geometry and materials, the
/// elements, the settings and the format version.
#[must_use]
pub fn cache_key(scene: &Scene, elements: &[RefElement], params: &ReferenceParams) -> u64 {
    let mut h = Hasher64::default();
    h.u64(u64::from(FORMAT_VERSION));
    hash_scene(&mut h, scene);
    h.u64(elements.len() as u64);
    for e in elements {
        h.u64(e.patch as u64);
        for v in &e.vertices {
            h.vec3(*v);
        }
    }
    h.u64(u64::from(params.samples))
        .u64(u64::from(params.min_bounces))
        .u64(u64::from(params.max_bounces))
        .u64(params.seed);
    h.finish()
}

/// Hash the patches' geometry and materials.
fn hash_scene(h: &mut Hasher64, scene: &Scene) {
    h.u64(scene.patches.len() as u64);
    for p in &scene.patches {
        h.u64(p.vertices.len() as u64);
        for v in &p.vertices {
            h.vec3(*v);
        }
        h.rgb(p.reflectance).rgb(p.emission);
    }
}

/// First word of a cache file's header line: `radlab-reference <checksum of the JSON body>`.
const CACHE_MAGIC: &str = "radlab-reference";

/// What the cache stores: the estimates and enough to check they belong to the request.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CachedReference {
    pub format_version: u32,
    /// [`cache_key`] as 16 hex digits.
    pub key: String,
    pub scene: String,
    pub params: ReferenceParams,
    pub elements: Vec<RefElement>,
    pub estimates: Vec<Estimate>,
    /// Seconds the computation took.
    pub compute_s: f64,
}

/// How a reference was obtained.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheStatus {
    /// Read from this file.
    Hit(PathBuf),
    /// Computed and written to this file.
    Computed(PathBuf),
    /// The file existed but was unreadable, corrupt or for other inputs; recomputed and rewritten.
    Recomputed { file: PathBuf, why: String },
}

impl CacheStatus {
    /// How the entry was obtained, in words ("cached", "computed in 12.3 s", …, with the
    /// computation's `compute_s`), and its file.
    #[must_use]
    pub fn describe(&self, compute_s: f64) -> (String, &std::path::Path) {
        match self {
            CacheStatus::Hit(f) => ("cached".to_string(), f),
            CacheStatus::Computed(f) => (format!("computed in {compute_s:.1} s"), f),
            CacheStatus::Recomputed { file, why } => {
                (format!("cache entry invalid ({why}); recomputed in {compute_s:.1} s"), file)
            }
        }
    }
}

/// The on-disk cache: one JSON file per key in a folder.
#[derive(Clone, Debug)]
pub struct Cache {
    pub dir: PathBuf,
}

impl Cache {
    /// `$RADLAB_CACHE` if set, else `.radlab-cache/` in the current directory.
    #[must_use]
    pub fn default_location() -> Cache {
        let dir =
            std::env::var_os("RADLAB_CACHE").map_or_else(|| PathBuf::from(".radlab-cache"), PathBuf::from);
        Cache { dir }
    }

    #[must_use]
    pub fn at(dir: impl Into<PathBuf>) -> Cache {
        Cache { dir: dir.into() }
    }

    #[must_use]
    pub fn file_for(&self, key: u64) -> PathBuf {
        self.dir.join(format!("reference-v{FORMAT_VERSION}-{key:016x}.json"))
    }

    /// Read an entry; `Err(why)` when missing, unreadable, unparsable, for another key or corrupt.
    pub fn read(&self, key: u64, n_elements: usize) -> Result<CachedReference, String> {
        read_entry(&self.file_for(key), key, n_elements)
    }

    /// The reference for these elements: from the cache if a valid entry exists, else computed
    /// (and written).
    pub fn get_or_compute(
        &self,
        scene: &Scene,
        accel: &Accel,
        elements: &[RefElement],
        params: &ReferenceParams,
    ) -> Result<(CachedReference, CacheStatus), ReferenceError> {
        self.get_or_compute_with(scene, accel, elements, params, &Control::default())
    }

    /// [`Cache::get_or_compute`] with progress and cancellation ([`Control`]); a cancelled
    /// computation writes nothing.
    pub fn get_or_compute_with(
        &self,
        scene: &Scene,
        accel: &Accel,
        elements: &[RefElement],
        params: &ReferenceParams,
        control: &Control,
    ) -> Result<(CachedReference, CacheStatus), ReferenceError> {
        let key = cache_key(scene, elements, params);
        let file = self.file_for(key);
        let previous = if file.exists() {
            match read_entry(&file, key, elements.len()) {
                Ok(c) => return Ok((c, CacheStatus::Hit(file))),
                Err(why) => Some(why),
            }
        } else {
            None
        };
        let t0 = std::time::Instant::now();
        let estimates = estimate_elements_with(scene, accel, elements, params, control)?;
        let entry = CachedReference {
            format_version: FORMAT_VERSION,
            key: format!("{key:016x}"),
            scene: scene.source.clone(),
            params: *params,
            elements: elements.to_vec(),
            estimates,
            compute_s: t0.elapsed().as_secs_f64(),
        };
        self.write(&file, &entry)?;
        let status = match previous {
            Some(why) => CacheStatus::Recomputed { file, why },
            None => CacheStatus::Computed(file),
        };
        Ok((entry, status))
    }

    /// The file of a pointwise reference entry.
    #[must_use]
    pub fn points_file_for(&self, key: u64) -> PathBuf {
        self.dir.join(format!("points-v{FORMAT_VERSION}-{key:016x}.json"))
    }

    /// The pointwise reference for these settings (its layout batch) if the cache holds a valid
    /// entry; never computes (the viewer's look-up before it offers to compute one).
    /// With the entry, its file.
    pub fn read_points(
        &self,
        scene: &Scene,
        params: &PointParams,
    ) -> Result<(CachedPoints, PathBuf), String> {
        let params = params.batch(params.layout_seed);
        let key = points::points_cache_key(scene, &params);
        let file = self.points_file_for(key);
        if !file.exists() {
            return Err(format!("no entry {}", file.display()));
        }
        read_points_entry(&file, key, None).map(|c| (c, file))
    }

    /// The pointwise reference for these settings ([`points`]): from the cache if a valid entry
    /// exists, else computed and written. A batch whose seed is not the layout seed reuses (or
    /// first computes) the layout's entry and re-estimates its points; its file holds only the
    /// estimates (the returned entry carries the layout's points).
    pub fn get_or_compute_points(
        &self,
        scene: &Scene,
        accel: &Accel,
        params: &PointParams,
        control: &Control,
    ) -> Result<(CachedPoints, CacheStatus), ReferenceError> {
        let layout = if params.paths.seed == params.layout_seed {
            None
        } else {
            Some(self.get_or_compute_points(scene, accel, &params.batch(params.layout_seed), control)?.0.set)
        };
        let key = points::points_cache_key(scene, params);
        let file = self.points_file_for(key);
        let previous = if file.exists() {
            match read_points_entry(&file, key, layout.as_ref().map(|l| l.points.len())) {
                Ok(mut c) => {
                    if let Some(set) = layout {
                        c.set = set;
                    }
                    return Ok((c, CacheStatus::Hit(file)));
                }
                Err(why) => Some(why),
            }
        } else {
            None
        };
        let t0 = std::time::Instant::now();
        let (set, estimates) = match &layout {
            None => reference_points(scene, accel, params, control)?,
            Some(set) => (PointSet::default(), estimate_at(scene, accel, set, &params.paths, control)?),
        };
        let mut entry = CachedPoints {
            format_version: FORMAT_VERSION,
            key: format!("{key:016x}"),
            scene: scene.source.clone(),
            params: *params,
            set,
            estimates,
            compute_s: t0.elapsed().as_secs_f64(),
        };
        self.write(&file, &entry)?;
        if let Some(set) = layout {
            entry.set = set;
        }
        let status = match previous {
            Some(why) => CacheStatus::Recomputed { file, why },
            None => CacheStatus::Computed(file),
        };
        Ok((entry, status))
    }

    fn write<T: Serialize>(&self, file: &Path, entry: &T) -> Result<(), ReferenceError> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|source| ReferenceError::CacheDir { dir: self.dir.clone(), source })?;
        let body = serde_json::to_string(entry).expect("cache entries serialise (plain data)");
        let sum = Hasher64::default().bytes(body.as_bytes()).finish();
        let text = format!("{CACHE_MAGIC} {sum:016x}\n{body}");
        // Write to a temporary name and rename, so a killed run leaves no half-written entry.
        let tmp = file.with_extension(format!("tmp{}", std::process::id()));
        std::fs::write(&tmp, text)
            .and_then(|()| std::fs::rename(&tmp, file))
            .map_err(|source| ReferenceError::CacheWrite { file: file.to_path_buf(), source })
    }
}

/// Read and check a cache file: header line `radlab-reference <hash>`, then the JSON body whose
/// hash must match (so any flipped byte is caught before parsing), then key and sizes.
fn read_entry(file: &Path, key: u64, n_elements: usize) -> Result<CachedReference, String> {
    let c: CachedReference = read_checked(file)?;
    if c.format_version != FORMAT_VERSION {
        return Err(format!("format version {} (expected {FORMAT_VERSION})", c.format_version));
    }
    if c.key != format!("{key:016x}") {
        return Err(format!("key {} (expected {key:016x})", c.key));
    }
    if c.estimates.len() != n_elements || c.elements.len() != n_elements {
        return Err(format!("{} estimates for {n_elements} elements", c.estimates.len()));
    }
    if c.estimates.iter().any(|e| !(e.radiosity.is_finite() && e.std_error.is_finite())) {
        return Err("non-finite estimate".into());
    }
    Ok(c)
}

/// Read and check a pointwise cache file (as [`read_entry`]); `batch_of`: the layout's point
/// count when the file is a further batch (estimates only).
fn read_points_entry(file: &Path, key: u64, batch_of: Option<usize>) -> Result<CachedPoints, String> {
    let c: CachedPoints = read_checked(file)?;
    if c.format_version != FORMAT_VERSION {
        return Err(format!("format version {} (expected {FORMAT_VERSION})", c.format_version));
    }
    if c.key != format!("{key:016x}") {
        return Err(format!("key {} (expected {key:016x})", c.key));
    }
    let n = batch_of.unwrap_or(c.set.points.len());
    if c.estimates.len() != n || (batch_of.is_none() && n < c.params.points as usize) {
        return Err(format!("{} estimates for {n} points", c.estimates.len()));
    }
    if c.estimates.iter().any(|e| !(e.radiosity.is_finite() && e.std_error.is_finite())) {
        return Err("non-finite estimate".into());
    }
    Ok(c)
}

/// The header line, checksum and JSON body of a cache file.
fn read_checked<T: serde::de::DeserializeOwned>(file: &Path) -> Result<T, String> {
    let text = std::fs::read_to_string(file).map_err(|e| format!("cannot read: {e}"))?;
    let (header, body) = text.split_once('\n').ok_or("no header line")?;
    let sum = header
        .strip_prefix(CACHE_MAGIC)
        .map(str::trim)
        .and_then(|h| u64::from_str_radix(h, 16).ok())
        .ok_or_else(|| format!("bad header {header:?}"))?;
    if sum != Hasher64::default().bytes(body.as_bytes()).finish() {
        return Err("checksum mismatch (corrupt entry)".into());
    }
    serde_json::from_str(body).map_err(|e| format!("cannot parse: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_reports_progress_cancels_and_changes_nothing() {
        let scene = Scene::load("builtin:cube-one-light").unwrap();
        let accel = Accel::build(&scene);
        let mesh = reference_mesh(&scene, 0.5).unwrap();
        let params = ReferenceParams { samples: 4, ..ReferenceParams::quick() };
        let plain = estimate_elements(&scene, &accel, &mesh, &params).unwrap();
        let control = Control::default();
        let with = estimate_elements_with(&scene, &accel, &mesh, &params, &control).unwrap();
        // Bit-identical, not merely close.
        assert_eq!(plain, with);
        assert_eq!(control.progress(), (mesh.len(), mesh.len()));
        control.cancel();
        assert!(matches!(
            estimate_elements_with(&scene, &accel, &mesh, &params, &control),
            Err(ReferenceError::Cancelled)
        ));
        let dir = std::env::temp_dir().join(format!("radlab-ref-cancel-{}", std::process::id()));
        let cache = Cache::at(&dir);
        assert!(cache.get_or_compute_with(&scene, &accel, &mesh, &params, &control).is_err());
        let key = cache_key(&scene, &mesh, &params);
        assert!(!cache.file_for(key).exists(), "a cancelled computation writes no cache entry");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn area_map_is_area_uniform_on_a_trapezoid() {
        // A trapezoid whose bilinear map would not be area-uniform; count points per half.
        let v =
            [DVec3::new(0., 0., 0.), DVec3::new(4., 0., 0.), DVec3::new(3., 1., 0.), DVec3::new(1., 1., 0.)];
        let m = AreaMap::new(&v);
        let mut rng = Pcg32::keyed(3, 3);
        let n = 40_000;
        let lower = (0..n).filter(|_| m.point(rng.next_f64(), rng.next_f64()).y < 0.5).count();
        // Lower half (y < 0.5) has area 1.75 of 3: fraction 0.5833. 4σ of a binomial at n=40000 ≈ 0.01.
        const BINOMIAL_4_SIGMA: f64 = 0.01;
        assert!((lower as f64 / f64::from(n) - 1.75 / 3.0).abs() < BINOMIAL_4_SIGMA);
    }

    #[test]
    fn cosine_directions_have_mean_cos_two_thirds() {
        let n = DVec3::new(1.0, -2.0, 0.5).normalize();
        let mut rng = Pcg32::keyed(1, 2);
        let k = 20_000;
        let mean: f64 =
            (0..k).map(|_| cosine_direction(n, rng.next_f64(), rng.next_f64()).dot(n)).sum::<f64>()
                / k as f64;
        // E[cos θ] under the cosine pdf is 2/3; σ of cos is √(1/2 − 4/9) ≈ 0.236, 4σ/√k ≈ 0.0067.
        const MEAN_4_SIGMA: f64 = 0.0067;
        assert!((mean - 2.0 / 3.0).abs() < MEAN_4_SIGMA, "{mean}");
    }

    #[test]
    fn merged_batches_average_and_shrink_the_standard_error() {
        let e = |b: f64, s: f64| Estimate { radiosity: Rgb::splat(b), std_error: Rgb::splat(s) };
        let m = merge_batches(&[vec![e(1.0, 0.2), e(5.0, 0.0)], vec![e(3.0, 0.2), e(5.0, 0.0)]]).unwrap();
        assert_eq!(m[0].radiosity, Rgb::splat(2.0));
        // Two equal σ: σ/√2.
        assert!((m[0].std_error.r() - 0.2 / 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(m[1], e(5.0, 0.0));
        assert!(merge_batches(&[]).is_none());
        // Scoring leaves out the layout batch once another exists.
        let b = |v: f64| vec![e(v, 0.1)];
        let (only, n) = scoring_batches(&[b(1.0)]).unwrap();
        assert_eq!((only[0].radiosity.0[0], n), (1.0, 1));
        let (later, n) = scoring_batches(&[b(1.0), b(3.0), b(5.0)]).unwrap();
        assert_eq!((later[0].radiosity.0[0], n), (4.0, 2));
        assert!(scoring_batches(&[]).is_none());
        assert!(merge_batches(&[vec![e(1.0, 0.1)], vec![]]).is_none());
    }

    #[test]
    fn hasher_is_stable_and_sensitive() {
        let a = Hasher64::default().f64(1.0).finish();
        assert_eq!(a, Hasher64::default().f64(1.0).finish());
        assert_ne!(a, Hasher64::default().f64(1.0 + f64::EPSILON).finish());
    }
}
