//! (in progress)
use std::path::Path; use crate::{scene::Scene, SceneError};
pub fn load_gltf(path: &Path) -> Result<Scene, SceneError> { Err(SceneError::UnknownFormat{path: path.into()}) }
