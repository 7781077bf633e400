//! Errors from loading a scene: each names where (file, line, column) and what (field).

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read (missing, unreadable, too large, not UTF-8 text).
    #[error("{path}: cannot read scene file: {message}")]
    Io { path: PathBuf, message: String },
    /// A syntax, type or validation error at a place in the file.
    #[error("{path}:{line}:{column}: {field}: {message}")]
    At { path: PathBuf, line: usize, column: usize, field: String, message: String },
    /// A problem in a mesh file an object refers to.
    #[error("{path}:{line}:{column}: {field}: mesh {mesh}: {message}")]
    Mesh { path: PathBuf, line: usize, column: usize, field: String, mesh: PathBuf, message: String },
    /// A problem in a file that comes with a mesh (its camera file).
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
    /// A problem in a glTF file given on its own; the message starts with the glTF path
    /// (`meshes[2].primitives[0].indices: ...`).
    #[error("{path}: {message}")]
    Gltf { path: PathBuf, message: String },
    /// The scene is valid but larger than strahl accepts.
    #[error("{path}: {message}")]
    TooLarge { path: PathBuf, message: String },
}
