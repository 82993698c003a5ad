//! Contact model files: `NAME.safetensors` and, beside it, the card `NAME.json`.
//!
//! Only bytes and text cross this seam: the contact crate parses the weights and the card, so
//! this crate needs no tensor library.

use std::path::{Path, PathBuf};

use crate::atomic::write_atomic;
use crate::error::IoError;
use crate::files::{read_bytes, utf8_text};

/// Largest model file read (bytes): far above the paper's network (2.7 MB), far below what
/// would exhaust memory on a mistaken path.
pub const MAX_MODEL_BYTES: u64 = 1 << 30;

/// The card path of a weights path: `NAME.safetensors` → `NAME.json`.
pub fn card_path(weights: &Path) -> PathBuf {
    weights.with_extension("json")
}

/// A model file read from disk: the weights' bytes and, when a card lies beside them, its text.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelFiles {
    /// Contents of `NAME.safetensors`.
    pub weights: Vec<u8>,
    /// Contents of `NAME.json`, if that file exists.
    pub card: Option<String>,
    /// Where the card was looked for.
    pub card_path: PathBuf,
}

/// Reads `NAME.safetensors` and the card `NAME.json` beside it, if there is one.
///
/// # Errors
/// [`IoError::Io`] for a missing or unreadable weights file, [`IoError::InvalidData`] for a
/// weights path that does not end in `.safetensors` or a file above [`MAX_MODEL_BYTES`],
/// [`IoError::Parse`] for a card that is not UTF-8.
pub fn read_model_files(weights: &Path) -> Result<ModelFiles, IoError> {
    if weights.extension().and_then(|e| e.to_str()) != Some("safetensors") {
        return Err(IoError::invalid(
            weights,
            "model path",
            "a model file is NAME.safetensors (with its card NAME.json beside it)",
        ));
    }
    let size = std::fs::metadata(weights)
        .map_err(|e| IoError::io(weights, e))?
        .len();
    if size > MAX_MODEL_BYTES {
        return Err(IoError::invalid(
            weights,
            "file size",
            format!("{size} bytes is above the limit of {MAX_MODEL_BYTES}"),
        ));
    }
    let bytes = read_bytes(weights)?;
    let card_path = card_path(weights);
    let card = if card_path.exists() {
        let raw = read_bytes(&card_path)?;
        Some(utf8_text(&raw, &card_path)?.to_owned())
    } else {
        None
    };
    Ok(ModelFiles {
        weights: bytes,
        card,
        card_path,
    })
}

/// Writes `NAME.safetensors` and, if given, the card `NAME.json`, each atomically.
///
/// # Errors
/// As [`write_atomic`], and [`IoError::InvalidData`] for a path that does not end in
/// `.safetensors`.
pub fn write_model_files(weights: &Path, bytes: &[u8], card: Option<&str>) -> Result<(), IoError> {
    if weights.extension().and_then(|e| e.to_str()) != Some("safetensors") {
        return Err(IoError::invalid(
            weights,
            "model path",
            "a model file is NAME.safetensors",
        ));
    }
    write_atomic(weights, bytes)?;
    if let Some(card) = card {
        write_atomic(&card_path(weights), card.as_bytes())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_and_card_round_trip() {
        let dir = std::env::temp_dir().join(format!("moe-io-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.safetensors");
        write_model_files(&path, b"weights", Some("{\"card\": 1}")).unwrap();
        let files = read_model_files(&path).unwrap();
        assert_eq!(files.weights, b"weights");
        assert_eq!(files.card.as_deref(), Some("{\"card\": 1}"));
        std::fs::remove_file(dir.join("m.json")).unwrap();
        assert_eq!(read_model_files(&path).unwrap().card, None);
        assert!(matches!(
            read_model_files(&dir.join("m.bin")),
            Err(IoError::InvalidData { .. })
        ));
        assert!(matches!(
            read_model_files(&dir.join("missing.safetensors")),
            Err(IoError::Io { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
