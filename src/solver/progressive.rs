//! Progressive refinement radiosity: Southwell iteration on unshot power, with an ambient term
//! for display [Cohen, Chen, Wallace, Greenberg 1988, "A Progressive Refinement Approach to
//! Fast Radiosity Image Generation", SIGGRAPH '88, secs. 3–4].
//!
//! ```text
//! pick the shooter s with the largest unshot power ΔB_s A_s
//! for every receiver r:   ΔH   = ΔB_s F_rs V_rs        (irradiance; F_rs = A_s F_sr / A_r)
//!                         H_r += ΔH;  B_r += ρ_r ΔH;  ΔB_r += ρ_r ΔH
//! escaped += ΔB_s A_s (1 − Σ_r F_sr V_sr);   ΔB_s = 0
//! ```
//!
//! until the unshot power is at most `tolerance` × the emitted power (worst channel).
//!
//! The form factors and visible fractions come from the same per-pair kernel as the uniform
//! solver ([`super::uniform::pair_coupling`]), computed for one shooter at a time (in parallel
//! over receivers) and cached per shooter within a memory budget, so at convergence the two
//! solvers solve the same linear system.
//!
//! **Ambient term** (sec. 4): the radiosity not yet distributed is approximated by a uniform
//! ambient `B_amb = R · Σ_j ΔB_j A_j / Σ_j A_j` with `R = 1 / (1 − ρ_avg)` the interreflection
//! factor of the area-averaged reflectance. It is for display only — the physical B stays in
//! [`super::SolvedElement::radiosity`]; `stats.extra.ambient` holds `B_amb`, and
//! [`display_radiosity`] adds `ρ_r B_amb` per element.
//!
//! Energy: `absorbed = Σ A_r (1−ρ_r) H_r`, `escaped` accumulated shot by shot; the balance
//! `emitted − absorbed − escaped` equals the power still unshot (≤ tolerance × emitted).

use super::uniform::{
    CouplingSettings, Element, SharedProgress, constant_elements, mesh_solution, pair_coupling,
    validate_common,
};
use super::{EnergyBalance, PhaseTimes, Progress, Solution, SolveStats};
use crate::geometry::accel::Accel;
use crate::math::Rgb;
use crate::scene::Scene;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Most cached (receiver, F_rs, F_sr) entries over all shooters (24 bytes each: ~200 MB).
const CACHE_ENTRIES: usize = 8_000_000;
/// Units of the progress bar: progress is reported as the fraction of the way from "all power
/// unshot" to the tolerance, on a log scale, in these units.
const PROGRESS_UNITS: u64 = 1000;

/// Settings of the progressive-refinement solver.
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct ProgressiveParams {
    /// Longest element side, in scene units (`f64::INFINITY`: one element per patch).
    pub element_size: f64,
    /// Shadow rays per element pair for the visible fraction (0: no occlusion test, V = 1).
    pub rays: u32,
    /// Stop when the unshot power is at most this fraction of the emitted power (worst channel).
    pub tolerance: f64,
    /// Cap on shots.
    pub max_shots: u32,
    /// Seed of the visibility jitter.
    pub seed: u64,
    /// Relative accuracy asked of each form factor's quadrature (`--ff-tol`, default
    /// [`super::uniform::DEFAULT_FF_TOLERANCE`]).
    pub ff_tolerance: f64,
    /// Refuse meshes with more elements than this.
    pub max_elements: usize,
}

impl Default for ProgressiveParams {
    fn default() -> Self {
        ProgressiveParams {
            element_size: f64::INFINITY,
            rays: 16,
            tolerance: 1e-3,
            max_shots: 100_000,
            seed: 0,
            ff_tolerance: super::uniform::DEFAULT_FF_TOLERANCE,
            max_elements: 10_000,
        }
    }
}

impl ProgressiveParams {
    /// The mesh and coupling settings (`uniform::start`).
    pub(crate) fn mesh(&self) -> super::uniform::MeshSettings {
        let (element_size, max_elements, ff_tolerance) =
            (self.element_size, self.max_elements, self.ff_tolerance);
        super::uniform::MeshSettings {
            element_size,
            max_elements,
            rays: self.rays,
            seed: self.seed,
            ff_tolerance,
        }
    }

    /// Reject absurd values with a message naming the parameter.
    pub fn validate(&self) -> Result<(), String> {
        validate_common(self.element_size, self.rays, self.ff_tolerance, self.max_elements)?;
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(format!("tolerance must be in (0, 1) (got {})", self.tolerance));
        }
        if self.max_shots == 0 {
            return Err("max-shots must be at least 1".into());
        }
        Ok(())
    }
}

