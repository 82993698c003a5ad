//! Recorded episodes in MCAP with Foxglove's message schemas, so that an episode opens in
//! Foxglove directly: the wrist camera's colour and depth images with their calibration, the
//! frame transforms, the ground-truth hand mesh coloured by contact, the ground-truth markers,
//! the tendon actuation and the obstacles.
//!
//! | topic | schema (encoding) | content |
//! |---|---|---|
//! | `/episode/info` | `moe.EpisodeInfo` (JSON) | once: scene name, camera, finger layout |
//! | `/camera/color` | `foxglove.RawImage` (protobuf) | `rgb8` |
//! | `/camera/depth` | `foxglove.RawImage` (protobuf) | `32FC1`, metres, 0 = no depth |
//! | `/camera/calibration` | `foxglove.CameraCalibration` (protobuf) | pinhole intrinsics |
//! | `/tf` | `foxglove.FrameTransforms` (protobuf) | `world→hand`, `hand→camera`, `hand→finger_i` |
//! | `/hand/tendons` | `foxglove.JointStates` (protobuf) | pulled length per tendon, metres |
//! | `/hand/mesh` | `foxglove.SceneUpdate` (protobuf) | ground-truth finger meshes, contact vertices red |
//! | `/hand/contacts` | `moe.ContactLabels` (JSON) | contact vertex ids per finger |
//! | `/hand/markers` | `foxglove.SceneUpdate` (protobuf) | ground-truth marker positions |
//! | `/obstacles` | `foxglove.SceneUpdate` (protobuf) | obstacle meshes in the world frame |
//!
//! Every frame writes one message per topic (except `/episode/info`) with the frame's time as
//! log time. Each frame is one zstd-compressed chunk (the episode info another), closed as soon
//! as the frame is written, so a file cut short — a crashed recorder, a partial copy — still
//! yields every frame written completely before the cut ([`parse_episode_prefix`]);
//! [`read_episode`] insists on a complete file. Reading is guarded: the file's records and
//! every chunk's contents are checked against their declared lengths before the MCAP reader
//! sees them (a corrupt length would otherwise make it reserve that much memory — the fuzz
//! tests found one in a damaged zstd chunk), and a panic in the MCAP or protobuf decoders
//! becomes [`IoError::ParserPanic`](crate::IoError::ParserPanic). Compression takes a 640 × 480 frame from about
//! 2.5 MB to 0.9 MB (the noisy depth image compresses least). Unchunked, uncompressed files (as
//! written by earlier versions) read the same way.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use foxglove::messages as fg;
use foxglove::{Decode, Encode};
use moe_geom::math::UnitQuat;
use moe_geom::nalgebra;
use moe_geom::{Iso3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::atomic::AtomicFile;
use crate::error::IoError;

/// Pinhole intrinsics of the recorded camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraInfo {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

/// What stays fixed over an episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EpisodeInfo {
    /// Name of the scene that produced the episode.
    pub scene: String,
    /// Wrist camera intrinsics.
    pub camera: CameraInfo,
    /// Camera mounting: camera frame to hand frame.
    pub hand_from_camera: Iso3,
    /// Each finger's base pose on the palm.
    pub hand_from_finger: Vec<Iso3>,
    /// Each finger's surface triangles (vertex ids into that finger's vertices).
    pub finger_faces: Vec<Vec<[u32; 3]>>,
    /// Each finger's vertex count.
    pub finger_num_vertices: Vec<usize>,
    /// Tendons per finger.
    pub tendons_per_finger: usize,
}

/// An obstacle's surface at one instant, in the world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ObstacleMesh {
    /// Identifier shown in Foxglove.
    pub name: String,
    /// Vertices in the world frame.
    pub vertices_in_world: Vec<Point3>,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
}

/// Everything recorded at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeFrame {
    /// Time since the start of the episode, nanoseconds.
    pub time_ns: u64,
    /// Colour image, RGB8 row-major.
    pub color_rgb8: Vec<u8>,
    /// Depth image, metres, row-major, 0 where there is no depth.
    pub depth_m: Vec<f32>,
    /// Where the hand is.
    pub world_from_hand: Iso3,
    /// Pulled length of every tendon, metres: `[finger][tendon]`.
    pub tendon_pull_m: Vec<Vec<f64>>,
    /// Ground-truth surface vertices of every finger, hand frame.
    pub finger_vertices_in_hand: Vec<Vec<Point3>>,
    /// Ground-truth contact vertex ids of every finger, sorted.
    pub contact_vertices: Vec<Vec<u32>>,
    /// Ground-truth marker centres of every finger, hand frame.
    pub markers_in_hand: Vec<Vec<Point3>>,
    /// Obstacles.
    pub obstacles: Vec<ObstacleMesh>,
}

/// A whole episode as read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Fixed information.
    pub info: EpisodeInfo,
    /// Frames in time order.
    pub frames: Vec<EpisodeFrame>,
}

