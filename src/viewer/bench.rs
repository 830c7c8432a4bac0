//! The `--bench-frames N` measurement: wall time between consecutive frames (median, 95th
//! percentile), the process's CPU time per frame (robust to other load on a shared machine: the
//! CPU rasteriser's threads count too) and the machine's load average when it finished.
//!
//! The frame interval is measured at the start of each `ui` call, so it covers everything one
//! frame costs: egui layout and tessellation, the viewport's `prepare`/`paint`, egui's own pass,
//! and presenting the surface.

use std::time::Instant;

/// Frame-time samples of one benchmark run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameBench {
    /// Wall seconds between consecutive frames.
    pub frame_s: Vec<f64>,
    /// Wall seconds spent in the app's `ui` code per frame (UI thread).
    pub ui_s: Vec<f64>,
    /// On-CPU seconds of the UI thread in the app's `ui` code per frame (Linux; excludes time
    /// the thread waited for a core, which on a loaded machine dominates the wall time).
    pub ui_cpu_s: Vec<f64>,
    last: Option<Instant>,
    cpu_start_s: Option<f64>,
    cpu_end_s: Option<f64>,
}

/// Summary of a [`FrameBench`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FrameSummary {
    pub frames: usize,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
    pub ui_median_ms: f64,
    /// Process CPU time (all threads) per frame, if the platform reports it.
    pub cpu_ms_per_frame: Option<f64>,
}

/// The `q`-quantile (0..1) of sorted samples, nearest rank; 0 for none.
#[must_use]
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

impl FrameBench {
    /// Mark the start of a frame; `ui_s` is the UI code time of the previous frame.
    pub fn tick(&mut self, now: Instant, prev_ui_s: f64, prev_ui_cpu_s: Option<f64>) {
        if let Some(t) = self.last {
            self.frame_s.push(now.duration_since(t).as_secs_f64());
            self.ui_s.push(prev_ui_s);
            self.ui_cpu_s.extend(prev_ui_cpu_s);
        } else {
            self.cpu_start_s = process_cpu_s();
        }
        self.cpu_end_s = process_cpu_s();
        self.last = Some(now);
    }

    /// Frames measured so far.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.frame_s.len()
    }

    #[must_use]
    pub fn summary(&self) -> FrameSummary {
        let mut t = self.frame_s.clone();
        t.sort_by(f64::total_cmp);
        let mut u = self.ui_s.clone();
        u.sort_by(f64::total_cmp);
        let cpu = match (self.cpu_start_s, self.cpu_end_s) {
            (Some(a), Some(b)) if !t.is_empty() => Some((b - a) / t.len() as f64 * 1e3),
            _ => None,
        };
        FrameSummary {
            frames: t.len(),
            median_ms: quantile(&t, 0.5) * 1e3,
            p95_ms: quantile(&t, 0.95) * 1e3,
            max_ms: t.last().copied().unwrap_or(0.0) * 1e3,
            ui_median_ms: quantile(&u, 0.5) * 1e3,
            cpu_ms_per_frame: cpu,
        }
    }
}

/// User + system CPU time of this process (all threads), seconds; `None` off Linux.
#[must_use]
pub fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / CLOCK_TICKS_PER_S)
}

/// Time this thread has run on a CPU, seconds (Linux `/proc/thread-self/schedstat`, in ns).
#[must_use]
pub fn thread_cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(s.split_whitespace().next()?.parse::<f64>().ok()? * 1e-9)
}

/// `sysconf(_SC_CLK_TCK)` on Linux (100 on every mainstream kernel configuration).
const CLOCK_TICKS_PER_S: f64 = 100.0;

/// The 1-minute load average (Linux), for stating the conditions of a measurement.
#[must_use]
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn quantiles_and_summary() {
        let s: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&s, 0.5), 50.0);
        assert_eq!(quantile(&s, 0.95), 95.0);
        assert_eq!(quantile(&s, 1.0), 100.0);
        assert_eq!(quantile(&[], 0.5), 0.0);
        let mut b = FrameBench::default();
        let t0 = Instant::now();
        for (i, ms) in [0u64, 10, 30, 40].iter().enumerate() {
            b.tick(t0 + Duration::from_millis(*ms), i as f64 * 1e-3, Some(0.0));
        }
        let s = b.summary();
        assert_eq!(s.frames, 3);
        // Intervals 10, 20, 10 ms.
        assert!((s.median_ms - 10.0).abs() < 1e-9 && (s.p95_ms - 20.0).abs() < 1e-9, "{s:?}");
        // UI times 1, 2, 3 ms (each tick reports the previous frame's).
        assert!((s.ui_median_ms - 2.0).abs() < 1e-9);
    }

    #[test]
    fn cpu_time_is_read_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(process_cpu_s().is_some_and(|s| s >= 0.0));
            assert!(thread_cpu_s().is_some_and(|s| s > 0.0));
            assert!(load_average().is_some());
        }
    }
}
