//! Reading and writing meshes by file extension.

use std::path::Path;

use moe_geom::TriMesh;

use crate::error::IoError;
use crate::files::extension;
use crate::obj::{read_obj, write_obj};
use crate::ply::{PlyData, read_ply, write_ply};
use crate::stl::read_stl;

/// Reads a mesh: `.obj`, `.ply` (which must have faces) or `.stl` (welded on load), chosen by
/// the (case-insensitive) extension.
///
/// # Errors
/// [`IoError::UnsupportedExtension`] for other extensions; otherwise the format reader's errors.
pub fn read_mesh(path: &Path) -> Result<TriMesh, IoError> {
    match extension(path).as_str() {
        "obj" => read_obj(path),
        "ply" => read_ply(path)?.into_mesh().map_err(|e| IoError::Geometry {
            path: path.to_path_buf(),
            source: e,
        }),
        "stl" => read_stl(path),
        ext => Err(IoError::UnsupportedExtension {
            path: path.to_path_buf(),
            ext: ext.to_string(),
            expected: "obj, ply or stl",
        }),
    }
}

/// Writes a mesh, atomically: `.obj` (text) or `.ply` (binary little-endian, double
/// coordinates), chosen by the extension. Both round-trip bit-exactly through [`read_mesh`].
///
/// # Errors
/// [`IoError::UnsupportedExtension`] for other extensions (STL is read-only: it cannot hold
/// shared vertices); otherwise as [`crate::write_atomic`].
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), IoError> {
    match extension(path).as_str() {
        "obj" => write_obj(path, mesh),
        "ply" => write_ply(path, &PlyData::from_mesh(mesh)),
        ext => Err(IoError::UnsupportedExtension {
            path: path.to_path_buf(),
            ext: ext.to_string(),
            expected: "obj or ply",
        }),
    }
}
