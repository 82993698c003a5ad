//! Atomic file replacement: write a temporary sibling, flush it to disk, rename it over the
//! target.
//!
//! A rename within one directory is atomic on POSIX file systems and on NTFS, so a reader sees
//! either the old file or the complete new one — never a prefix. The data are synced before the
//! rename and the directory after it, so a crash leaves the old or the new file, not an empty
//! one. If anything fails the
//! temporary file is removed, so a failed write leaves nothing behind.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::IoError;

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically.
///
/// The parent directory must exist (it is not created).
///
/// # Errors
/// [`IoError::MissingDirectory`] when the parent directory does not exist, [`IoError::Io`]
/// for any failure to create, write, flush or rename (the temporary file is then removed).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let tmp = temp_sibling(path)?;
    let result = write_and_sync(&tmp, bytes).and_then(|()| fs::rename(&tmp, path));
    match result {
        Ok(()) => {
            sync_dir(parent_dir(path));
            Ok(())
        }
        Err(source) => {
            // Best effort: the temporary may not exist if creating it failed.
            let _ = fs::remove_file(&tmp);
            Err(IoError::io(path, source))
        }
    }
}

/// A file being written in place of `path`: the bytes go to a hidden temporary sibling, and
/// [`AtomicFile::commit`] flushes, syncs and renames it over `path`. Dropped without a commit
/// (an error, a panic), it removes the temporary file, so nothing appears under `path`.
#[derive(Debug)]
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    file: Option<std::io::BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing a replacement for `path`.
    ///
    /// # Errors
    /// [`IoError::MissingDirectory`] or [`IoError::Io`].
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let tmp = temp_sibling(path)?;
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| IoError::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            file: Some(std::io::BufWriter::new(file)),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and renames the temporary file over the final path.
    ///
    /// # Errors
    /// [`IoError::Io`]; the temporary file is then removed.
    pub fn commit(mut self) -> Result<(), IoError> {
        let Some(writer) = self.file.take() else {
            return Ok(());
        };
        let result = writer
            .into_inner()
            .map_err(|e| e.into_error())
            .and_then(|f| f.sync_all())
            .and_then(|()| fs::rename(&self.tmp, &self.path));
        match result {
            Ok(()) => {
                sync_dir(parent_dir(&self.path));
                Ok(())
            }
            Err(source) => {
                let _ = fs::remove_file(&self.tmp);
                Err(IoError::io(&self.path, source))
            }
        }
    }

    fn writer(&mut self) -> std::io::Result<&mut std::io::BufWriter<File>> {
        self.file
            .as_mut()
            .ok_or_else(|| std::io::Error::other("file already committed"))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.writer()?.flush()
    }
}

impl std::io::Seek for AtomicFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.writer()?.seek(pos)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// The directory a file lives in (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A fresh, hidden temporary name next to `path`, after checking the directory exists.
fn temp_sibling(path: &Path) -> Result<PathBuf, IoError> {
    let dir = parent_dir(path);
    if !dir.is_dir() {
        return Err(IoError::MissingDirectory {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
        });
    }
    let Some(name) = path.file_name() else {
        return Err(IoError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "path has no file name"),
        ));
    };
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}-{n}", std::process::id()));
    Ok(dir.join(tmp_name))
}

/// Flushes the directory entry of the rename to disk (best effort: not every platform or file
/// system can open a directory for syncing, and the data itself is already synced).
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

fn write_and_sync(tmp: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut f: File = OpenOptions::new().write(true).create_new(true).open(tmp)?;
    f.write_all(bytes)?;
    f.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("moe-io-atomic-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_and_replaces_leaving_only_the_target() {
        let dir = scratch("replace");
        let p = dir.join("out.txt");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second, longer").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second, longer");
        assert_eq!(entries(&dir), vec!["out.txt".to_string()]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn missing_directory_is_reported_and_nothing_is_created() {
        let dir = scratch("missing");
        let p = dir.join("no-such-dir").join("out.txt");
        let err = write_atomic(&p, b"x").unwrap_err();
        assert!(matches!(err, IoError::MissingDirectory { .. }), "{err}");
        assert!(err.to_string().contains("no-such-dir"), "{err}");
        assert!(entries(&dir).is_empty());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_rename_removes_the_temporary() {
        // Renaming a file over a non-empty directory fails: the target name is taken.
        let dir = scratch("rename");
        let target = dir.join("taken");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("keep"), b"k").unwrap();
        let err = write_atomic(&target, b"data").unwrap_err();
        assert!(matches!(err, IoError::Io { .. }), "{err}");
        assert_eq!(entries(&dir), vec!["taken".to_string()]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn streamed_atomic_files_appear_only_on_commit() {
        let dir = std::env::temp_dir().join(format!("moe-atomic-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.bin");
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"hello").unwrap();
        assert!(!path.exists());
        f.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"hello");
        let mut g = AtomicFile::create(&dir.join("b.bin")).unwrap();
        g.write_all(b"partial").unwrap();
        drop(g);
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(
            names,
            vec![std::ffi::OsString::from("a.bin")],
            "nothing left of the dropped file"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
