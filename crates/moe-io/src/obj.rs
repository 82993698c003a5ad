//! Wavefront OBJ meshes: positions (`v`) and polygonal faces (`f`), parsed by `tobj`.
//!
//! `tobj` renumbers vertices by first use within each object, which would scramble vertex ids
//! (marker and base vertices of a finger refer to the file's vertex order). The reader keeps the
//! file's order: before parsing it removes the keywords that split a file into several objects
//! (`o`, `g`, `usemtl`, `mtllib`) or that carry no surface (`l`, `p`), and prepends one
//! single-vertex face `f k` per vertex in file order, so first-use order is file order. These
//! come back from `tobj` as N degenerate triangles `(i, i, i)` that are dropped. Faces of the
//! file with fewer than three vertices are rejected before parsing.
//! Polygons are fan-triangulated by `tobj`; texture coordinates, normals and vertex colours are
//! ignored. Face numbers in geometry errors count triangles after triangulation.

use std::io::Read;
use std::path::Path;

use moe_geom::{Point3, TriMesh};

use crate::atomic::write_atomic;
use crate::error::IoError;
use crate::files::{MEMORY, guarded, read_bytes, read_to_end};

/// Reads an OBJ mesh (metres, the frame the file was written in).
///
/// # Errors
/// [`IoError::Io`] if the file cannot be read, [`IoError::Parse`] for malformed lines,
/// [`IoError::InvalidData`] for a face with fewer than three vertices or an index out of range,
/// [`IoError::Geometry`] when the faces do not form a valid mesh.
pub fn read_obj(path: &Path) -> Result<TriMesh, IoError> {
    parse_obj(&read_bytes(path)?, path)
}

/// Reads an OBJ mesh from any reader (errors name the path `<memory>`).
///
/// # Errors
/// As [`read_obj`].
pub fn read_obj_from(reader: impl Read) -> Result<TriMesh, IoError> {
    let path = Path::new(MEMORY);
    parse_obj(&read_to_end(reader, path)?, path)
}

/// Writes a mesh as OBJ, atomically. Coordinates use the shortest decimal form that parses
/// back to the same `f64`, so [`read_obj`] returns bit-identical vertices and the same faces.
///
/// # Errors
/// As [`write_atomic`].
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), IoError> {
    write_atomic(path, &obj_bytes(mesh))
}

