//! Writing episodes.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use super::foxglove::{add_channel, format_err, mcap_err, mcap_writer, write_info, write_message};
use super::topic::{INFO_TOPIC, Topic};
use super::{EpisodeFrame, EpisodeInfo, check_frame, check_info};
use moe_io::AtomicFile;
use moe_io::IoError;

/// Writes an episode to any seekable sink.
pub struct EpisodeWriter<W: Write + Seek> {
    path: PathBuf,
    writer: mcap::Writer<W>,
    channels: [u16; Topic::ALL.len()],
    info: EpisodeInfo,
    sequence: u32,
    last_time_ns: Option<u64>,
}

impl<W: Write + Seek> std::fmt::Debug for EpisodeWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EpisodeWriter")
            .field("scene", &self.info.scene)
            .field("messages", &self.sequence)
            .finish()
    }
}

impl<W: Write + Seek> EpisodeWriter<W> {
    /// Starts an episode: writes the header, the schemas, the channels and the episode info.
    ///
    /// # Errors
    /// Inconsistent info (finger lists of different lengths, a face id beyond the vertex count),
    /// or a write failure.
    /// `path` names the destination in errors (use [`moe_io::MEMORY`] for an in-memory sink).
    pub fn new(sink: W, info: &EpisodeInfo, path: &Path) -> Result<Self, IoError> {
        check_info(path, info)?;
        let mut writer = mcap_writer(sink, path, "")?;
        write_info(&mut writer, path, INFO_TOPIC, "moe.EpisodeInfo", info)?;
        let mut channels = [0u16; Topic::ALL.len()];
        for (slot, topic) in channels.iter_mut().zip(Topic::ALL) {
            let (schema, encoding) = topic.schema();
            *slot = add_channel(&mut writer, path, topic.name(), schema, encoding)?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            channels,
            info: info.clone(),
            sequence: 1,
            last_time_ns: None,
        })
    }

    /// Appends one frame.
    ///
    /// # Errors
    /// A frame that does not fit the episode info (image size, finger count, vertex counts,
    /// contact ids), non-finite numbers, time going backwards, or a write failure.
    pub fn write_frame(&mut self, frame: &EpisodeFrame) -> Result<(), IoError> {
        let path = self.path.as_path();
        check_frame(path, &self.info, frame)?;
        if self.last_time_ns.is_some_and(|t| frame.time_ns < t) {
            return Err(format_err(
                path,
                format!("frame time {} ns goes backwards", frame.time_ns),
            ));
        }
        self.last_time_ns = Some(frame.time_ns);
        for (channel, topic) in self.channels.iter().zip(Topic::ALL) {
            let data = topic.encode(path, &self.info, frame)?;
            write_message(
                &mut self.writer,
                path,
                *channel,
                &mut self.sequence,
                frame.time_ns,
                &data,
            )?;
        }
        // Close the frame's chunk: everything up to here survives a cut.
        self.writer.flush().map_err(|e| mcap_err(path, e))
    }

    /// Writes the summary and returns the sink.
    ///
    /// # Errors
    /// A write failure.
    pub fn finish(mut self) -> Result<W, IoError> {
        let path = self.path.as_path();
        self.writer.finish().map_err(|e| mcap_err(path, e))?;
        Ok(self.writer.into_inner())
    }
}

/// Starts an episode file at `path`, streamed to a temporary sibling; [`EpisodeWriter::commit`]
/// moves it into place, and dropping the writer without committing leaves nothing at `path`.
///
/// # Errors
/// As [`EpisodeWriter::new`], and file-system errors.
pub fn create_episode(
    path: &Path,
    info: &EpisodeInfo,
) -> Result<EpisodeWriter<AtomicFile>, IoError> {
    EpisodeWriter::new(AtomicFile::create(path)?, info, path)
}

impl EpisodeWriter<AtomicFile> {
    /// Finishes the episode and moves the file into place.
    ///
    /// # Errors
    /// A write failure; nothing is left at the path.
    pub fn commit(self) -> Result<(), IoError> {
        self.finish()?.commit()
    }
}

/// Writes a whole episode to `path` atomically (temporary file, then rename).
///
/// # Errors
/// As [`EpisodeWriter::new`] and [`EpisodeWriter::write_frame`], and file-system errors; on any
/// error nothing is left at `path`.
pub fn write_episode(
    path: &Path,
    info: &EpisodeInfo,
    frames: &[EpisodeFrame],
) -> Result<(), IoError> {
    let mut writer = EpisodeWriter::new(std::io::Cursor::new(Vec::new()), info, path)?;
    for frame in frames {
        writer.write_frame(frame)?;
    }
    let bytes = writer.finish()?.into_inner();
    moe_io::write_atomic(path, &bytes)
}
