//! Errors a caller cannot foresee: a file that does not exist, cannot be parsed,
//! or holds something hyrt cannot render. Each names the file and the problem.

use std::path::PathBuf;

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read file: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The glTF file is malformed or refers to data that cannot be loaded.
    #[error("{path}: not a valid glTF 2.0 file: {message}")]
    Gltf { path: PathBuf, message: String },
    /// The TOML manifest does not parse or does not match the manifest schema.
    #[error("{path}: invalid scene manifest: {message}")]
    Manifest { path: PathBuf, message: String },
    /// An entry of a TOML manifest (a model file) could not be loaded. The message names the
    /// manifest, the entry (e.g. `model[1] 'bunny'`) and the underlying error, which names
    /// the model file.
    #[error("{path}: {entry}: {error}")]
    ManifestEntry {
        /// The manifest.
        path: PathBuf,
        /// The entry, e.g. `model[1] 'bunny'`.
        entry: String,
        /// Why it failed (an error naming the model file).
        error: Box<SceneError>,
    },
    /// The file parses but its content cannot be rendered (e.g. NaN vertex positions,
    /// indices out of range, a primitive mode other than triangles).
    #[error("{path}: {message}")]
    Content { path: PathBuf, message: String },
    /// The file extension is not one hyrt knows.
    #[error("{path}: unknown scene format (expected .glb, .gltf or .toml)")]
    UnknownFormat { path: PathBuf },
}