/// One shooter's row: (receiver, F_rs V, F_sr V), sorted by receiver.
type ShotRow = Vec<(u32, f64, f64)>;
/// A row entry as computed: (receiver, F_rs V, F_sr V, rays cast, kernel evaluations).
type RowEntry = (u32, f64, f64, u64, u64);

/// The ambient radiosity stored in a progressive solution's `stats.extra.ambient`, if any.
#[must_use]
pub fn ambient(solution: &Solution) -> Option<Rgb> {
    let a = solution.stats.extra.as_ref()?.get("ambient")?.as_array()?;
    let c = |i: usize| a.get(i).and_then(serde_json::Value::as_f64);
    Some(Rgb::new(c(0)?, c(1)?, c(2)?))
}

/// Per-element radiosity for display: `B + ρ B_amb` (just `B` for solutions without an ambient).
#[must_use]
pub fn display_radiosity(scene: &Scene, solution: &Solution) -> Vec<Rgb> {
    let amb = ambient(solution).unwrap_or(Rgb::ZERO);
    solution
        .elements
        .iter()
        .map(|e| e.radiosity + scene.patches.get(e.patch).map_or(Rgb::ZERO, |p| p.reflectance.mul_rgb(amb)))
        .collect()
}

/// Unshot power relative to emitted power, worst channel (0 for a dark scene).
fn unshot_fraction(unshot: &[Rgb], elems: &[Element], emitted: Rgb) -> f64 {
    let u: Rgb = unshot.iter().zip(elems).map(|(d, e)| *d * e.area).sum();
    (0..3).map(|c| if emitted.0[c] > 0.0 { u.0[c] / emitted.0[c] } else { 0.0 }).fold(0.0, f64::max)
}

/// Solve the scene by progressive refinement. Errors: invalid parameters, or a mesh over the cap.
pub fn solve(
    scene: &Scene,
    accel: &Accel,
    params: &ProgressiveParams,
    progress: Progress,
) -> Result<Solution, String> {
    let (t_start, elems, settings) = super::uniform::start(scene, params.validate(), params.mesh())?;
    let n = elems.len();
    let rho: Vec<Rgb> = elems.iter().map(|e| scene.patches[e.patch].reflectance).collect();
    let emis: Vec<Rgb> = elems.iter().map(|e| scene.patches[e.patch].emission).collect();
    let emitted: Rgb = emis.iter().zip(&elems).map(|(e, el)| *e * el.area).sum();
    let mut b = emis.clone();
    let mut unshot = emis.clone();
    let mut irradiance = vec![Rgb::ZERO; n];
    let mut escaped = Rgb::ZERO;

    let mut cache: Vec<Option<ShotRow>> = vec![None; n];
    let mut cached = 0usize;
    let (mut rays, mut evaluations, mut shots) = (0u64, 0u64, 0usize);
    let mut t_ff = Duration::ZERO;
    let shared = SharedProgress::new(progress, PROGRESS_UNITS);
    let mut reported = 0u64;
    let log_tol = params.tolerance.ln();
    let mut fraction = unshot_fraction(&unshot, &elems, emitted);
    while fraction > params.tolerance && shots < params.max_shots as usize {
        let (s, best) = shooter(&unshot, &elems);
        if best.is_nan() || best <= 0.0 {
            break;
        }
        let t = Instant::now();
        let from_cache = cache[s].is_some();
        let row = match cache[s].take() {
            Some(row) => row,
            None => {
                let (row, ry, ev) = shot_row(accel, &elems, &settings, &cache, s);
                rays += ry;
                evaluations += ev;
                row
            }
        };
        t_ff += t.elapsed();
        let shot = unshot[s];
        let mut row_sum = 0.0;
        for &(r, frs, fsr) in &row {
            let r = r as usize;
            let dh = shot * frs;
            irradiance[r] += dh;
            let db = rho[r].mul_rgb(dh);
            b[r] += db;
            unshot[r] += db;
            row_sum += fsr;
        }
        escaped += shot * (elems[s].area * (1.0 - row_sum));
        unshot[s] = Rgb::ZERO;
        if from_cache {
            cache[s] = Some(row);
        } else if cached + row.len() <= CACHE_ENTRIES {
            cached += row.len();
            cache[s] = Some(row);
        }
        shots += 1;
        fraction = unshot_fraction(&unshot, &elems, emitted);
        let done = progress_done(fraction, log_tol);
        if done > reported {
            shared.add(done - reported);
            reported = done;
        }
    }
    shared.finish();
    let converged = fraction <= params.tolerance;

    let ambient = ambient_term(&elems, &rho, &unshot);

    let mut energy = EnergyBalance { emitted, escaped, ..EnergyBalance::default() };
    for ((h, r), e) in irradiance.iter().zip(&rho).zip(&elems) {
        energy.absorbed += (Rgb::ONE - *r).mul_rgb(*h) * e.area;
    }
    let elapsed = t_start.elapsed().as_secs_f64();
    let t_ff = t_ff.as_secs_f64();
    Ok(mesh_solution(
        scene,
        "progressive".into(),
        constant_elements(elems, &b),
        energy,
        SolveStats {
            links: shots,
            iterations: shots,
            rays,
            time_s: PhaseTimes {
                form_factors: t_ff,
                solve: elapsed - t_ff,
                total: elapsed,
                ..PhaseTimes::default()
            },
            extra: Some(serde_json::json!({
                "converged": converged,
                "shots": shots,
                "unshot_fraction": fraction,
                "ambient": ambient,
                "ambient_note": "display radiosity = B + reflectance * ambient (Cohen et al. 1988, sec. 4)",
                "kernel_evaluations": evaluations,
                "params": params,
            })),
            ..SolveStats::default()
        },
    ))
}

