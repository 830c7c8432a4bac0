//! `radlab mesh SCENE [--kind cdt|bsp] [--min-angle DEG] [--max-area F] [--budget N] [--solve]
//! [--json PATH]`: the scene's discontinuity mesh (`radlab::mesh`): critical segments by kind,
//! constraints inserted, receivers remeshed, patches before and after, and the meshing time;
//! with `--budget N|auto`, graded to N patches (or a budget chosen from the scene)
//! ([`radlab::mesh::grade`]); with `--solve`, also a uniform p = 0 solve on the mesh and its
//! time (meshing against solving).

use super::solve::load_scene;
use anyhow::Context as _;
use radlab::mesh::cdt::CdtParams;
use radlab::mesh::remesh::{MeshKind, RemeshParams, RemeshStats, discontinuity_scene};
use radlab::solver::discontinuity::{self, DiscontinuityParams};
use serde_json::json;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene (.gltf/.glb or builtin:NAME)
    pub scene: String,
    /// Constrained Delaunay (Heckbert) or BSP (Campbell & Fussell)
    #[arg(long, value_enum, default_value = "cdt")]
    pub kind: MeshKind,
    /// CDT refinement: smallest angle in degrees (0: the unrefined CDT; default 20, or 0 with
    /// --budget, whose grading sizes the elements)
    #[arg(long)]
    pub min_angle: Option<f64>,
    /// CDT refinement: largest triangle area as a fraction of its receiver's area
    #[arg(long, default_value_t = f64::INFINITY)]
    pub max_area: f64,
    /// Refuse meshes with more patches than this
    #[arg(long, default_value_t = RemeshParams::cdt().max_patches)]
    pub max_patches: usize,
    /// Grade the mesh to N patches for the whole scene, or to the budget `auto` chooses from the
    /// scene (as `radlab solve --dmesh-budget`; the defaults of src/mesh/grade.rs; `off`, the
    /// default: ungraded)
    #[arg(long, value_name = "N|auto|off")]
    pub budget: Option<super::solve::BudgetArg>,
    /// Also solve on the mesh (uniform solver, one element per piece, 16 rays, --ff-tol 1e-4)
    #[arg(long)]
    pub solve: bool,
    /// Write the figures as JSON to PATH (`-` for stdout)
    #[arg(long)]
    pub json: Option<String>,
}

fn print(spec: &str, kind: MeshKind, s: &RemeshStats) {
    let c = &s.segments;
    println!("{spec}: {kind:?} discontinuity mesh");
    println!(
        "  segments   {} (D0 {}, D1 {}, D2 {}; EV {}, VE {}); occluder pairs kept {}, culled {}",
        c.total(),
        c.d0,
        c.d1,
        c.d2,
        c.ev,
        c.ve,
        c.occluders_kept,
        c.occluders_culled
    );
    println!(
        "  constraints {} (clipped, snapped, deduplicated) on {} receivers",
        s.constraints, s.receivers_meshed
    );
    println!("  patches    {} → {}", s.input_patches, s.output_patches);
    if let Some(g) = &s.graded {
        println!(
            "  graded     to {}{}: {} → {} patches, {} splits, {} direct-light samples, {:.4} s",
            g.budget,
            if g.auto { " (auto)" } else { "" },
            g.patches_before,
            g.patches_after,
            g.splits,
            g.direct_samples,
            g.grade_s
        );
    }
    if s.pieces_dropped > 0 || s.refinement_incomplete > 0 {
        println!(
            "  warnings   {} pieces dropped (area {:e}); {} receivers' refinement hit the Steiner cap",
            s.pieces_dropped, s.area_dropped, s.refinement_incomplete
        );
    }
    println!(
        "  time       {:.4} s wall (segments {:.4} s + meshing {:.4} s, summed over threads)",
        s.total_s, s.segments_s, s.mesh_s
    );
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // The loader's default triangle cap; the mesh cap (--max-patches) is the one that binds.
    let scene = load_scene(&args.scene, radlab::scene::gltf::LoadOptions::default().max_triangles)?;
    let base = match args.kind {
        MeshKind::Cdt => RemeshParams::cdt(),
        MeshKind::Bsp => RemeshParams::bsp(),
    };
    let grading = super::solve::BudgetArg::grading(args.budget, super::solve::BudgetArg::Off);
    let params = RemeshParams {
        cdt: CdtParams {
            min_angle_deg: args.min_angle.unwrap_or(if grading.is_some() {
                0.0
            } else {
                CdtParams::quality().min_angle_deg
            }),
            max_area: args.max_area,
            ..base.cdt
        },
        max_patches: match grading {
            Some(radlab::mesh::grade::Budget::Patches(n)) => args.max_patches.max(n),
            _ => args.max_patches,
        },
        grade: grading.map(|budget| radlab::mesh::grade::GradeParams {
            budget,
            ..radlab::mesh::grade::GradeParams::auto()
        }),
        ..base
    };
    let stdout_json = args.json.as_deref() == Some("-");
    let (stats, solve) = if args.solve {
        let d = discontinuity::solve(&scene, &DiscontinuityParams::with_mesh(params), &mut |_, _| {})
            .with_context(|| format!("solving {} on its discontinuity mesh", args.scene))?;
        let s = &d.solution.stats;
        if !stdout_json {
            print(&args.scene, args.kind, &d.mesh);
            println!("  solve      {:.3} s (uniform, {} elements, {} links)", d.solve_s, s.elements, s.links);
        }
        let solve =
            json!({ "method": "uniform", "elements": s.elements, "links": s.links, "time_s": d.solve_s });
        (d.mesh, solve)
    } else {
        let meshed =
            discontinuity_scene(&scene, &params).with_context(|| format!("meshing {}", args.scene))?;
        if !stdout_json {
            print(&args.scene, args.kind, &meshed.stats);
        }
        (meshed.stats, serde_json::Value::Null)
    };
    let doc = json!({ "scene": args.scene, "params": params, "stats": stats, "solve": solve });
    match args.json.as_deref() {
        Some("-") => println!("{}", serde_json::to_string_pretty(&doc)?),
        Some(path) => std::fs::write(path, serde_json::to_string_pretty(&doc)? + "\n")
            .with_context(|| format!("writing {path}"))?,
        None => {}
    }
    Ok(())
}
