//! One picture per meshing artifact ([`crate::eval::artifacts`]): every reflecting patch drawn flat in
//! its own plane, as a tile of a contact sheet (patches in scene order, left to right, top to
//! bottom, each scaled to fill its tile), so a floor's shadow and a wall's highlight are seen as
//! a plan view.
//!
//! Each tile's background is the grey-level of one field at the artifact grid's points (the
//! reference for A, the solution elsewhere; √ of B over the tile's largest reference value);
//! over it:
//!
//! | picture | marks |
//! |---|---|
//! | `A-blocky-shadows.png` | penumbra-band points coloured by \|B − B_ref\| / m_p (viridis, 0 → 50 %) |
//! | `B-missing-features.png` | points of features the solution shows (green) and misses (red) |
//! | `C-mach-bands.png` | interior element edges (blue) and their Mach-band samples (red) |
//! | `D-shading-discontinuities.png` | interior element edges (blue) and their inappropriate jumps (red) |
//! | `E-unresolved-discontinuities.png` | critical segments resolved by an element edge (green) or inside an element (red) |

use crate::eval::artifacts::ArtifactMaps;
use crate::eval::pointwise::PointInterpolant;
use crate::math::DVec3;
use crate::mesh::ReceiverPlane;
use crate::present::image::{Colormap, Image};
use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// Side of one patch's tile, pixels.
const TILE: usize = 200;
/// Gap between tiles and around the sheet, pixels.
const GAP: usize = 6;
const BACKGROUND: [f32; 3] = [0.12, 0.12, 0.14];
const RED: [f32; 3] = [0.95, 0.1, 0.1];
const GREEN: [f32; 3] = [0.1, 0.85, 0.2];
const BLUE: [f32; 3] = [0.25, 0.45, 0.95];

/// The five file names, A to E.
pub const FILES: [&str; 5] = [
    "A-blocky-shadows.png",
    "B-missing-features.png",
    "C-mach-bands.png",
    "D-shading-discontinuities.png",
    "E-unresolved-discontinuities.png",
];

/// One tile: a patch's plane, its 2-D bounding box and where it goes on the sheet.
struct Tile {
    plane: ReceiverPlane,
    min: glam::DVec2,
    scale: f64,
    origin: (usize, usize),
    /// Largest reference value on the patch (the grey scale's white).
    white: f64,
}

impl Tile {
    fn pixel(&self, x: DVec3) -> (f64, f64) {
        let q = (self.plane.to_2d(x) - self.min) * self.scale;
        (self.origin.0 as f64 + q.x, (self.origin.1 + TILE) as f64 - q.y)
    }
}

/// The sheet: tiles of the patches that have grid points, in patch order.
struct Sheet {
    tiles: Vec<Option<Tile>>,
    width: usize,
    height: usize,
}

impl Sheet {
    fn new(scene: &Scene, maps: &ArtifactMaps) -> Sheet {
        let mut patches: Vec<usize> = maps.points.iter().map(|p| p.patch).collect();
        patches.dedup();
        let columns = (patches.len() as f64).sqrt().ceil().max(1.0) as usize;
        let rows = patches.len().div_ceil(columns).max(1);
        let mut tiles: Vec<Option<Tile>> = (0..scene.patches.len()).map(|_| None).collect();
        for (k, &p) in patches.iter().enumerate() {
            let Ok(plane) = ReceiverPlane::new(&scene.patches[p].vertices, 0.0) else { continue };
            let (min, max) = plane.polygon.iter().fold(
                (glam::DVec2::splat(f64::INFINITY), glam::DVec2::splat(f64::NEG_INFINITY)),
                |(lo, hi), q| (lo.min(*q), hi.max(*q)),
            );
            let extent = (max - min).max_element();
            if !(extent > 0.0) {
                continue;
            }
            let white = maps
                .points
                .iter()
                .zip(&maps.reference)
                .filter(|(pt, _)| pt.patch == p)
                .map(|(_, r)| r.mean())
                .fold(0.0, f64::max);
            let origin = (GAP + (k % columns) * (TILE + GAP), GAP + (k / columns) * (TILE + GAP));
            let scale = (TILE - 1) as f64 / extent;
            tiles[p] = Some(Tile { plane, min, scale, origin, white });
        }
        Sheet { tiles, width: GAP + columns * (TILE + GAP), height: GAP + rows * (TILE + GAP) }
    }

