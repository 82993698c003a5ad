//! Reading episodes: every complete frame up to the first damage, with the declared lengths
//! checked before the MCAP reader sees them.

use std::path::Path;

use super::foxglove::{format_err, mcap_err};
use super::topic::{FrameParts, INFO_TOPIC, Topic};
use super::{Episode, EpisodeFrame, EpisodeInfo, MAX_CHUNK_BYTES, check_frame, check_info};
use moe_io::IoError;

/// Walks the file's records before the MCAP reader sees them, so that no declared length can
/// make it allocate without bound (it reserves what a record or a chunk declares): every
/// top-level record must fit in the bytes that follow it; a chunk may not declare more than
/// [`MAX_CHUNK_BYTES`] uncompressed, its compressed records are decompressed here into at most
/// the declared size (which they must fill exactly), and every record inside must fit in the
/// chunk. A top-level record that runs past the end of the file is truncation: the bytes the
/// reader gets end before it, and it reports the frames before the cut. Returns how many bytes
/// to read. (Decompressing twice costs about a millisecond per 640 × 480 frame.)
pub(crate) fn check_declared_lengths(path: &Path, bytes: &[u8]) -> Result<usize, IoError> {
    const CHUNK: u8 = 0x06;
    let magic = mcap::MAGIC.len();
    if bytes.len() < magic {
        return Ok(bytes.len());
    }
    let mut at = magic;
    while bytes.len() - at >= 9 {
        let opcode = bytes[at];
        let len = read_u64(bytes, at + 1);
        let body = at + 9;
        let remaining = (bytes.len() - body) as u64;
        if len > remaining {
            return Ok(at);
        }
        if opcode == CHUNK {
            check_chunk(path, at, &bytes[body..body + len as usize])?;
        }
        at = body + len as usize;
    }
    Ok(bytes.len())
}

fn read_u64(b: &[u8], at: usize) -> u64 {
    b.get(at..at + 8)
        .and_then(|s| s.try_into().ok())
        .map_or(u64::MAX, u64::from_le_bytes)
}

/// Checks one chunk record's body (see [`check_declared_lengths`]); `at` is its file offset.
fn check_chunk(path: &Path, at: usize, body: &[u8]) -> Result<(), IoError> {
    let bad = |what: String| format_err(path, format!("the chunk at byte {at} {what}"));
    if body.len() < 32 {
        return Err(bad("is too short for a chunk header".into()));
    }
    let uncompressed = read_u64(body, 16);
    if uncompressed > MAX_CHUNK_BYTES {
        return Err(bad(format!(
            "declares {uncompressed} bytes uncompressed, more than {MAX_CHUNK_BYTES}"
        )));
    }
    let name_len = u32::from_le_bytes([body[28], body[29], body[30], body[31]]) as usize;
    let Some(name) = body.get(32..32 + name_len) else {
        return Err(bad("declares a compression name past its end".into()));
    };
    let records_len = read_u64(body, 32 + name_len);
    let start = 40 + name_len;
    if records_len != (body.len() as u64).saturating_sub(start as u64) || start > body.len() {
        return Err(bad(format!(
            "declares {records_len} bytes of records in a body of {}",
            body.len()
        )));
    }
    let compressed = &body[start..];
    let records = match name {
        b"" => std::borrow::Cow::Borrowed(compressed),
        b"zstd" => std::borrow::Cow::Owned(
            zstd::bulk::decompress(compressed, uncompressed as usize)
                .map_err(|e| bad(format!("does not decompress: {e}")))?,
        ),
        other => {
            return Err(bad(format!(
                "uses compression '{}', which episodes do not use",
                String::from_utf8_lossy(other)
            )));
        }
    };
    if records.len() as u64 != uncompressed {
        return Err(bad(format!(
            "declares {uncompressed} bytes uncompressed and holds {}",
            records.len()
        )));
    }
    let mut k = 0usize;
    while k < records.len() {
        let len = read_u64(&records, k + 1);
        let left = (records.len() - k).saturating_sub(9) as u64;
        if records.len() - k < 9 || len > left {
            return Err(bad(format!(
                "holds a record at offset {k} declaring {len} bytes, {left} left"
            )));
        }
        k += 9 + len as usize;
    }
    Ok(())
}

/// Reads a complete episode file.
///
/// # Errors
/// A file that cannot be read, is not MCAP, lacks the episode info, is cut short, or holds
/// messages that do not decode or do not fit the episode info.
pub fn read_episode(path: &Path) -> Result<Episode, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    parse_episode(path, &bytes)
}

/// Reads an episode file that may be cut short (a crashed recorder, a partial copy): every frame
/// written completely before the cut, and the error at the cut when there is one.
///
/// # Errors
/// A file that cannot be read, or that yields no episode at all (not MCAP, no episode info):
/// the error that stopped the reading.
pub fn read_episode_prefix(path: &Path) -> Result<(Episode, Option<IoError>), IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    match parse_episode_prefix(path, &bytes) {
        (Some(episode), cut) => Ok((episode, cut)),
        (None, Some(err)) => Err(err),
        (None, None) => Err(IoError::invalid(path, "episode", "holds no episode")),
    }
}

