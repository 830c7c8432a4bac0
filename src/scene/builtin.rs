//! Built-in scenes (being written).
use super::{Scene, SceneError};

/// Load a built-in scene by name.
pub fn load(name: &str) -> Result<Scene, SceneError> {
    Err(SceneError::UnknownBuiltin { name: name.into() })
}