/// The next shooter: the element with the largest unshot power ΔB A (the lowest index on a tie),
/// and that power (−1 for no elements).
fn shooter(unshot: &[Rgb], elems: &[Element]) -> (usize, f64) {
    let mut s = 0;
    let mut best = -1.0;
    for (j, (d, e)) in unshot.iter().zip(elems).enumerate() {
        let p = d.mean() * e.area;
        if p > best {
            best = p;
            s = j;
        }
    }
    (s, best)
}

/// Shooter `s`'s row of couplings, in parallel over receivers: a receiver that shot before gives
/// the pair from its own cached row, the others [`pair_coupling`]; pairs that exchange nothing are
/// left out. Also the rays cast and kernel evaluations spent.
fn shot_row(
    accel: &Accel,
    elems: &[Element],
    settings: &CouplingSettings,
    cache: &[Option<ShotRow>],
    s: usize,
) -> (ShotRow, u64, u64) {
    let computed: Vec<Option<RowEntry>> = (0..elems.len())
        .into_par_iter()
        .map(|r| {
            // Reuse the pair from the receiver's own cached row (it shot before).
            if let Some(row_r) = &cache[r] {
                let k = row_r.binary_search_by_key(&(s as u32), |e| e.0).ok()?;
                let (_, f_sr, f_rs) = row_r[k];
                return Some((r as u32, f_rs, f_sr, 0, 0));
            }
            let (a, c) = (r.min(s), r.max(s));
            pair_coupling(accel, elems, a, c, settings).map(|(fac, fca, ry, ev)| {
                // (F_rs, F_sr): receiver r gathers from shooter s.
                let (frs, fsr) = if r < s { (fac, fca) } else { (fca, fac) };
                (r as u32, frs, fsr, ry, ev)
            })
        })
        .collect();
    let (mut rays, mut evaluations) = (0u64, 0u64);
    let row = computed
        .into_iter()
        .flatten()
        .filter_map(|(r, frs, fsr, ry, ev)| {
            rays += ry;
            evaluations += ev;
            (frs > 0.0 || fsr > 0.0).then_some((r, frs, fsr))
        })
        .collect();
    (row, rays, evaluations)
}

/// Progress in [`PROGRESS_UNITS`]: how far the unshot fraction has come from 1 towards the
/// tolerance, on a log scale (`log_tol` = ln tolerance).
fn progress_done(fraction: f64, log_tol: f64) -> u64 {
    if fraction > 0.0 && log_tol < 0.0 {
        ((fraction.ln() / log_tol).clamp(0.0, 1.0) * PROGRESS_UNITS as f64) as u64
    } else {
        PROGRESS_UNITS
    }
}

/// The ambient term for display (sec. 4): `B_amb = Σ_j ΔB_j A_j / Σ_j A_j / (1 − ρ_avg)`, per
/// channel, ρ_avg the area-averaged reflectance.
fn ambient_term(elems: &[Element], rho: &[Rgb], unshot: &[Rgb]) -> Rgb {
    let total_area: f64 = elems.iter().map(|e| e.area).sum::<f64>().max(f64::MIN_POSITIVE);
    let rho_avg: Rgb = rho.iter().zip(elems).map(|(r, e)| *r * e.area).sum::<Rgb>() / total_area;
    let unshot_avg: Rgb = unshot.iter().zip(elems).map(|(d, e)| *d * e.area).sum::<Rgb>() / total_area;
    // ρ ≤ RHO_MAX in a valid scene; the floor keeps a hand-built ρ = 1 scene finite.
    Rgb(std::array::from_fn(|c| unshot_avg.0[c] / (1.0 - rho_avg.0[c]).max(1.0 - crate::scene::RHO_MAX)))
}
