//! Generated scene families: interiors of many small objects, of any size, to measure the
//! solver on scenes shaped like a user's rather than like the one it was tuned on.
//!
//! `builtin:FAMILY-SIZE[-sSEED]` (and `radlab scenes --generate FAMILY --triangles N --out
//! PATH.glb`): a scene of `SIZE` triangles (within 2 %, [`MIN_TRIANGLES`] to [`MAX_TRIANGLES`]),
//! the same patch for patch for the same name. Every family is a closed room (or a closed
//! building of rooms) lit by emissive panels facing down:
//!
//! | family | what fills the room |
//! |---|---|
//! | `furnished` | tables, chairs, desks, bookcases, lamps ([`super::furnished`]) |
//! | `box-grid` | a dense grid of small boxes of varying height on the floor, one 2 × 2 panel ([`box_grid`]) |
//! | `shelves` | rows of bookcases back to back, full of thin books ([`shelves`]) |
//! | `chairs` | rows of chairs with thin legs facing a board ([`chairs`]) |
//! | `stacked-boxes` | stacks of boxes resting on each other, each turned ([`stacked_boxes`]) |
//! | `corridor` | a long corridor with rooms on both sides behind doors, mostly shut off ([`corridor`]) |
//!
//! ## How it works
//! ```text
//!  plan(k):  the family's layout for k objects (boxes, bookcases, chairs, stacks, pairs of
//!            rooms) and a room sized to hold them → pieces (boxes, parallelograms), the floor
//!            a "fill" piece counted as one cell
//!  k:        the largest k whose plan has ≤ SIZE − 2 triangles (count(k) grows with k:
//!            bracket from a linear estimate, then bisect)
//!  fill:     the floor cut into as many cells as make up the rest
//! ```
//! The objects are made of quads, one per face, written to a file as two triangles each and
//! merged back by the loader; a face whose quad is not planar at f32 precision (a turned box
//! far from the origin) stays two triangles ([`kit`]). So `SIZE` counts triangles as a glTF
//! file does, a scene has about SIZE / 2 patches, and the generated scene and its file load the
//! same. The furnished room keeps its own generator: its patches are triangles (SIZE of them),
//! and its file loads back as quads where two halves merge.

pub mod box_grid;
pub mod chairs;
pub mod corridor;
pub mod kit;
pub mod shelves;
pub mod stacked_boxes;

use super::{Scene, SceneError};
use kit::Layout;

/// The smallest family scene (one object and its room are a few hundred triangles).
pub const MIN_TRIANGLES: usize = 1_000;
/// The largest (the loader's default triangle cap).
pub const MAX_TRIANGLES: usize = 5_000_000;

/// A scene family.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    Furnished,
    BoxGrid,
    Shelves,
    Chairs,
    StackedBoxes,
    Corridor,
}

impl Family {
    /// Every family, in the order they are listed.
    pub const ALL: [Family; 6] = [
        Family::Furnished,
        Family::BoxGrid,
        Family::Shelves,
        Family::Chairs,
        Family::StackedBoxes,
        Family::Corridor,
    ];

    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Family::Furnished => "furnished",
            Family::BoxGrid => "box-grid",
            Family::Shelves => "shelves",
            Family::Chairs => "chairs",
            Family::StackedBoxes => "stacked-boxes",
            Family::Corridor => "corridor",
        }
    }

    #[must_use]
    pub fn from_name(name: &str) -> Option<Family> {
        Family::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The families' names, comma-separated (for messages).
    #[must_use]
    pub fn names() -> String {
        Family::ALL.map(Family::name).join(", ")
    }

    /// One line: what the family's scenes hold.
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Family::Furnished => "a furnished room: tables, chairs, desks, bookcases, lamps",
            Family::BoxGrid => "a dense grid of small boxes of varying height under one 2 x 2 ceiling panel",
            Family::Shelves => "rows of bookcases back to back, full of thin books",
            Family::Chairs => "rows of chairs with thin legs facing a board",
            Family::StackedBoxes => "stacks of turned boxes resting on each other and side by side",
            Family::Corridor => "a long corridor with rooms behind doors on both sides, mostly shut off",
        }
    }

    /// The size range the family's generator takes.
    #[must_use]
    pub fn range(self) -> (usize, usize) {
        match self {
            Family::Furnished => (super::furnished::MIN_TRIANGLES, super::furnished::MAX_TRIANGLES),
            _ => (MIN_TRIANGLES, MAX_TRIANGLES),
        }
    }
}

/// What a `FAMILY-SIZE[-sSEED]` name asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FamilyParams {
    pub family: Family,
    /// Target number of triangles.
    pub triangles: usize,
    /// Picks the layout, sizes and colours.
    pub seed: u64,
}