    /// A blank sheet with every pixel of every tile's patch filled by `colour(k)`, k the grid
    /// point nearest to the pixel's centre (`nearest`).
    fn cells(&self, nearest: &PointInterpolant, colour: &dyn Fn(usize) -> [f32; 3]) -> Image {
        let mut img = Image::new(self.width, self.height, BACKGROUND);
        for (patch, tile) in self.tiles.iter().enumerate() {
            let Some(tile) = tile else { continue };
            for py in 0..TILE {
                for px in 0..TILE {
                    let q =
                        tile.min + glam::DVec2::new(px as f64 + 0.5, (TILE - py) as f64 - 0.5) / tile.scale;
                    if !tile.plane.contains(q) {
                        continue;
                    }
                    if let Some(k) = nearest.nearest(patch, tile.plane.to_3d(q)) {
                        img.pixels[(tile.origin.1 + py) * self.width + tile.origin.0 + px] = colour(k);
                    }
                }
            }
        }
        img
    }

    /// Grey level of `values[k]` on its patch's scale.
    fn grey(&self, maps: &ArtifactMaps, values: &[crate::math::Rgb], k: usize) -> [f32; 3] {
        let white = self.tiles[maps.points[k].patch].as_ref().map_or(1.0, |t| t.white);
        let g = if white > 0.0 { (values[k].mean() / white).clamp(0.0, 1.0).sqrt() as f32 } else { 0.0 };
        [g * 0.8; 3]
    }

    /// A line of `length` along `along` centred on `x`, on `patch`'s tile.
    fn line(&self, img: &mut Image, patch: usize, x: DVec3, along: DVec3, length: f64, c: [f32; 3]) {
        let Some(tile) = &self.tiles[patch] else { return };
        let (a, b) = (tile.pixel(x - along * (0.5 * length)), tile.pixel(x + along * (0.5 * length)));
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            fill_square(img, a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t, 1.0, c);
        }
    }
}

/// Fill the pixels within `r` (half side, pixels) of (x, y).
fn fill_square(img: &mut Image, x: f64, y: f64, r: f64, c: [f32; 3]) {
    let (x0, x1) = ((x - r).round().max(0.0) as usize, (x + r).round().max(0.0) as usize);
    let (y0, y1) = ((y - r).round().max(0.0) as usize, (y + r).round().max(0.0) as usize);
    for py in y0..y1.min(img.height) {
        for px in x0..x1.min(img.width) {
            img.pixels[py * img.width + px] = c;
        }
    }
}

/// The five pictures of the artifact maps (module docs), A to E in [`FILES`] order.
#[must_use]
pub fn pictures(scene: &Scene, maps: &ArtifactMaps) -> [Image; 5] {
    let sheet = Sheet::new(scene, maps);
    let Ok(grid) = PointInterpolant::new(scene, &maps.points, &maps.solution) else {
        // The maps' points name patches of another scene: blank pictures.
        return std::array::from_fn(|_| Image::new(sheet.width, sheet.height, BACKGROUND));
    };
    let a = sheet.cells(&grid, &|k| {
        if maps.in_band[k] {
            let m = maps.means[maps.points[k].patch].0.max(f64::MIN_POSITIVE);
            Colormap::Viridis.at((maps.solution[k] - maps.reference[k]).mean().abs() / m / 0.5)
        } else {
            sheet.grey(maps, &maps.reference, k)
        }
    });
    let b = sheet.cells(&grid, &|k| match maps.features[k] {
        1 => GREEN,
        -1 => RED,
        _ => sheet.grey(maps, &maps.solution, k),
    });
    let base = |img: &mut Image, flag: &dyn Fn(&crate::eval::artifacts::EdgeMark) -> bool| {
        for e in &maps.edges {
            sheet.line(img, e.patch, e.x, e.along, e.length, BLUE);
        }
        for e in maps.edges.iter().filter(|e| flag(e)) {
            sheet.line(img, e.patch, e.x, e.along, e.length, RED);
        }
    };
    let mut c = sheet.cells(&grid, &|k| sheet.grey(maps, &maps.solution, k));
    base(&mut c, &|e| e.mach_band);
    let mut d = sheet.cells(&grid, &|k| sheet.grey(maps, &maps.solution, k));
    base(&mut d, &|e| e.jump);
    let mut e = sheet.cells(&grid, &|k| sheet.grey(maps, &maps.solution, k));
    for s in &maps.segments {
        sheet.line(&mut e, s.patch, s.x, s.along, s.length, if s.unresolved { RED } else { GREEN });
    }
    [a, b, c, d, e]
}

