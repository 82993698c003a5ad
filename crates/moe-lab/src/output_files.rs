//! The files a command writes into its output directory, made in memory first so that a failure
//! leaves nothing half-written, then written together by one call.

use std::path::Path;

use moe_geom::{Real, TriMesh};
use moe_io::{IoError, PlyData};
use serde::Serialize;

use crate::error::LabError;

/// Writes a value to a path.
type Writer = Box<dyn Fn(&Path) -> Result<(), IoError> + Send + Sync>;

/// One file's content, written by the `moe-io` writer of its format.
enum Content {
    /// A mesh, OBJ or PLY by the file name's extension.
    Mesh(TriMesh),
    /// A PLY file with per-vertex properties.
    Ply(PlyData),
    /// A numeric CSV table.
    Csv {
        header: &'static [&'static str],
        rows: Vec<Vec<Real>>,
    },
    /// A value as JSON.
    Json(Writer),
    /// Bytes as they are.
    Bytes(Vec<u8>),
}

impl std::fmt::Debug for Content {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Mesh(_) => "Mesh",
            Self::Ply(_) => "Ply",
            Self::Csv { .. } => "Csv",
            Self::Json(_) => "Json",
            Self::Bytes(_) => "Bytes",
        })
    }
}

/// The files of one output directory, by name, in the order they are written.
#[derive(Debug, Default)]
pub struct OutputFiles {
    files: Vec<(String, Content)>,
}

impl OutputFiles {
    /// No files.
    pub fn new() -> Self {
        Self::default()
    }

    /// A mesh, written as OBJ or PLY by the extension of `name`.
    pub fn add_mesh(&mut self, name: impl Into<String>, mesh: TriMesh) {
        self.files.push((name.into(), Content::Mesh(mesh)));
    }

    /// A PLY file.
    pub fn add_ply(&mut self, name: impl Into<String>, ply: PlyData) {
        self.files.push((name.into(), Content::Ply(ply)));
    }

    /// A numeric CSV table with its header.
    pub fn add_csv(
        &mut self,
        name: impl Into<String>,
        header: &'static [&'static str],
        rows: Vec<Vec<Real>>,
    ) {
        self.files
            .push((name.into(), Content::Csv { header, rows }));
    }

    /// `value` as JSON, written by `moe_io::write_json` (indented, ending in a newline).
    pub fn add_json<T: Serialize + Send + Sync + 'static>(
        &mut self,
        name: impl Into<String>,
        value: T,
    ) {
        let write: Writer = Box::new(move |path| moe_io::write_json(path, &value));
        self.files.push((name.into(), Content::Json(write)));
    }

    /// A file of these bytes.
    pub fn add_bytes(&mut self, name: impl Into<String>, bytes: Vec<u8>) {
        self.files.push((name.into(), Content::Bytes(bytes)));
    }

    /// The names of the files, in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.files.iter().map(|(name, _)| name.as_str())
    }

    /// Creates `dir` (and its parents) and writes every file into it, each atomically.
    ///
    /// # Errors
    /// [`IoError`] naming the directory or the file that could not be written.
    pub fn write(&self, dir: &Path) -> Result<(), LabError> {
        std::fs::create_dir_all(dir).map_err(|source| IoError::io(dir, source))?;
        for (name, content) in &self.files {
            let path = dir.join(name);
            match content {
                Content::Mesh(mesh) => moe_io::write_mesh(&path, mesh)?,
                Content::Ply(ply) => moe_io::write_ply(&path, ply)?,
                Content::Csv { header, rows } => moe_io::write_csv(&path, header, rows)?,
                Content::Json(write) => write(&path)?,
                Content::Bytes(bytes) => moe_io::write_atomic(&path, bytes)?,
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_file_is_written_in_a_new_directory_as_its_writer_writes_it() {
        let dir = std::env::temp_dir().join(format!("moe-lab-output-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let out = dir.join("a/b");
        let mut files = OutputFiles::new();
        files.add_csv("t.csv", &["x", "y"], vec![vec![1.0, 2.0]]);
        files.add_json("r.json", serde_json::json!({"k": 1}));
        files.add_bytes("raw.txt", b"raw".to_vec());
        assert_eq!(
            files.names().collect::<Vec<_>>(),
            ["t.csv", "r.json", "raw.txt"]
        );
        files.write(&out).unwrap();
        let table = moe_io::read_csv(&out.join("t.csv")).unwrap();
        assert_eq!(table.rows, [vec![1.0, 2.0]]);
        let json = std::fs::read_to_string(out.join("r.json")).unwrap();
        assert_eq!(json, "{\n  \"k\": 1\n}\n");
        assert_eq!(std::fs::read(out.join("raw.txt")).unwrap(), b"raw");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_directory_that_cannot_be_made_is_named() {
        let dir = std::env::temp_dir().join(format!("moe-lab-output-file-{}", std::process::id()));
        std::fs::write(&dir, b"a file").unwrap();
        let err = OutputFiles::new().write(&dir.join("sub")).unwrap_err();
        assert!(err.to_string().contains("sub"), "{err}");
        std::fs::remove_file(&dir).unwrap();
    }
}