/// The OBJ text of a mesh.
pub fn obj_bytes(mesh: &TriMesh) -> Vec<u8> {
    use std::fmt::Write;
    let mut s = String::with_capacity(mesh.num_vertices() * 64 + mesh.num_faces() * 24);
    let _ = writeln!(
        s,
        "# {} vertices, {} triangles; metres",
        mesh.num_vertices(),
        mesh.num_faces()
    );
    for p in mesh.vertices() {
        // `{:?}` prints the shortest representation that round-trips exactly.
        let _ = writeln!(s, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    for f in mesh.faces() {
        let _ = writeln!(s, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    s.into_bytes()
}

/// Parses OBJ bytes; `path` only names the source in errors.
pub(crate) fn parse_obj(bytes: &[u8], path: &Path) -> Result<TriMesh, IoError> {
    let text = crate::files::utf8_text(bytes, path)?;
    let (models, num_vertices) = match run_tobj(text, path)? {
        Ok(parsed) => parsed,
        Err(e) => return Err(locate_error(text, path, e)),
    };
    if num_vertices == 0 {
        return Err(IoError::geometry(
            path,
            moe_geom::GeomError::EmptyMesh {
                vertices: 0,
                faces: 0,
            },
        ));
    }
    let [model] = models.as_slice() else {
        return Err(IoError::parse(
            path,
            None,
            format!(
                "expected one object after preprocessing, got {}",
                models.len()
            ),
        ));
    };
    let mesh = &model.mesh;
    if mesh.positions.len() != 3 * num_vertices
        || mesh.indices.len() % 3 != 0
        || mesh.indices.len() < 3 * num_vertices
    {
        return Err(IoError::parse(
            path,
            None,
            "vertex list does not match the number of 'v' lines",
        ));
    }
    let (points, triangles) = mesh.indices.split_at(3 * num_vertices);
    if points
        .chunks_exact(3)
        .enumerate()
        .any(|(i, c)| c.iter().any(|&k| k as usize != i))
    {
        return Err(IoError::parse(
            path,
            None,
            "vertex order could not be preserved",
        ));
    }
    let vertices: Vec<Point3> = mesh
        .positions
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let faces: Vec<[u32; 3]> = triangles
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    TriMesh::new(vertices, faces).map_err(|e| IoError::geometry(path, e))
}

/// Keeps the lines that define one surface and prepends the order-fixing single-vertex faces.
/// Returns the text handed to `tobj` and the number of vertices.
fn prepare(text: &str, path: &Path) -> Result<(String, usize), IoError> {
    let mut body = String::with_capacity(text.len() + 16);
    let mut num_vertices = 0usize;
    let mut num_faces = 0usize;
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("o" | "g" | "usemtl" | "mtllib" | "l" | "p") => continue,
            Some("v") => num_vertices += 1,
            Some("f") => {
                num_faces += 1;
                let corners = words.count();
                if corners < 3 {
                    return Err(IoError::InvalidData {
                        path: path.to_path_buf(),
                        item: format!("face {} (line {})", num_faces - 1, i + 1),
                        message: format!("has {corners} vertices; a face needs at least 3"),
                    });
                }
            }
            _ => {}
        }
        body.push_str(line);
        body.push('\n');
    }
    if num_vertices > u32::MAX as usize {
        return Err(IoError::invalid(
            path,
            "vertex list",
            "more than 2^32 vertices",
        ));
    }
    let mut prepared = String::with_capacity(body.len() + num_vertices * 8 + 4);
    for k in 1..=num_vertices {
        use std::fmt::Write;
        let _ = writeln!(prepared, "f {k}");
    }
    prepared.push_str(&body);
    Ok((prepared, num_vertices))
}

/// Prepares `text` and runs `tobj` on it. The outer error is ours (prepass, caught panic), the
/// inner one is `tobj`'s.
#[allow(clippy::type_complexity)]
fn run_tobj(
    text: &str,
    path: &Path,
) -> Result<Result<(Vec<tobj::Model>, usize), tobj::LoadError>, IoError> {
    let (prepared, num_vertices) = prepare(text, path)?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: false,
        ignore_lines: true,
    };
    let mut reader = std::io::Cursor::new(prepared.as_bytes());
    guarded(path, "tobj", || {
        Ok(tobj::load_obj_buf(&mut reader, &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map(|(models, _materials)| (models, num_vertices)))
    })
}

/// Turns a `tobj` error (which carries no position) into one naming the line: an out-of-range
/// vertex index is found by checking the face lines; any other error by bisecting on the
/// number of leading lines handed to `tobj` (its errors come from the first bad line).
fn locate_error(text: &str, path: &Path, e: tobj::LoadError) -> IoError {
    use tobj::LoadError as E;
    if e == E::FaceVertexOutOfBounds
        && let Some(err) = find_bad_face_index(text, path)
    {
        return err;
    }
    let lines: Vec<&str> = text.lines().collect();
    let fails = |k: usize| -> bool {
        let prefix = lines[..k].join("\n");
        matches!(run_tobj(&prefix, path), Ok(Err(e2)) if e2 == e)
    };
    // Invariant: the first `lo` lines parse, the first `hi` lines fail with `e`.
    let (mut lo, mut hi) = (0, lines.len());
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fails(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let line = (hi > 0 && fails(hi)).then_some(hi);
    match e {
        E::InvalidPolygon => IoError::InvalidData {
            path: path.to_path_buf(),
            item: line.map_or("a polygon".into(), |l| format!("polygon on line {l}")),
            message: "cannot be triangulated".into(),
        },
        _ => IoError::parse(path, line, e.to_string()),
    }
}

/// The first face corner whose vertex index is zero or outside the vertex list.
fn find_bad_face_index(text: &str, path: &Path) -> Option<IoError> {
    let total = text
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count() as i64;
    let mut defined = 0i64;
    let mut face = 0usize;
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => defined += 1,
            Some("f") => {
                for corner in words {
                    let Some(Ok(x)) = corner.split('/').next().map(str::parse::<i64>) else {
                        continue;
                    };
                    let resolved = if x < 0 { defined + x } else { x - 1 };
                    if x == 0 || resolved < 0 || resolved >= total {
                        return Some(IoError::InvalidData {
                            path: path.to_path_buf(),
                            item: format!("face {face} (line {})", i + 1),
                            message: format!(
                                "vertex index {x} is out of range (the file has {total} vertices)"
                            ),
                        });
                    }
                }
                face += 1;
            }
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Result<TriMesh, IoError> {
        parse_obj(s.as_bytes(), Path::new("t.obj"))
    }

    const TETRA: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    #[test]
    fn keeps_file_vertex_order_even_when_faces_use_them_out_of_order() {
        // The first face uses vertex 4 first; tobj alone would renumber it to 0.
        let s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 4 2 3\nf 1 3 2\nf 1 2 4\nf 1 4 3\n";
        let m = p(s).unwrap();
        assert_eq!(m.vertices()[3], Point3::new(0.0, 0.0, 1.0));
        assert_eq!(m.faces()[0], [3, 1, 2]);
    }

    #[test]
    fn quads_are_triangulated_and_groups_merged() {
        let s = "o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng b\nf 1 2 3 4\n";
        let m = p(s).unwrap();
        assert_eq!(m.num_faces(), 2);
        assert_eq!(m.num_vertices(), 4);
    }

    #[test]
    fn slash_forms_and_negative_indices() {
        let s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf -3/1/1 -2/1/1 -1/1/1\n";
        let m = p(s).unwrap();
        assert_eq!(m.faces(), &[[0, 1, 2]]);
    }

    #[test]
    fn bad_input_gives_typed_errors() {
        assert!(matches!(
            p("v 0 0\n"),
            Err(IoError::Parse { line: Some(1), .. })
        ));
        let bad_number = TETRA.replace("v 0 1 0", "v 0 x 0");
        assert!(matches!(
            p(&bad_number),
            Err(IoError::Parse { line: Some(3), .. })
        ));
        let bad_face = TETRA.replace("f 1 4 3", "f 1 4 q");
        assert!(matches!(
            p(&bad_face),
            Err(IoError::Parse { line: Some(7), .. })
        ));
        let e = p(&TETRA.replace("f 1 2 4", "f 1 2 -9")).unwrap_err();
        assert!(e.to_string().contains("face 1 (line 6)"), "{e}");
        assert!(matches!(
            p(TETRA.replace("f 2 3 4", "f 2 3 9").as_str()),
            Err(IoError::InvalidData { .. })
        ));
        assert!(matches!(
            p("v 0 0 0\nv 1 0 0\nf 1 2\n"),
            Err(IoError::InvalidData { .. })
        ));
        assert!(matches!(p(""), Err(IoError::Geometry { .. })));
        assert!(matches!(
            p("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
            Err(IoError::Geometry { .. })
        ));
        assert!(matches!(
            p("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
            Err(IoError::Geometry { .. })
        ));
        assert!(matches!(
            parse_obj(b"v 0 0 0\xff\n", Path::new("t.obj")),
            Err(IoError::Parse { line: Some(1), .. })
        ));
    }

    #[test]
    fn write_then_parse_is_bit_exact() {
        let v = vec![
            Point3::new(0.1, -2.0 / 3.0, 1e-7),
            Point3::new(std::f64::consts::PI, 5e-7, -0.0),
            Point3::new(1.0 / 7.0, 0.3, 1.234_567_890_123_456_7),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2]]).unwrap();
        let back = parse_obj(&obj_bytes(&m), Path::new("t.obj")).unwrap();
        for (a, b) in m.vertices().iter().zip(back.vertices()) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits());
            }
        }
        assert_eq!(m.faces(), back.faces());
    }
}