/// Parses a complete episode from memory (`path` names the source in errors).
///
/// # Errors
/// As [`read_episode`].
pub fn parse_episode(path: &Path, bytes: &[u8]) -> Result<Episode, IoError> {
    match parse_episode_prefix(path, bytes) {
        (Some(episode), None) => Ok(episode),
        (_, Some(err)) => Err(err),
        (None, None) => Err(format_err(path, "the file holds no episode info")),
    }
}

/// Reads every complete frame up to the first damage. Returns the episode read so far (`None`
/// when not even the episode info could be read) and the error that stopped the reading, if any.
pub fn parse_episode_prefix(path: &Path, bytes: &[u8]) -> (Option<Episode>, Option<IoError>) {
    let readable = match check_declared_lengths(path, bytes) {
        Ok(n) => n,
        Err(e) => return (None, Some(e)),
    };
    let bytes = &bytes[..readable];
    // The MCAP and protobuf decoders are third-party parsers: a panic in them becomes an error.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse_prefix(path, bytes)))
        .unwrap_or_else(|_| {
            (
                None,
                Some(IoError::ParserPanic {
                    path: path.to_path_buf(),
                    parser: "mcap",
                }),
            )
        })
}

fn parse_prefix(path: &Path, bytes: &[u8]) -> (Option<Episode>, Option<IoError>) {
    let options = mcap::read::Options::IgnoreEndMagic.into();
    let stream = match mcap::MessageStream::new_with_options(bytes, options) {
        Ok(s) => s,
        Err(e) => return (None, Some(mcap_err(path, e))),
    };
    let mut info: Option<EpisodeInfo> = None;
    let mut frames = Vec::new();
    let mut pending: [Option<Vec<u8>>; Topic::ALL.len()] = Default::default();
    let mut pending_time: Option<u64> = None;
    let incomplete = |time: Option<u64>| {
        format_err(
            path,
            format!("frame at {} ns is incomplete", time.unwrap_or_default()),
        )
    };
    for message in stream {
        let message = match message {
            Ok(m) => m,
            Err(e) => {
                let err = format_err(
                    path,
                    format!(
                        "damaged or truncated after {} complete frames: {e}",
                        frames.len()
                    ),
                );
                return (info.map(|info| Episode { info, frames }), Some(err));
            }
        };
        let topic = message.channel.topic.as_str();
        if topic == INFO_TOPIC {
            match serde_json::from_slice::<EpisodeInfo>(&message.data) {
                Ok(i) => {
                    if let Err(e) = check_info(path, &i) {
                        return (None, Some(e));
                    }
                    info = Some(i);
                }
                Err(e) => return (None, Some(format_err(path, format!("{INFO_TOPIC}: {e}")))),
            }
            continue;
        }
        let Some(info_ref) = info.as_ref() else {
            return (
                None,
                Some(format_err(
                    path,
                    format!("message on {topic} before the episode info"),
                )),
            );
        };
        let Some(slot) = Topic::from_name(topic).map(|t| t as usize) else {
            continue; // Topics added by other tools are ignored.
        };
        if pending_time != Some(message.log_time) {
            if pending.iter().any(Option::is_some) {
                let err = incomplete(pending_time);
                return (info.map(|info| Episode { info, frames }), Some(err));
            }
            pending_time = Some(message.log_time);
        }
        pending[slot] = Some(message.data.into_owned());
        if pending.iter().all(Option::is_some) {
            let messages = std::mem::take(&mut pending);
            match decode_frame(path, info_ref, message.log_time, messages) {
                Ok(frame) => frames.push(frame),
                Err(e) => return (info.map(|info| Episode { info, frames }), Some(e)),
            }
        }
    }
    if pending.iter().any(Option::is_some) {
        let err = incomplete(pending_time);
        return (info.map(|info| Episode { info, frames }), Some(err));
    }
    if bytes.len() < 8 || bytes[bytes.len() - 8..] != mcap::MAGIC[..] {
        let err = format_err(
            path,
            format!("file is cut short after {} complete frames", frames.len()),
        );
        return (info.map(|info| Episode { info, frames }), Some(err));
    }
    (info.map(|info| Episode { info, frames }), None)
}

/// Puts a frame together from one message per topic (in [`Topic::ALL`]'s order) and checks it
/// against the episode info.
fn decode_frame(
    path: &Path,
    info: &EpisodeInfo,
    time_ns: u64,
    messages: [Option<Vec<u8>>; Topic::ALL.len()],
) -> Result<EpisodeFrame, IoError> {
    let mut parts = FrameParts::default();
    for (topic, data) in Topic::ALL.into_iter().zip(messages) {
        let data = data.ok_or_else(|| {
            format_err(
                path,
                format!("frame at {time_ns} ns lacks {}", topic.name()),
            )
        })?;
        topic.decode(path, info, &data, &mut parts)?;
    }
    let frame = parts
        .into_frame(time_ns)
        .ok_or_else(|| format_err(path, format!("frame at {time_ns} ns is incomplete")))?;
    check_frame(path, info, &frame)?;
    Ok(frame)
}