const TOPICS: [&str; 9] = [
    "/camera/color",
    "/camera/depth",
    "/camera/calibration",
    "/tf",
    "/hand/tendons",
    "/hand/mesh",
    "/hand/contacts",
    "/hand/markers",
    "/obstacles",
];
const INFO_TOPIC: &str = "/episode/info";
const CONTACT_COLOR: [f64; 4] = [0.86, 0.1, 0.1, 1.0];
const FREE_COLOR: [f64; 4] = [0.75, 0.75, 0.72, 1.0];

/// JSON body of `/hand/contacts`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactLabels {
    fingers: Vec<Vec<u32>>,
}

pub(crate) fn format_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::parse(path, None, message)
}

pub(crate) fn mcap_err(path: &Path, e: mcap::McapError) -> IoError {
    IoError::parse(path, None, format!("MCAP: {e}"))
}

/// Writes an episode to any seekable sink.
pub struct EpisodeWriter<W: Write + Seek> {
    path: PathBuf,
    writer: mcap::Writer<W>,
    channels: [u16; 9],
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

pub(crate) fn schema_of<T: Encode>() -> (String, String, Vec<u8>) {
    let s = T::get_schema().expect("Foxglove messages carry their schema");
    (s.name, s.encoding, s.data.into_owned())
}

impl<W: Write + Seek> EpisodeWriter<W> {
    /// Starts an episode: writes the header, the schemas, the channels and the episode info.
    ///
    /// # Errors
    /// Inconsistent info (finger lists of different lengths, a face id beyond the vertex count),
    /// or a write failure.
    /// `path` names the destination in errors (use [`crate::MEMORY`] for an in-memory sink).
    pub fn new(sink: W, info: &EpisodeInfo, path: &Path) -> Result<Self, IoError> {
        check_info(path, info)?;
        // One chunk per frame (closed by `flush` after each frame, so no size limit), compressed
        // on this thread: the output does not depend on the machine's core count.
        let options = mcap::WriteOptions::new()
            .profile("")
            .library("moe-touch")
            .compression(Some(mcap::Compression::Zstd))
            .compression_threads(0)
            .use_chunks(true)
            .chunk_size(None);
        let mut writer = options.create(sink).map_err(|e| mcap_err(path, e))?;
        let json_schema = br#"{"type":"object"}"#;
        let mut channel = |topic: &str,
                           (name, encoding, data): (String, String, Vec<u8>),
                           message_encoding: &str| {
            let schema = writer
                .add_schema(&name, &encoding, &data)
                .map_err(|e| mcap_err(path, e))?;
            writer
                .add_channel(schema, topic, message_encoding, &BTreeMap::new())
                .map_err(|e| mcap_err(path, e))
        };
        let json = |name: &str| {
            (
                name.to_owned(),
                "jsonschema".to_owned(),
                json_schema.to_vec(),
            )
        };
        let info_channel = channel(INFO_TOPIC, json("moe.EpisodeInfo"), "json")?;
        let channels = [
            channel(TOPICS[0], schema_of::<fg::RawImage>(), "protobuf")?,
            channel(TOPICS[1], schema_of::<fg::RawImage>(), "protobuf")?,
            channel(TOPICS[2], schema_of::<fg::CameraCalibration>(), "protobuf")?,
            channel(TOPICS[3], schema_of::<fg::FrameTransforms>(), "protobuf")?,
            channel(TOPICS[4], schema_of::<fg::JointStates>(), "protobuf")?,
            channel(TOPICS[5], schema_of::<fg::SceneUpdate>(), "protobuf")?,
            channel(TOPICS[6], json("moe.ContactLabels"), "json")?,
            channel(TOPICS[7], schema_of::<fg::SceneUpdate>(), "protobuf")?,
            channel(TOPICS[8], schema_of::<fg::SceneUpdate>(), "protobuf")?,
        ];
        let body = serde_json::to_vec(info).map_err(|e| format_err(path, e.to_string()))?;
        let header = mcap::records::MessageHeader {
            channel_id: info_channel,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        writer
            .write_to_known_channel(&header, &body)
            .map_err(|e| mcap_err(path, e))?;
        writer.flush().map_err(|e| mcap_err(path, e))?;
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
        let messages = encode_frame(path, &self.info, frame)?;
        for (channel, data) in self.channels.iter().zip(messages) {
            let header = mcap::records::MessageHeader {
                channel_id: *channel,
                sequence: self.sequence,
                log_time: frame.time_ns,
                publish_time: frame.time_ns,
            };
            self.writer
                .write_to_known_channel(&header, &data)
                .map_err(|e| mcap_err(path, e))?;
            self.sequence += 1;
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

fn check_info(path: &Path, info: &EpisodeInfo) -> Result<(), IoError> {
    let n = info.hand_from_finger.len();
    if info.finger_faces.len() != n || info.finger_num_vertices.len() != n {
        return Err(format_err(
            path,
            format!(
                "episode info lists {n} finger poses, {} face lists and {} vertex counts",
                info.finger_faces.len(),
                info.finger_num_vertices.len()
            ),
        ));
    }
    for (f, (faces, &nv)) in info
        .finger_faces
        .iter()
        .zip(&info.finger_num_vertices)
        .enumerate()
    {
        if let Some(bad) = faces.iter().flatten().find(|&&v| v as usize >= nv) {
            return Err(format_err(
                path,
                format!("finger {f}: face refers to vertex {bad}, but it has {nv}"),
            ));
        }
    }
    let c = &info.camera;
    if !(1..=MAX_IMAGE_SIDE).contains(&c.width) || !(1..=MAX_IMAGE_SIDE).contains(&c.height) {
        return Err(format_err(
            path,
            format!(
                "camera image size {} × {} is outside 1..={MAX_IMAGE_SIDE} pixels a side",
                c.width, c.height
            ),
        ));
    }
    if let Some((f, &nv)) = info
        .finger_num_vertices
        .iter()
        .enumerate()
        .find(|(_, n)| **n > MAX_FINGER_VERTICES)
    {
        return Err(format_err(
            path,
            format!("finger {f} declares {nv} vertices, more than {MAX_FINGER_VERTICES}"),
        ));
    }
    Ok(())
}

/// Largest image side an episode may declare, pixels.
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// Most vertices a finger of an episode may declare.
pub const MAX_FINGER_VERTICES: usize = 1 << 22;
/// Largest uncompressed size a chunk may declare, bytes (a 640 × 480 frame takes 2.5 MB).
pub const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// Walks the file's records before the MCAP reader sees them, so that no declared length can
/// make it allocate without bound (it reserves what a record or a chunk declares): every
/// top-level record must fit in the bytes that follow it; a chunk may not declare more than
/// [`MAX_CHUNK_BYTES`] uncompressed, its compressed records are decompressed here into at most
/// the declared size (which they must fill exactly), and every record inside must fit in the
/// chunk. A top-level record that runs past the end of the file is truncation: the bytes the
/// reader gets end before it, and it reports the frames before the cut. Returns how many bytes
/// to read. (Decompressing twice costs about a millisecond per 640 × 480 frame.)
fn check_declared_lengths(path: &Path, bytes: &[u8]) -> Result<usize, IoError> {
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

fn check_frame(path: &Path, info: &EpisodeInfo, frame: &EpisodeFrame) -> Result<(), IoError> {
    let pixels = info.camera.width as usize * info.camera.height as usize;
    if frame.color_rgb8.len() != 3 * pixels || frame.depth_m.len() != pixels {
        return Err(format_err(
            path,
            format!(
                "frame at {} ns: images hold {} colour bytes and {} depths, the camera has {pixels} pixels",
                frame.time_ns,
                frame.color_rgb8.len(),
                frame.depth_m.len()
            ),
        ));
    }
    let n = info.hand_from_finger.len();
    for (what, len) in [
        ("tendon lists", frame.tendon_pull_m.len()),
        ("vertex lists", frame.finger_vertices_in_hand.len()),
        ("contact lists", frame.contact_vertices.len()),
        ("marker lists", frame.markers_in_hand.len()),
    ] {
        if len != n {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns has {len} {what} for {n} fingers",
                    frame.time_ns
                ),
            ));
        }
    }
    for f in 0..n {
        let nv = info.finger_num_vertices[f];
        if frame.finger_vertices_in_hand[f].len() != nv {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: finger {f} has {} vertices, expected {nv}",
                    frame.time_ns,
                    frame.finger_vertices_in_hand[f].len()
                ),
            ));
        }
        if frame.tendon_pull_m[f].len() != info.tendons_per_finger {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: finger {f} has {} tendons",
                    frame.time_ns,
                    frame.tendon_pull_m[f].len()
                ),
            ));
        }
        if let Some(bad) = frame.contact_vertices[f]
            .iter()
            .find(|&&v| v as usize >= nv)
        {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: finger {f} contact vertex {bad} out of range",
                    frame.time_ns
                ),
            ));
        }
        if !frame.contact_vertices[f].windows(2).all(|w| w[0] < w[1]) {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: finger {f} contact ids not sorted and distinct",
                    frame.time_ns
                ),
            ));
        }
        let finite = frame.finger_vertices_in_hand[f]
            .iter()
            .chain(&frame.markers_in_hand[f])
            .all(moe_geom::math::is_finite_point)
            && frame.tendon_pull_m[f].iter().all(|v| v.is_finite());
        if !finite {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: finger {f} has a non-finite value",
                    frame.time_ns
                ),
            ));
        }
    }
    if frame.depth_m.iter().any(|d| !d.is_finite()) {
        return Err(format_err(
            path,
            format!("frame at {} ns: non-finite depth", frame.time_ns),
        ));
    }
    for o in &frame.obstacles {
        let nv = o.vertices_in_world.len();
        if o.faces.iter().flatten().any(|&v| v as usize >= nv)
            || !o
                .vertices_in_world
                .iter()
                .all(moe_geom::math::is_finite_point)
        {
            return Err(format_err(
                path,
                format!(
                    "frame at {} ns: obstacle '{}' has a bad vertex or face",
                    frame.time_ns, o.name
                ),
            ));
        }
    }
    Ok(())
}

