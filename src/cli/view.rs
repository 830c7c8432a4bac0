//! `radlab view` (being written).

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: a .gltf/.glb path or builtin:NAME.
    #[arg(default_value = "builtin:cornell")]
    pub scene: String,
}

impl Args {
    pub fn default_scene() -> Args {
        Args { scene: "builtin:cornell".into() }
    }
}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("the viewer is not written yet; try `radlab solve`")
}
