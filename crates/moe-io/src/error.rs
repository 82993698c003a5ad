//! The error type of `moe-io`.

use std::path::PathBuf;

use moe_geom::GeomError;

/// Everything that can go wrong reading or writing a file.
///
/// Every variant names the file (`path`; readers fed from memory use the pseudo-path
/// `<memory>`), and where the format tells us, the line, column, element or row at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused a read, write, rename or directory listing.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A writer was asked to write into a directory that does not exist. Writers never create
    /// directories: create it first.
    #[error("{}: directory {} does not exist", path.display(), dir.display())]
    MissingDirectory {
        /// The file that was to be written.
        path: PathBuf,
        /// Its parent directory.
        dir: PathBuf,
    },
    /// The file name's extension names no format this function handles.
    #[error("{}: unsupported extension '{ext}' (expected {expected})", path.display())]
    UnsupportedExtension {
        /// The file.
        path: PathBuf,
        /// The extension found (empty when there is none).
        ext: String,
        /// The extensions accepted, e.g. `"obj, ply or stl"`.
        expected: &'static str,
    },
    /// The file is not well-formed in its format (syntax error, truncation, bad header).
    #[error("{}{}: {message}", path.display(), location(*line, *column))]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line, when the parser reports it.
        line: Option<usize>,
        /// 1-based column, when the parser reports it.
        column: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The file parses but an item in it is invalid (NaN coordinate, wrong number of values,
    /// an index out of range, a polygon that cannot be triangulated).
    #[error("{}: {item}: {message}", path.display())]
    InvalidData {
        /// The file.
        path: PathBuf,
        /// The offending item, e.g. `"face 12"`, `"vertex 3 property 'x'"`, `"row 4, column 2"`.
        item: String,
        /// What is wrong with it.
        message: String,
    },
    /// The file's mesh data do not form a valid mesh (see [`GeomError`], which names the
    /// vertex, face or edge).
    #[error("{}: {source}", path.display())]
    Geometry {
        /// The file.
        path: PathBuf,
        /// The geometric problem.
        #[source]
        source: GeomError,
    },
    /// A config is well-formed but asks for something inconsistent.
    #[error("{}: {message}", path.display())]
    Config {
        /// The config file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file referenced by a config (e.g. a finger mesh) could not be loaded.
    #[error("{}: {what}: {source}", path.display())]
    Referenced {
        /// The config file that references the other file.
        path: PathBuf,
        /// Which entry references it, e.g. `"fingers[1].mesh"`.
        what: String,
        /// The error loading the referenced file (it names that file).
        #[source]
        source: Box<IoError>,
    },
    /// A value could not be serialised (e.g. a map with non-string keys for JSON, a
    /// non-finite number in a format that cannot hold it).
    #[error("{}: cannot serialise: {message}", path.display())]
    Serialize {
        /// The file that was to be written.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A third-party parser panicked on this input; the panic was caught and turned into this
    /// error.
    #[error("{}: the {parser} parser failed on malformed input", path.display())]
    ParserPanic {
        /// The file.
        path: PathBuf,
        /// Which parser crate.
        parser: &'static str,
    },
}

fn location(line: Option<usize>, column: Option<usize>) -> String {
    match (line, column) {
        (Some(l), Some(c)) => format!(":{l}:{c}"),
        (Some(l), None) => format!(":{l}"),
        _ => String::new(),
    }
}

impl IoError {
    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            Self::Io { path, .. }
            | Self::MissingDirectory { path, .. }
            | Self::UnsupportedExtension { path, .. }
            | Self::Parse { path, .. }
            | Self::InvalidData { path, .. }
            | Self::Geometry { path, .. }
            | Self::Config { path, .. }
            | Self::Referenced { path, .. }
            | Self::Serialize { path, .. }
            | Self::ParserPanic { path, .. } => path,
        }
    }

    /// [`IoError::Io`] about `path`.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// [`IoError::Parse`] about `path`, at `line` when known.
    pub fn parse(path: &std::path::Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Self::Parse {
            path: path.to_path_buf(),
            line,
            column: None,
            message: message.into(),
        }
    }

    /// [`IoError::InvalidData`]: `item` in `path` is wrong as `message` says.
    pub fn invalid(
        path: &std::path::Path,
        item: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self::InvalidData {
            path: path.to_path_buf(),
            item: item.into(),
            message: message.into(),
        }
    }

    pub(crate) fn geometry(path: &std::path::Path, source: GeomError) -> Self {
        Self::Geometry {
            path: path.to_path_buf(),
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_path_and_location() {
        let e = IoError::Parse {
            path: "a/b.obj".into(),
            line: Some(7),
            column: Some(3),
            message: "bad number".into(),
        };
        assert_eq!(e.to_string(), "a/b.obj:7:3: bad number");
        assert_eq!(e.path(), std::path::Path::new("a/b.obj"));
        let e = IoError::invalid(
            std::path::Path::new("c.csv"),
            "row 2, column 1",
            "not finite",
        );
        assert_eq!(e.to_string(), "c.csv: row 2, column 1: not finite");
    }
}