pub(crate) fn timestamp(time_ns: u64) -> Option<fg::Timestamp> {
    Some(fg::Timestamp::new(
        (time_ns / 1_000_000_000) as u32,
        (time_ns % 1_000_000_000) as u32,
    ))
}

fn fg_point(p: &Point3) -> fg::Point3 {
    fg::Point3 {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

pub(crate) fn fg_color(c: [f64; 4]) -> Option<fg::Color> {
    Some(fg::Color {
        r: c[0],
        g: c[1],
        b: c[2],
        a: c[3],
    })
}

pub(crate) fn fg_transform(
    time_ns: u64,
    parent: &str,
    child: &str,
    iso: &Iso3,
) -> fg::FrameTransform {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    fg::FrameTransform {
        timestamp: timestamp(time_ns),
        parent_frame_id: parent.to_owned(),
        child_frame_id: child.to_owned(),
        translation: Some(fg::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        rotation: Some(fg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn iso_from(path: &Path, t: &fg::FrameTransform) -> Result<Iso3, IoError> {
    let (Some(v), Some(q)) = (t.translation, t.rotation) else {
        return Err(format_err(
            path,
            format!(
                "transform {}→{} lacks translation or rotation",
                t.parent_frame_id, t.child_frame_id
            ),
        ));
    };
    let rotation = UnitQuat::new_unchecked(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
    Ok(Iso3::from_parts(
        Vector3::new(v.x, v.y, v.z).into(),
        rotation,
    ))
}

pub(crate) fn encode<T: Encode>(message: &T) -> Vec<u8> {
    let mut buf = Vec::new();
    message
        .encode(&mut buf)
        .expect("encoding into a Vec cannot fail");
    buf
}

/// The colour image of a frame as a Foxglove `RawImage` (`rgb8`, frame `camera`).
pub(crate) fn color_image(time_ns: u64, cam: &CameraInfo, rgb8: &[u8]) -> fg::RawImage {
    fg::RawImage {
        timestamp: timestamp(time_ns),
        frame_id: "camera".into(),
        width: cam.width,
        height: cam.height,
        encoding: "rgb8".into(),
        step: 3 * cam.width,
        data: rgb8.to_vec().into(),
    }
}

/// The pinhole calibration of the camera (no distortion).
pub(crate) fn camera_calibration(time_ns: u64, cam: &CameraInfo) -> fg::CameraCalibration {
    fg::CameraCalibration {
        timestamp: timestamp(time_ns),
        frame_id: "camera".into(),
        width: cam.width,
        height: cam.height,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: vec![cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0],
        r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: vec![
            cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
    }
}

/// Spheres of diameter `size_m` at `points` (in `frame_id`), one entity.
pub(crate) fn spheres_entity(
    time_ns: u64,
    frame_id: &str,
    id: String,
    points: &[Point3],
    size_m: f64,
    color: [f64; 4],
) -> fg::SceneEntity {
    fg::SceneEntity {
        timestamp: timestamp(time_ns),
        frame_id: frame_id.to_owned(),
        id,
        spheres: points
            .iter()
            .map(|m| fg::SpherePrimitive {
                pose: Some(fg::Pose {
                    position: Some(fg::Vector3 {
                        x: m.x,
                        y: m.y,
                        z: m.z,
                    }),
                    orientation: Some(fg::Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                        w: 1.0,
                    }),
                }),
                size: Some(fg::Vector3 {
                    x: size_m,
                    y: size_m,
                    z: size_m,
                }),
                color: fg_color(color),
            })
            .collect(),
        ..Default::default()
    }
}

pub(crate) fn mesh_entity(
    time_ns: u64,
    frame_id: &str,
    id: String,
    vertices: &[Point3],
    faces: &[[u32; 3]],
    colors: Option<Vec<fg::Color>>,
) -> fg::SceneEntity {
    let triangle = fg::TriangleListPrimitive {
        pose: Some(fg::Pose {
            position: Some(fg::Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.0,
            }),
            orientation: Some(fg::Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            }),
        }),
        points: vertices.iter().map(fg_point).collect(),
        color: fg_color(FREE_COLOR),
        colors: colors.unwrap_or_default(),
        indices: faces.iter().flatten().copied().collect(),
    };
    fg::SceneEntity {
        timestamp: timestamp(time_ns),
        frame_id: frame_id.to_owned(),
        id,
        triangles: vec![triangle],
        ..Default::default()
    }
}

fn encode_frame(
    path: &Path,
    info: &EpisodeInfo,
    frame: &EpisodeFrame,
) -> Result<Vec<Vec<u8>>, IoError> {
    let t = frame.time_ns;
    let cam = &info.camera;
    let color = color_image(t, cam, &frame.color_rgb8);
    let depth = fg::RawImage {
        timestamp: timestamp(t),
        frame_id: "camera".into(),
        width: cam.width,
        height: cam.height,
        encoding: "32FC1".into(),
        step: 4 * cam.width,
        data: frame
            .depth_m
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect::<Vec<u8>>()
            .into(),
    };
    let calibration = camera_calibration(t, cam);
    let mut transforms = vec![
        fg_transform(t, "world", "hand", &frame.world_from_hand),
        fg_transform(t, "hand", "camera", &info.hand_from_camera),
    ];
    for (i, iso) in info.hand_from_finger.iter().enumerate() {
        transforms.push(fg_transform(t, "hand", &format!("finger_{i}"), iso));
    }
    let tf = fg::FrameTransforms { transforms };
    let tendons = fg::JointStates {
        timestamp: timestamp(t),
        joints: frame
            .tendon_pull_m
            .iter()
            .enumerate()
            .flat_map(|(f, pulls)| {
                pulls.iter().enumerate().map(move |(k, &p)| fg::JointState {
                    name: format!("finger_{f}/tendon_{k}"),
                    position: Some(p),
                    ..Default::default()
                })
            })
            .collect(),
    };
    let mut hand_entities = Vec::with_capacity(info.finger_faces.len());
    for (f, faces) in info.finger_faces.iter().enumerate() {
        let mut colors = vec![fg_color(FREE_COLOR).expect("some"); info.finger_num_vertices[f]];
        for &v in &frame.contact_vertices[f] {
            colors[v as usize] = fg_color(CONTACT_COLOR).expect("some");
        }
        hand_entities.push(mesh_entity(
            t,
            "hand",
            format!("finger_{f}"),
            &frame.finger_vertices_in_hand[f],
            faces,
            Some(colors),
        ));
    }
    let hand = fg::SceneUpdate {
        deletions: vec![],
        entities: hand_entities,
    };
    let contacts = serde_json::to_vec(&ContactLabels {
        fingers: frame.contact_vertices.clone(),
    })
    .map_err(|e| format_err(path, e.to_string()))?;
    let markers = fg::SceneUpdate {
        deletions: vec![],
        entities: frame
            .markers_in_hand
            .iter()
            .enumerate()
            .map(|(f, ms)| {
                spheres_entity(
                    t,
                    "hand",
                    format!("markers_{f}"),
                    ms,
                    0.005,
                    [1.0, 0.0, 0.0, 1.0],
                )
            })
            .collect(),
    };
    let obstacles = fg::SceneUpdate {
        deletions: vec![],
        entities: frame
            .obstacles
            .iter()
            .map(|o| {
                mesh_entity(
                    t,
                    "world",
                    o.name.clone(),
                    &o.vertices_in_world,
                    &o.faces,
                    None,
                )
            })
            .collect(),
    };
    Ok(vec![
        encode(&color),
        encode(&depth),
        encode(&calibration),
        encode(&tf),
        encode(&tendons),
        encode(&hand),
        contacts,
        encode(&markers),
        encode(&obstacles),
    ])
}

fn decode<T: Decode>(path: &Path, topic: &str, data: &[u8]) -> Result<T, IoError> {
    T::decode(data).map_err(|e| format_err(path, format!("{topic}: cannot decode: {e}")))
}

fn points_of(tri: &fg::TriangleListPrimitive) -> Vec<Point3> {
    tri.points
        .iter()
        .map(|p| Point3::new(p.x, p.y, p.z))
        .collect()
}

fn faces_of(
    path: &Path,
    topic: &str,
    tri: &fg::TriangleListPrimitive,
) -> Result<Vec<[u32; 3]>, IoError> {
    if !tri.indices.len().is_multiple_of(3) {
        return Err(format_err(
            path,
            format!(
                "{topic}: triangle index count {} is not a multiple of 3",
                tri.indices.len()
            ),
        ));
    }
    Ok(tri.indices.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn first_triangles<'a>(
    path: &Path,
    topic: &str,
    e: &'a fg::SceneEntity,
) -> Result<&'a fg::TriangleListPrimitive, IoError> {
    e.triangles
        .first()
        .ok_or_else(|| format_err(path, format!("{topic}: entity '{}' has no triangles", e.id)))
}

fn decode_frame(
    path: &Path,
    info: &EpisodeInfo,
    time_ns: u64,
    parts: &[Vec<u8>],
) -> Result<EpisodeFrame, IoError> {
    let color: fg::RawImage = decode(path, TOPICS[0], &parts[0])?;
    let depth: fg::RawImage = decode(path, TOPICS[1], &parts[1])?;
    if !depth.data.len().is_multiple_of(4) {
        return Err(format_err(
            path,
            "/camera/depth: data length is not a multiple of 4",
        ));
    }
    let depth_m = depth
        .data
        .chunks(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let tf: fg::FrameTransforms = decode(path, TOPICS[3], &parts[3])?;
    let world_from_hand = tf
        .transforms
        .iter()
        .find(|t| t.parent_frame_id == "world" && t.child_frame_id == "hand")
        .ok_or_else(|| format_err(path, "/tf: no world→hand transform"))
        .and_then(|t| iso_from(path, t))?;
    let n = info.hand_from_finger.len();
    let tendons: fg::JointStates = decode(path, TOPICS[4], &parts[4])?;
    let mut tendon_pull_m = vec![Vec::with_capacity(info.tendons_per_finger); n];
    for (k, joint) in tendons.joints.iter().enumerate() {
        let f = k / info.tendons_per_finger.max(1);
        let list = tendon_pull_m
            .get_mut(f)
            .ok_or_else(|| format_err(path, "/hand/tendons: more tendons than fingers hold"))?;
        list.push(joint.position.ok_or_else(|| {
            format_err(
                path,
                format!("/hand/tendons: {} has no position", joint.name),
            )
        })?);
    }
    let hand: fg::SceneUpdate = decode(path, TOPICS[5], &parts[5])?;
    let finger_vertices_in_hand = hand
        .entities
        .iter()
        .map(|e| first_triangles(path, TOPICS[5], e).map(points_of))
        .collect::<Result<Vec<_>, _>>()?;
    let contacts: ContactLabels = serde_json::from_slice(&parts[6])
        .map_err(|e| format_err(path, format!("/hand/contacts: {e}")))?;
    let markers: fg::SceneUpdate = decode(path, TOPICS[7], &parts[7])?;
    let markers_in_hand = markers
        .entities
        .iter()
        .map(|e| {
            e.spheres
                .iter()
                .map(|s| {
                    let p = s.pose.and_then(|p| p.position).ok_or_else(|| {
                        format_err(path, "/hand/markers: sphere without position")
                    })?;
                    Ok(Point3::new(p.x, p.y, p.z))
                })
                .collect::<Result<Vec<_>, IoError>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let obstacles_msg: fg::SceneUpdate = decode(path, TOPICS[8], &parts[8])?;
    let obstacles = obstacles_msg
        .entities
        .iter()
        .map(|e| {
            let tri = first_triangles(path, TOPICS[8], e)?;
            Ok(ObstacleMesh {
                name: e.id.clone(),
                vertices_in_world: points_of(tri),
                faces: faces_of(path, TOPICS[8], tri)?,
            })
        })
        .collect::<Result<Vec<_>, IoError>>()?;
    let frame = EpisodeFrame {
        time_ns,
        color_rgb8: color.data.to_vec(),
        depth_m,
        world_from_hand,
        tendon_pull_m,
        finger_vertices_in_hand,
        contact_vertices: contacts.fingers,
        markers_in_hand,
        obstacles,
    };
    check_frame(path, info, &frame)?;
    Ok(frame)
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
    crate::atomic::write_atomic(path, &bytes)
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
    let mut pending: Vec<Option<Vec<u8>>> = vec![None; TOPICS.len()];
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
        let Some(slot) = TOPICS.iter().position(|t| *t == topic) else {
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
            let parts: Vec<Vec<u8>> = pending
                .iter_mut()
                .map(|p| p.take().unwrap_or_default())
                .collect();
            match decode_frame(path, info_ref, message.log_time, &parts) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::Vector3;

    fn info() -> EpisodeInfo {
        EpisodeInfo {
            scene: "unit".into(),
            camera: CameraInfo {
                width: 4,
                height: 3,
                fx: 380.0,
                fy: 381.0,
                cx: 1.5,
                cy: 1.0,
            },
            hand_from_camera: Iso3::translation(0.0, 0.0, -0.02),
            hand_from_finger: vec![
                Iso3::new(Vector3::new(-0.025, 0.0, 0.0), Vector3::zeros()),
                Iso3::new(
                    Vector3::new(0.025, 0.0, 0.0),
                    Vector3::z() * std::f64::consts::PI,
                ),
            ],
            finger_faces: vec![vec![[0, 1, 2], [0, 2, 3]], vec![[0, 2, 1]]],
            finger_num_vertices: vec![4, 3],
            tendons_per_finger: 2,
        }
    }

    fn frame(k: u64) -> EpisodeFrame {
        let s = k as f64 * 1e-3;
        EpisodeFrame {
            time_ns: k * 33_333_333,
            color_rgb8: (0..36).map(|i| (i * 7 + k as usize) as u8).collect(),
            depth_m: (0..12)
                .map(|i| {
                    if i == 5 {
                        0.0
                    } else {
                        0.1 + i as f32 * 0.01 + s as f32
                    }
                })
                .collect(),
            world_from_hand: Iso3::new(
                Vector3::new(0.1, 0.2 + s, 0.3),
                Vector3::new(0.1, -0.2, 0.3 + s),
            ),
            tendon_pull_m: vec![vec![0.001 * k as f64, 0.0], vec![0.0, 1.0 / 3.0]],
            finger_vertices_in_hand: vec![
                vec![
                    Point3::new(0.0, 0.0, s),
                    Point3::new(0.01, 0.0, 0.0),
                    Point3::new(0.01, 0.01, 0.0),
                    Point3::new(0.0, 0.01, 0.1 / 3.0),
                ],
                vec![
                    Point3::new(1.0, 0.0, 0.0),
                    Point3::new(1.0, 0.1, 0.0),
                    Point3::new(1.0, 0.0, 0.1),
                ],
            ],
            contact_vertices: vec![vec![1, 3], vec![]],
            markers_in_hand: vec![
                vec![Point3::new(0.005, 0.001, 0.02)],
                vec![Point3::new(1.0, 0.05, 0.05), Point3::new(1.0, 0.05, 0.07)],
            ],
            obstacles: vec![ObstacleMesh {
                name: "plate".into(),
                vertices_in_world: vec![
                    Point3::new(0.0, 0.0, 0.5),
                    Point3::new(1.0, 0.0, 0.5),
                    Point3::new(0.0, 1.0, 0.5 + s),
                ],
                faces: vec![[0, 1, 2]],
            }],
        }
    }

    fn bytes(frames: &[EpisodeFrame]) -> Vec<u8> {
        let mut w = EpisodeWriter::new(
            std::io::Cursor::new(Vec::new()),
            &info(),
            Path::new(crate::MEMORY),
        )
        .unwrap();
        for f in frames {
            w.write_frame(f).unwrap();
        }
        w.finish().unwrap().into_inner()
    }

    #[test]
    fn episodes_round_trip_exactly() {
        let frames: Vec<EpisodeFrame> = (0..3).map(frame).collect();
        let episode = parse_episode(Path::new("e.mcap"), &bytes(&frames)).unwrap();
        assert_eq!(episode.info, info());
        assert_eq!(episode.frames, frames);
    }

    #[test]
    fn the_file_uses_foxglove_schemas_on_the_documented_topics() {
        let data = bytes(&[frame(0)]);
        let summary = mcap::Summary::read(&data)
            .unwrap()
            .expect("summary written");
        let mut topics: Vec<(String, String)> = summary
            .channels
            .values()
            .map(|c| {
                (
                    c.topic.clone(),
                    c.schema
                        .as_ref()
                        .map(|s| s.name.clone())
                        .unwrap_or_default(),
                )
            })
            .collect();
        topics.sort();
        assert!(topics.contains(&("/camera/color".into(), "foxglove.RawImage".into())));
        assert!(topics.contains(&(
            "/camera/calibration".into(),
            "foxglove.CameraCalibration".into()
        )));
        assert!(topics.contains(&("/tf".into(), "foxglove.FrameTransforms".into())));
        assert!(topics.contains(&("/hand/mesh".into(), "foxglove.SceneUpdate".into())));
        assert_eq!(topics.len(), TOPICS.len() + 1);
    }

    #[test]
    fn a_truncated_episode_keeps_every_complete_frame() {
        let frames: Vec<EpisodeFrame> = (0..4).map(frame).collect();
        let data = bytes(&frames);
        let path = Path::new("cut.mcap");
        // Cut at many places: every complete frame before the cut is read back exactly, and the
        // strict reader reports the damage.
        let mut seen_partial = false;
        for cut in (16..data.len()).step_by(37) {
            let (episode, err) = parse_episode_prefix(path, &data[..cut]);
            let err = err.expect("a cut file is reported");
            assert!(err.to_string().starts_with("cut.mcap"), "{err}");
            if let Some(e) = episode {
                assert!(e.frames.len() <= frames.len());
                assert_eq!(e.frames[..], frames[..e.frames.len()]);
                seen_partial |= !e.frames.is_empty() && e.frames.len() < frames.len();
            }
            assert!(parse_episode(path, &data[..cut]).is_err());
        }
        assert!(seen_partial, "some cuts keep a proper prefix of the frames");
    }

    /// A sink whose bytes stay readable while a writer owns it.
    #[derive(Clone, Default)]
    struct SharedSink(std::rc::Rc<std::cell::RefCell<std::io::Cursor<Vec<u8>>>>);

    impl Write for SharedSink {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.borrow_mut().write(buf)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Seek for SharedSink {
        fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
            self.0.borrow_mut().seek(pos)
        }
    }

    #[test]
    fn each_frame_is_one_compressed_chunk_and_a_cut_after_it_keeps_it() {
        let frames: Vec<EpisodeFrame> = (0..4).map(frame).collect();
        let sink = SharedSink::default();
        let mut w = EpisodeWriter::new(sink.clone(), &info(), Path::new(crate::MEMORY)).unwrap();
        // Where the file ends once the info, then each frame, is written (its chunk closed).
        let mut ends = vec![sink.0.borrow().get_ref().len()];
        for f in &frames {
            w.write_frame(f).unwrap();
            ends.push(sink.0.borrow().get_ref().len());
        }
        w.finish().unwrap();
        let data = sink.0.borrow().get_ref().clone();
        let path = Path::new("cut.mcap");
        for (k, pair) in ends.windows(2).enumerate() {
            let (start, end) = (pair[0], pair[1]);
            // The cut is reported (no footer), and every frame up to it is read.
            let (episode, err) = parse_episode_prefix(path, &data[..end]);
            assert!(err.is_some());
            assert_eq!(
                episode.unwrap().frames[..],
                frames[..=k],
                "cut after frame {k}"
            );
            // A cut inside the frame's chunk (its middle: the chunk is most of the frame's
            // bytes, the message index after it the rest) loses exactly that frame.
            let (episode, err) = parse_episode_prefix(path, &data[..(start + end) / 2]);
            assert!(err.is_some());
            assert_eq!(
                episode.unwrap().frames[..],
                frames[..k],
                "cut inside frame {k}"
            );
        }
        // The info and every frame are zstd chunks.
        let compressions: Vec<String> = mcap::read::LinearReader::new(&data)
            .unwrap()
            .filter_map(|r| match r.unwrap() {
                mcap::records::Record::Chunk { header, .. } => Some(header.compression),
                _ => None,
            })
            .collect();
        assert_eq!(compressions.len(), 1 + frames.len());
        assert!(compressions.iter().all(|c| c == "zstd"), "{compressions:?}");
    }

    #[test]
    fn unchunked_uncompressed_episodes_still_read() {
        // The layout of earlier versions: every record in the data section, no compression.
        let frames: Vec<EpisodeFrame> = (0..3).map(frame).collect();
        let chunked = bytes(&frames);
        let mut data = Vec::new();
        {
            let mut w = mcap::WriteOptions::new()
                .use_chunks(false)
                .compression(None)
                .create(std::io::Cursor::new(&mut data))
                .unwrap();
            let stream = mcap::MessageStream::new(&chunked).unwrap();
            for message in stream {
                w.write(&message.unwrap()).unwrap();
            }
            w.finish().unwrap();
        }
        assert!(
            mcap::read::LinearReader::new(&data)
                .unwrap()
                .all(|r| !matches!(r.unwrap(), mcap::records::Record::Chunk { .. }))
        );
        let episode = parse_episode(Path::new("old.mcap"), &data).unwrap();
        assert_eq!(episode.info, info());
        assert_eq!(episode.frames, frames);
    }

    #[test]
    fn frames_that_do_not_fit_are_rejected() {
        let mut w = EpisodeWriter::new(
            std::io::Cursor::new(Vec::new()),
            &info(),
            Path::new("x.mcap"),
        )
        .unwrap();
        let mut f = frame(1);
        f.depth_m.pop();
        assert!(
            w.write_frame(&f)
                .unwrap_err()
                .to_string()
                .contains("camera has 12 pixels")
        );
        let mut f = frame(1);
        f.contact_vertices[0] = vec![3, 9];
        assert!(
            w.write_frame(&f)
                .unwrap_err()
                .to_string()
                .contains("out of range")
        );
        let mut f = frame(1);
        f.finger_vertices_in_hand[1][0].x = f64::NAN;
        assert!(w.write_frame(&f).is_err());
        w.write_frame(&frame(2)).unwrap();
        assert!(
            w.write_frame(&frame(1))
                .unwrap_err()
                .to_string()
                .contains("backwards")
        );
        let mut bad = info();
        bad.finger_faces[1] = vec![[0, 1, 7]];
        assert!(
            EpisodeWriter::new(std::io::Cursor::new(Vec::new()), &bad, Path::new("x.mcap"))
                .is_err()
        );
    }

    #[test]
    fn an_inconsistent_info_record_is_an_error() {
        // Hand-craft an episode whose info lists two finger poses but one vertex count.
        let mut data = Vec::new();
        {
            let mut w = mcap::WriteOptions::new()
                .use_chunks(false)
                .create(std::io::Cursor::new(&mut data))
                .unwrap();
            let schema = w
                .add_schema("moe.EpisodeInfo", "jsonschema", b"{}")
                .unwrap();
            let ch = w
                .add_channel(schema, INFO_TOPIC, "json", &BTreeMap::new())
                .unwrap();
            let mut bad = info();
            bad.finger_num_vertices.pop();
            let body = serde_json::to_vec(&bad).unwrap();
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            };
            w.write_to_known_channel(&header, &body).unwrap();
            w.finish().unwrap();
        }
        let err = parse_episode(Path::new("i.mcap"), &data)
            .unwrap_err()
            .to_string();
        assert!(err.contains("2 finger poses"), "{err}");
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        let path = Path::new("g.mcap");
        assert!(parse_episode(path, b"").is_err());
        assert!(parse_episode(path, b"not an mcap file at all").is_err());
        let mut data = bytes(&[frame(0), frame(1)]);
        let mut rng = moe_geom::SeededRng::new(5);
        for _ in 0..200 {
            let k = rng.below(data.len() as u64) as usize;
            data[k] ^= 1 << rng.below(8);
            let _ = parse_episode_prefix(path, &data);
        }
    }

    #[test]
    fn write_episode_is_atomic() {
        let dir = std::env::temp_dir().join(format!("moe-episode-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("e.mcap");
        write_episode(&path, &info(), &[frame(0), frame(1)]).unwrap();
        assert_eq!(read_episode(&path).unwrap().frames.len(), 2);
        let mut bad = frame(2);
        bad.color_rgb8.clear();
        let other = dir.join("bad.mcap");
        assert!(write_episode(&other, &info(), &[frame(0), bad]).is_err());
        assert!(!other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