/// Write [`pictures`] into `dir` (created if missing) as [`FILES`]; returns the paths written.
pub fn write_pictures(scene: &Scene, maps: &ArtifactMaps, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let mut out = Vec::new();
    for (img, name) in pictures(scene, maps).iter().zip(FILES) {
        let path = dir.join(name);
        img.write_png(&path)?;
        out.push(path);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::artifacts::{ArtifactParams, Gouraud, measure_views};
    use crate::eval::pointwise::PiecewiseConstant;
    use crate::solver::Solution;

    /// Pixels of `img` equal to `c`.
    fn count(img: &Image, c: [f32; 3]) -> usize {
        img.pixels.iter().filter(|p| **p == c).count()
    }

    fn pictures_of(scene: &Scene, sol: &Solution) -> [Image; 5] {
        let sb = crate::geometry::exact::SingleBounce::new(scene).unwrap();
        let exact = |p: usize, x: DVec3| sb.patch_radiosity_at(p, x);
        let pc = PiecewiseConstant::new(scene, &sol.elements).unwrap();
        let g = Gouraud::new(scene, sol).unwrap();
        let (_, maps) = measure_views(scene, sol, &pc, &g, &exact, &ArtifactParams::quick()).unwrap();
        pictures(scene, &maps)
    }

    /// shadow-narrow as one element a patch: every critical segment lies inside the floor's one
    /// element (E red, no green), every feature is missing (B red, no green), no interior edge
    /// (C, D without blue). On the CDT the segments are resolved (E green, no red).
    #[test]
    fn pictures_mark_what_the_numbers_count() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let accel = crate::geometry::accel::Accel::build(&scene);
        let p = crate::solver::uniform::UniformParams {
            element_size: f64::INFINITY,
            ff_tolerance: crate::solver::uniform::COARSE_FF_TOLERANCE,
            ..Default::default()
        };
        let one = crate::solver::uniform::solve(&scene, &accel, &p, &mut |_, _| {}).unwrap();
        let [_, b, c, d, e] = pictures_of(&scene, &one);
        assert!(
            count(&e, RED) > 100 && count(&e, GREEN) == 0,
            "E: {} red, {} green",
            count(&e, RED),
            count(&e, GREEN)
        );
        assert!(count(&b, RED) > 100 && count(&b, GREEN) == 0, "B: {} red", count(&b, RED));
        assert_eq!(count(&c, BLUE) + count(&d, BLUE), 0, "no interior edges");
        let cdt = crate::solver::discontinuity::solve(
            &scene,
            &crate::solver::discontinuity::DiscontinuityParams::cdt(),
            &mut |_, _| {},
        )
        .unwrap();
        let [_, _, _, d, e] = pictures_of(&scene, &cdt.solution);
        assert!(
            count(&e, GREEN) > 100 && count(&e, RED) == 0,
            "E: {} green, {} red",
            count(&e, GREEN),
            count(&e, RED)
        );
        assert!(count(&d, BLUE) > 100 && count(&d, RED) > 0, "D: the CDT's edges, some jumping");
    }
}
