//! STL meshes (ascii and binary), parsed by `stl_io` and welded into an indexed mesh.
//!
//! STL stores every triangle with its own three corners in `f32`. `stl_io` merges corners with
//! bit-identical coordinates; the reader then welds corners closer than
//! [`STL_WELD_RELATIVE_TOLERANCE`] × the bounding-box diagonal, drops faces that collapse and
//! validates the result. The tolerance, 1e-7, is just above `f32`'s relative precision
//! (6e-8): it absorbs exporters that write the same corner twice rounded differently (one `f32`
//! ulp apart), and is far below any real edge length (for an 8 cm finger, 8 nm). The welded
//! vertices are numbered in order of first appearance in the file. STL is read-only here: it
//! cannot carry shared vertex ids.

use std::io::Read;
use std::path::Path;

use moe_geom::{Aabb, Point3, TriMesh};

use crate::error::IoError;
use crate::files::{MEMORY, guarded, read_bytes, read_to_end};

/// Weld tolerance of [`read_stl`], relative to the mesh's bounding-box diagonal.
pub const STL_WELD_RELATIVE_TOLERANCE: f64 = 1e-7;

/// Reads an ascii or binary STL file as a welded, validated triangle mesh.
///
/// # Errors
/// [`IoError::Io`] if unreadable, [`IoError::Parse`] for malformed or truncated files,
/// [`IoError::Geometry`] when the welded triangles do not form a valid mesh.
pub fn read_stl(path: &Path) -> Result<TriMesh, IoError> {
    parse_stl(&read_bytes(path)?, path)
}

/// Reads STL from any reader (errors name the path `<memory>`).
///
/// # Errors
/// As [`read_stl`].
pub fn read_stl_from(reader: impl Read) -> Result<TriMesh, IoError> {
    let path = Path::new(MEMORY);
    parse_stl(&read_to_end(reader, path)?, path)
}

/// Parses STL bytes; `path` only names the source in errors.
pub(crate) fn parse_stl(bytes: &[u8], path: &Path) -> Result<TriMesh, IoError> {
    let mut cursor = std::io::Cursor::new(bytes);
    let indexed = guarded(path, "stl_io", || {
        stl_io::read_stl(&mut cursor).map_err(|e| IoError::parse(path, None, e.to_string()))
    })?;
    let vertices: Vec<Point3> = indexed
        .vertices
        .iter()
        .map(|v| Point3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    let mut faces = Vec::with_capacity(indexed.faces.len());
    for (f, t) in indexed.faces.iter().enumerate() {
        let mut ids = [0u32; 3];
        for (k, &i) in t.vertices.iter().enumerate() {
            ids[k] = u32::try_from(i).map_err(|_| {
                IoError::invalid(path, format!("facet {f}"), "more than 2^32 vertices")
            })?;
        }
        faces.push(ids);
    }
    let tolerance = Aabb::from_points(&vertices)
        .map(|b| b.diagonal() * STL_WELD_RELATIVE_TOLERANCE)
        .filter(|t| t.is_finite())
        .unwrap_or(0.0);
    TriMesh::welded(&vertices, &faces, tolerance).map_err(|e| IoError::geometry(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "solid t\n\
        facet normal 0 0 -1\n outer loop\n  vertex 0 0 0\n  vertex 0 1 0\n  vertex 1 0 0\n endloop\nendfacet\n\
        facet normal 0 -1 0\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 0 1\n endloop\nendfacet\n\
        facet normal -1 0 0\n outer loop\n  vertex 0 0 0\n  vertex 0 0 1\n  vertex 0 1 0\n endloop\nendfacet\n\
        facet normal 1 1 1\n outer loop\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 0 0 1\n endloop\nendfacet\n\
        endsolid t\n";

    #[test]
    fn ascii_tetrahedron_is_welded_and_closed() {
        let m = parse_stl(ASCII.as_bytes(), Path::new("t.stl")).unwrap();
        assert_eq!(m.num_vertices(), 4);
        assert_eq!(m.num_faces(), 4);
        m.require_closed().unwrap();
        assert!((m.signed_volume() - 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn garbage_is_an_error() {
        for garbage in [&b"solid x\nfacet nonsense\n"[..], &[0u8; 10]] {
            moe_geom::assert_err!(
                parse_stl(garbage, Path::new("t.stl")),
                IoError::Parse { path, .. } if path == Path::new("t.stl")
            );
        }
    }
}
