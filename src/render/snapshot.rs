//! Golden-image comparison for the viewer's tests: mean and 95th-percentile thresholds on the
//! per-pixel difference, stated by the caller with the device that set them.
//!
//! On failure the comparison writes `NAME_actual.png` and `NAME_diff.png` next to the golden
//! image; with `UPDATE_SNAPSHOTS=1` it (re)writes the golden image instead.

use super::RgbaImage;
use std::path::Path;

/// Thresholds of one snapshot: on per-pixel max-channel differences (0..255).
#[derive(Copy, Clone, Debug)]
pub struct Thresholds {
    /// Largest allowed mean difference over all pixels.
    pub mean: f64,
    /// Largest allowed 95th-percentile difference.
    pub p95: f64,
}

/// Statistics of a comparison.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DiffStats {
    pub mean: f64,
    pub p95: f64,
    pub max: u8,
}

/// Per-pixel max-channel difference of two equally sized images, and the difference image.
#[must_use]
pub fn diff(a: &RgbaImage, b: &RgbaImage) -> Option<(DiffStats, RgbaImage)> {
    if (a.width, a.height) != (b.width, b.height) {
        return None;
    }
    let mut d: Vec<u8> = a
        .pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .map(|(p, q)| (0..4).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0))
        .collect();
    let img = RgbaImage {
        width: a.width,
        height: a.height,
        pixels: d.iter().flat_map(|&v| [v.saturating_mul(4), 0, 0, 255]).collect(),
    };
    let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len().max(1) as f64;
    d.sort_unstable();
    let p95 = d.get((d.len() * 95 / 100).min(d.len().saturating_sub(1))).map_or(0.0, |&v| f64::from(v));
    let max = d.last().copied().unwrap_or(0);
    Some((DiffStats { mean, p95, max }, img))
}

/// Compare `image` with the golden `dir/NAME.png`. Returns an error message naming the files
/// written when it differs (or is missing) and `UPDATE_SNAPSHOTS` is not set.
pub fn check(dir: &Path, name: &str, image: &RgbaImage, limits: Thresholds) -> Result<DiffStats, String> {
    let golden = dir.join(format!("{name}.png"));
    let update = std::env::var_os("UPDATE_SNAPSHOTS").is_some_and(|v| v != "0");
    if update {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        image.save_png(&golden)?;
        return Ok(DiffStats { mean: 0.0, p95: 0.0, max: 0 });
    }
    let actual = dir.join(format!("{name}_actual.png"));
    let want = match RgbaImage::load_png(&golden) {
        Ok(w) => w,
        Err(e) => {
            image.save_png(&actual)?;
            return Err(format!(
                "{e} (no golden image; wrote {}; run with UPDATE_SNAPSHOTS=1)",
                actual.display()
            ));
        }
    };
    let Some((stats, d)) = diff(image, &want) else {
        image.save_png(&actual)?;
        return Err(format!(
            "{name}: size {}x{} differs from golden {}x{} (wrote {})",
            image.width,
            image.height,
            want.width,
            want.height,
            actual.display()
        ));
    };
    if stats.mean > limits.mean || stats.p95 > limits.p95 {
        image.save_png(&actual)?;
        let diff_path = dir.join(format!("{name}_diff.png"));
        d.save_png(&diff_path)?;
        return Err(format!(
            "{name}: mean diff {:.3} (limit {}), p95 {} (limit {}); wrote {} and {}",
            stats.mean,
            limits.mean,
            stats.p95,
            limits.p95,
            actual.display(),
            diff_path.display()
        ));
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diff_statistics() {
        let a = RgbaImage { width: 2, height: 1, pixels: vec![0, 0, 0, 255, 10, 10, 10, 255] };
        let b = RgbaImage { width: 2, height: 1, pixels: vec![0, 0, 0, 255, 10, 30, 10, 255] };
        let (s, _) = diff(&a, &b).unwrap();
        assert_eq!(s.max, 20);
        assert!((s.mean - 10.0).abs() < 1e-12);
        assert_eq!(s.p95, 20.0);
        let c = RgbaImage { width: 1, height: 1, pixels: vec![0; 4] };
        assert!(diff(&a, &c).is_none());
    }
}
