//! Lazy reading of a data set directory: the card, then shards one at a time.

use std::borrow::Borrow;
use std::path::{Path, PathBuf};

use moe_geom::LabelledFrame;

use super::card::{CARD_FILE, DatasetCard};
use super::frame::DatasetFrame;
use super::shard::read_shard;
use super::split::{Split, SplitFractions, split_of};
use crate::error::IoError;

/// Reads a data set directory lazily: the card at once, shards one at a time while iterating.
#[derive(Debug, Clone)]
pub struct DatasetReader {
    dir: PathBuf,
    card: DatasetCard,
}

impl DatasetReader {
    /// Opens a data set directory by reading its card.
    ///
    /// # Errors
    /// A missing or malformed card.
    pub fn open(dir: &Path) -> Result<Self, IoError> {
        let card: DatasetCard = crate::config::read_json(&dir.join(CARD_FILE))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            card,
        })
    }

    /// The card.
    pub fn card(&self) -> &DatasetCard {
        &self.card
    }

    /// Number of shards the card lists.
    pub fn num_shards(&self) -> usize {
        self.card.shards.len()
    }

    /// Every frame of shard `index` (in card order), in the order stored.
    ///
    /// # Errors
    /// [`IoError::InvalidData`] for an index past the last shard or a shard whose layout differs
    /// from the card's; an unreadable or malformed shard.
    pub fn shard(&self, index: usize) -> Result<Vec<DatasetFrame>, IoError> {
        let entry = self.card.shards.get(index).ok_or_else(|| {
            IoError::invalid(
                &self.dir,
                "shard",
                format!(
                    "index {index} is past the last of {} shards",
                    self.card.shards.len()
                ),
            )
        })?;
        let path = self.dir.join(&entry.file);
        let (layout, frames) = read_shard(&path)?;
        if layout != self.card.layout {
            return Err(IoError::invalid(
                &path,
                "layout",
                "differs from the data set card",
            ));
        }
        Ok(frames)
    }

    /// Like [`DatasetReader::frames`], as the in-memory vocabulary ([`LabelledFrame`]: per-finger
    /// vertices, labels and markers, typed wrist pose).
    pub fn labelled_frames(
        &self,
        split: Option<Split>,
        fractions: SplitFractions,
    ) -> LabelledFrames<'_> {
        LabelledFrames {
            frames: self.frames(split, fractions),
        }
    }

    /// Frames of `split` (all frames for `None`), shard by shard in card order; each item is a
    /// frame or the error that stopped reading a shard.
    pub fn frames(
        &self,
        split: Option<Split>,
        fractions: SplitFractions,
    ) -> DatasetFrames<&DatasetReader> {
        DatasetFrames::new(self, split, fractions)
    }

    /// [`DatasetReader::frames`] that owns the reader (for an iterator that outlives it, as a
    /// binding's does).
    pub fn into_frames(
        self,
        split: Option<Split>,
        fractions: SplitFractions,
    ) -> DatasetFrames<DatasetReader> {
        DatasetFrames::new(self, split, fractions)
    }
}

/// Iterator over a data set's frames as [`LabelledFrame`]s; see
/// [`DatasetReader::labelled_frames`].
#[derive(Debug)]
pub struct LabelledFrames<'a> {
    frames: DatasetFrames<&'a DatasetReader>,
}

impl Iterator for LabelledFrames<'_> {
    type Item = Result<LabelledFrame, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let frame = match self.frames.next()? {
            Ok(frame) => frame,
            Err(e) => return Some(Err(e)),
        };
        let reader = self.frames.reader;
        Some(frame.to_labelled(&reader.card.layout).map_err(|e| {
            self.frames.failed = true;
            IoError::invalid(
                &reader.dir,
                format!(
                    "trajectory {}, frame {}",
                    frame.trajectory_id, frame.frame_index
                ),
                e.to_string(),
            )
        }))
    }
}

/// Iterator over a data set's frames; see [`DatasetReader::frames`] (borrowing the reader) and
/// [`DatasetReader::into_frames`] (owning it).
#[derive(Debug)]
pub struct DatasetFrames<R: Borrow<DatasetReader>> {
    reader: R,
    split: Option<Split>,
    fractions: SplitFractions,
    shard: usize,
    buffer: std::vec::IntoIter<DatasetFrame>,
    failed: bool,
}

impl<R: Borrow<DatasetReader>> DatasetFrames<R> {
    /// The frames of `split` in `reader`, from its first shard.
    fn new(reader: R, split: Option<Split>, fractions: SplitFractions) -> Self {
        Self {
            reader,
            split,
            fractions,
            shard: 0,
            buffer: Vec::new().into_iter(),
            failed: false,
        }
    }
}

impl<R: Borrow<DatasetReader>> Iterator for DatasetFrames<R> {
    type Item = Result<DatasetFrame, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let reader = self.reader.borrow();
        loop {
            if self.failed {
                return None;
            }
            if let Some(frame) = self.buffer.next() {
                let keep = self.split.is_none_or(|s| {
                    split_of(frame.trajectory_id, reader.card.seed, self.fractions) == s
                });
                if keep {
                    return Some(Ok(frame));
                }
                continue;
            }
            if self.shard >= reader.num_shards() {
                return None;
            }
            self.shard += 1;
            match reader.shard(self.shard - 1) {
                Ok(frames) => self.buffer = frames.into_iter(),
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
    }
}
