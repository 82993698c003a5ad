//! The `KNN[All]` baseline's index: read from a file, or built from a data set's frames (and
//! kept in a file so that the next evaluation does not rebuild it).

use std::path::Path;

use moe_contact::KnnIndex;
use moe_io::{DatasetReader, Split, SplitFractions};

use crate::error::LabError;

/// Where [`knn_index`] found its index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KnnIndexSource {
    /// Read from the file given.
    Read,
    /// Built from the data set's training frames (no file given).
    Built,
    /// Built from the data set's training frames and written to the file given.
    BuiltAndWritten,
}

/// The index file at `path`, checked against a hand with `vertices_per_finger`.
///
/// # Errors
/// An unreadable or malformed file, or an index of a hand with other vertex counts.
pub fn read_knn_index(path: &Path, vertices_per_finger: &[usize]) -> Result<KnnIndex, LabError> {
    let bytes = moe_io::read_bytes(path)?;
    let index = KnnIndex::from_bytes(&bytes).map_err(|e| LabError::InvalidEvaluation {
        reason: format!("KNN index {}: {e}", path.display()),
    })?;
    if index.vertices_per_finger() != vertices_per_finger {
        return Err(LabError::InvalidEvaluation {
            reason: format!(
                "KNN index {} is of a hand with {:?} vertices per finger, the evaluated hand's \
                 has {vertices_per_finger:?}",
                path.display(),
                index.vertices_per_finger(),
            ),
        });
    }
    Ok(index)
}

/// The one builder of a `KNN[All]` index: every frame of `split` of the data set (all frames
/// for `None`), with their shapes when `keep_shapes` (the KNN rows of the shape table need them).
///
/// # Errors
/// An unreadable data set, no frames in `split`, or frames that do not fit together.
pub fn build_knn_index(
    reader: &DatasetReader,
    split: Option<Split>,
    keep_shapes: bool,
) -> Result<KnnIndex, LabError> {
    let frames = reader
        .labelled_frames(split, SplitFractions::default())
        .collect::<Result<Vec<_>, _>>()?;
    if frames.is_empty() {
        return Err(LabError::InvalidEvaluation {
            reason: format!(
                "no {}frames for the KNN index",
                if split == Some(Split::Train) {
                    "training "
                } else {
                    ""
                }
            ),
        });
    }
    Ok(KnnIndex::new(&frames, keep_shapes)?)
}

/// `eval contact`'s `KNN[All]` index of a data set: read from `path` when that file exists
/// (checked against the data set's hand), otherwise built from the data set's training frames
/// with their shapes and, when `path` is given, written there.
///
/// # Errors
/// As [`read_knn_index`] and [`build_knn_index`], or the file cannot be written.
pub fn knn_index(
    reader: &DatasetReader,
    path: Option<&Path>,
) -> Result<(KnnIndex, KnnIndexSource), LabError> {
    if let Some(path) = path
        && path.exists()
    {
        let counts = &reader.card().layout.finger_num_vertices;
        return Ok((read_knn_index(path, counts)?, KnnIndexSource::Read));
    }
    let index = build_knn_index(reader, Some(Split::Train), true)?;
    let Some(path) = path else {
        return Ok((index, KnnIndexSource::Built));
    };
    moe_io::write_atomic(path, &index.to_bytes()?)?;
    Ok((index, KnnIndexSource::BuiltAndWritten))
}