impl FamilyParams {
    /// Parameters for `family` at `triangles` (checked against the family's range) and `seed`.
    pub fn new(family: Family, triangles: usize, seed: u64) -> Result<FamilyParams, String> {
        let (min, max) = family.range();
        if !(min..=max).contains(&triangles) {
            return Err(format!(
                "{triangles} triangles is outside the {} generator's range {min}..={max}",
                family.name()
            ));
        }
        Ok(FamilyParams { family, triangles, seed })
    }
}

/// Parse a triangle count such as `10k`, `30000` or `1m` in the family's range.
pub fn parse_triangles(family: Family, size: &str) -> Result<usize, String> {
    let (min, max) = family.range();
    super::furnished::parse_triangles(size, min, max)
}

/// Parse `FAMILY-SIZE[-sSEED]` (the part after `builtin:`). `None` if the name is no family's;
/// `Some(Err(cause))` if it is one with a bad size or seed.
#[must_use]
pub fn parse(name: &str) -> Option<Result<FamilyParams, String>> {
    let (family, rest) = Family::ALL
        .into_iter()
        .find_map(|f| name.strip_prefix(f.name()).and_then(|r| r.strip_prefix('-')).map(|r| (f, r)))?;
    let (min, max) = family.range();
    Some(super::furnished::parse_size_seed(rest, min, max).map(|(triangles, seed)| FamilyParams {
        family,
        triangles,
        seed,
    }))
}

/// Load `builtin:NAME` for a family name: parse it and generate the scene.
pub fn load(name: &str, params: Result<FamilyParams, String>) -> Result<Scene, SceneError> {
    super::furnished::load_generated(name, params, generate)
}

/// The scene for these parameters (deterministic).
#[must_use]
pub fn generate(params: FamilyParams) -> Scene {
    let FamilyParams { family, triangles, seed } = params;
    let plan: fn(usize, u64) -> Layout = match family {
        Family::Furnished => {
            let room = super::furnished::FurnishedParams { triangles, seed };
            return super::furnished::generate(room);
        }
        Family::BoxGrid => box_grid::layout,
        Family::Shelves => shelves::layout,
        Family::Chairs => chairs::layout,
        Family::StackedBoxes => stacked_boxes::layout,
        Family::Corridor => corridor::layout,
    };
    let budget = triangles.saturating_sub(2);
    let k = largest_fitting(budget, |k| plan(k, seed).triangles());
    let layout = plan(k, seed);
    let extra = triangles.saturating_sub(layout.triangles());
    let name = format!("{}-{triangles}-s{seed}", family.name());
    let mut scene = Scene::new(name.clone(), format!("builtin:{name}"), layout.patches(extra));
    scene.camera = Some(layout.camera);
    scene
}

/// Triangles of a scene as a glTF file holds them: a quad patch is two.
#[must_use]
pub fn triangles(scene: &Scene) -> usize {
    scene.patches.iter().map(|p| p.vertices.len() - 2).sum()
}

/// The largest k ≥ 1 with `count(k) ≤ budget` (1 if none), for a count that grows with k
/// (about linearly): bracketed from the slope between k = 1 and 2, then bisected.
fn largest_fitting(budget: usize, count: impl Fn(usize) -> usize) -> usize {
    let first = count(1);
    if first >= budget {
        return 1;
    }
    let per = count(2).saturating_sub(first).max(1);
    let estimate = 1 + (budget - first) / per;
    let mut lo = (estimate * 4 / 5).max(1);
    while lo > 1 && count(lo) > budget {
        lo /= 2;
    }
    let mut hi = (estimate * 5 / 4).max(lo + 1);
    while count(hi) <= budget {
        lo = hi;
        hi *= 2;
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if count(mid) <= budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse() {
        let p = |s: &str| parse(s).map(|r| r.map(|f| (f.family, f.triangles, f.seed)));
        assert_eq!(p("box-grid-10k"), Some(Ok((Family::BoxGrid, 10_000, 0))));
        assert_eq!(p("stacked-boxes-2500-s3"), Some(Ok((Family::StackedBoxes, 2_500, 3))));
        assert_eq!(p("furnished-1m"), Some(Ok((Family::Furnished, 1_000_000, 0))));
        assert_eq!(p("cornell"), None);
        assert_eq!(p("box-grid"), None);
        for bad in
            ["box-grid-", "shelves-10q", "chairs-999", "corridor-10k-sx", "furnished-1k", "box-grid-6m"]
        {
            assert!(matches!(p(bad), Some(Err(_))), "{bad}");
        }
        for f in Family::ALL {
            assert_eq!(Family::from_name(f.name()), Some(f));
        }
    }

    #[test]
    fn the_largest_fitting_count_is_found() {
        for budget in [0, 5, 99, 100, 1234, 1_000_000] {
            let count = |k: usize| 37 + 10 * k + k / 7;
            let k = largest_fitting(budget, count);
            assert!(k == 1 || count(k) <= budget, "{budget}: {k}");
            assert!(count(k + 1) > budget, "{budget}: {k}");
        }
    }
}
