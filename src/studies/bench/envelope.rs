//! A method's speed against its error as a curve: the lower envelope of its (time, error) rows
//! (the Pareto-optimal ones), the time at which it first reaches a target (log-log interpolation
//! between the bracketing rows), and, where it never does, the power law err = c · t^(−a) through
//! its last rows solved for the target — an estimate, labelled as one.

/// The lower envelope of (time, error) points: sorted by time, each point kept only if its error
/// is below every earlier one. These are also the Pareto-optimal points.
#[must_use]
pub fn pareto(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> =
        points.iter().copied().filter(|(t, e)| t.is_finite() && e.is_finite()).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for q in p {
        if out.last().is_none_or(|l| q.1 < l.1) {
            out.push(q);
        }
    }
    out
}

/// Time at which the lower envelope of `points` first reaches `target` error, interpolated
/// linearly in log t – log err between the bracketing points. `None` if never reached.
#[must_use]
pub fn time_to_reach(points: &[(f64, f64)], target: f64) -> Option<f64> {
    let env = pareto(points);
    let first = *env.first()?;
    if first.1 <= target {
        return Some(first.0);
    }
    for w in env.windows(2) {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        if e1 <= target {
            if !(t0 > 0.0 && e0 > 0.0 && e1 > 0.0) {
                return Some(t1);
            }
            let s = (target.ln() - e0.ln()) / (e1.ln() - e0.ln());
            return Some((t0.ln() + s * (t1.ln() - t0.ln())).exp());
        }
    }
    None
}

/// Rows of the lower envelope that [`extrapolate_time`] fits.
pub const EXTRAPOLATE_POINTS: usize = 3;

/// Where a method that did not reach `target` would, if its error kept falling as it does over
/// its last [`EXTRAPOLATE_POINTS`] rows on the lower envelope: the least-squares power law
/// err = c · t^(−a) through them (a line in log t – log err), solved for `target`. `None` with
/// fewer rows, when the envelope already reaches the target, or when the fitted error does not
/// fall with time (a ≤ 0). An estimate beyond the measured range, never a measurement: a uniform
/// mesh's error falls ever more slowly where shadow edges cut its elements, so the power law of
/// its last rows is, if anything, optimistic for it.
#[must_use]
pub fn extrapolate_time(points: &[(f64, f64)], target: f64) -> Option<f64> {
    let env = pareto(points);
    if env.len() < EXTRAPOLATE_POINTS || env.last()?.1 <= target || !(target > 0.0) {
        return None;
    }
    let tail: Vec<(f64, f64)> = env[env.len() - EXTRAPOLATE_POINTS..]
        .iter()
        .filter(|(t, e)| *t > 0.0 && *e > 0.0)
        .map(|(t, e)| (t.ln(), e.ln()))
        .collect();
    if tail.len() < EXTRAPOLATE_POINTS {
        return None;
    }
    let n = tail.len() as f64;
    let (mx, my) = (tail.iter().map(|p| p.0).sum::<f64>() / n, tail.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = tail.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = tail.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if !(sxx > 0.0) {
        return None;
    }
    let slope = sxy / sxx;
    if !(slope < 0.0) {
        return None;
    }
    let t = (mx + (target.ln() - my) / slope).exp();
    t.is_finite().then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::studies::bench::table::{secs_rough, times};

    #[test]
    fn pareto_keeps_only_improving_points() {
        let p = pareto(&[(1.0, 0.5), (2.0, 0.6), (3.0, 0.1), (0.5, 0.9), (4.0, f64::NAN)]);
        assert_eq!(p, vec![(0.5, 0.9), (1.0, 0.5), (3.0, 0.1)]);
    }

    #[test]
    fn crossing_time_is_log_log_interpolated() {
        // err = 1/t: reaching 0.1 happens at t = 10, between samples at 1 and 100.
        let pts = [(1.0, 1.0), (100.0, 0.01)];
        let t = time_to_reach(&pts, 0.1).unwrap();
        assert!((t - 10.0).abs() < 1e-9, "{t}");
        assert_eq!(time_to_reach(&pts, 0.001), None);
        assert_eq!(time_to_reach(&[(2.0, 0.001)], 0.01), Some(2.0));
    }

    /// The power law through the last three envelope rows is solved for the target; only the
    /// last three count, and a method that reached the target, or whose error does not fall,
    /// gets no estimate.
    #[test]
    fn unreached_targets_are_extrapolated_from_the_last_rows() {
        // err = 0.8 · t^(−1/4) from t = 1 on; an early outlier row that the fit must ignore.
        let law = |t: f64| 0.8 * t.powf(-0.25);
        let pts = [(0.01, 5.0), (1.0, law(1.0)), (4.0, law(4.0)), (16.0, law(16.0))];
        let t = extrapolate_time(&pts, 0.05).unwrap();
        // 0.8 t^(−1/4) = 0.05 at t = 16⁴ = 65 536.
        assert!((t / 65_536.0 - 1.0).abs() < 1e-9, "{t}");
        assert_eq!(time_to_reach(&pts, 0.05), None);
        // Reached: no estimate.
        assert_eq!(extrapolate_time(&pts, 0.5), None);
        // Too few rows, or an error that does not fall with time.
        assert_eq!(extrapolate_time(&pts[2..], 0.05), None);
        assert_eq!(extrapolate_time(&[(1.0, 0.2), (2.0, 0.2), (4.0, 0.2)], 0.05), None);
        assert_eq!(secs_rough(65_536.0), "66 000 s");
        assert_eq!(secs_rough(12.345), "12.35 s");
        assert_eq!(secs_rough(1.8e19), "1.8e19 s");
        assert_eq!(times(0.0012), "1.2e-3×");
        assert_eq!(times(0.23), "0.23×");
        assert_eq!(times(0.0951), "0.095×");
    }
}
