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
//! becomes [`IoError::ParserPanic`](moe_io::IoError::ParserPanic). Compression shrinks a frame about threefold (the
//! noisy depth image compresses least; sizes in docs/results.md). Unchunked, uncompressed files (as
//! written by earlier versions) read the same way.

#[cfg(feature = "mcap")]
mod foxglove;
#[cfg(feature = "mcap")]
mod read;
#[cfg(feature = "mcap")]
mod topic;
#[cfg(feature = "mcap")]
mod write;

#[cfg(feature = "mcap")]
use std::path::Path;

use moe_geom::{Iso3, Point3};
use serde::{Deserialize, Serialize};

#[cfg(feature = "mcap")]
pub(crate) use foxglove::{
    add_channel, camera_calibration, color_image, contact_mesh_entity, encode, fg_color, fg_pose,
    fg_transform, mcap_err, mcap_writer, mesh_entity, obstacle_entities, schema_of, spheres_entity,
    timestamp, write_info, write_message,
};
#[cfg(feature = "mcap")]
use moe_io::IoError;
#[cfg(feature = "mcap")]
pub(crate) use read::check_declared_lengths;
#[cfg(feature = "mcap")]
pub use read::{parse_episode, parse_episode_prefix, read_episode, read_episode_prefix};
#[cfg(feature = "mcap")]
pub use write::{EpisodeWriter, create_episode, write_episode};

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

impl From<moe_geom::CameraIntrinsics> for CameraInfo {
    fn from(k: moe_geom::CameraIntrinsics) -> Self {
        let moe_geom::CameraIntrinsics {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        } = k;
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        }
    }
}

impl From<CameraInfo> for moe_geom::CameraIntrinsics {
    fn from(c: CameraInfo) -> Self {
        let CameraInfo {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        } = c;
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        }
    }
}

impl EpisodeInfo {
    /// Whether `hand` is the episode's hand (as many fingers, as many vertices each): `None`
    /// when it is, else the first difference in words.
    pub fn hand_mismatch(&self, hand: &moe_geom::HandModel) -> Option<String> {
        let recorded = moe_geom::HandSignature::of_vertex_counts(self.finger_num_vertices.clone());
        hand.differs_from(&recorded).map(|_| {
            let ours = hand.signature().vertices_per_finger;
            format!(
                "the hand has fingers of {ours:?} vertices, the episode '{}' of {:?}",
                self.scene, self.finger_num_vertices
            )
        })
    }

    /// The fixed information of an episode of `hand` seen by a camera with intrinsics `camera`
    /// mounted at `hand_from_camera`: the fingers' poses, faces and vertex counts, and the
    /// tendon count, from the hand.
    ///
    /// # Errors
    /// A hand whose fingers have different numbers of tendons (an episode records one count).
    pub fn for_hand(
        scene: impl Into<String>,
        camera: CameraInfo,
        hand_from_camera: Iso3,
        hand: &moe_geom::HandModel,
    ) -> Result<Self, moe_geom::GeomError> {
        Ok(Self {
            scene: scene.into(),
            camera,
            hand_from_camera,
            hand_from_finger: hand
                .fingers()
                .iter()
                .map(|f| *f.hand_from_finger.iso())
                .collect(),
            finger_faces: hand
                .fingers()
                .iter()
                .map(|f| f.model.mesh().faces().to_vec())
                .collect(),
            finger_num_vertices: hand
                .fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect(),
            tendons_per_finger: hand.tendons_per_finger()?,
        })
    }
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
    /// Time, nanoseconds: since the start of a simulated episode; for a ROS 2 recording, the
    /// colour image's stamp (since the epoch).
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

impl EpisodeFrame {
    /// The frame's time, seconds.
    pub fn time_secs(&self) -> f64 {
        1e-9 * self.time_ns as f64
    }

    /// The frame's images, as the pipeline takes them.
    pub fn rgbd(&self) -> moe_geom::RgbdFrame<'_> {
        moe_geom::RgbdFrame {
            color_rgb8: &self.color_rgb8,
            depth_m: &self.depth_m,
        }
    }

    /// What the robot knows of the frame besides its images: the tendon pulls, the wrist pose
    /// and the time (the markers are found in the images).
    pub fn observation(&self) -> moe_geom::Observation<'_> {
        moe_geom::Observation::new()
            .with_tendon_pulls(&self.tendon_pull_m)
            .with_world_from_hand(moe_geom::WorldFromHand::new(self.world_from_hand))
            .with_time(self.time_secs())
    }
}

/// A whole episode as read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Fixed information.
    pub info: EpisodeInfo,
    /// Frames in time order.
    pub frames: Vec<EpisodeFrame>,
}

#[cfg(feature = "mcap")]
pub(crate) fn check_info(path: &Path, info: &EpisodeInfo) -> Result<(), IoError> {
    let refuse = |message: String| Err(IoError::invalid(path, "episode info", message));
    let n = info.hand_from_finger.len();
    if info.finger_faces.len() != n || info.finger_num_vertices.len() != n {
        return refuse(format!(
            "{n} finger poses, {} face lists and {} vertex counts",
            info.finger_faces.len(),
            info.finger_num_vertices.len()
        ));
    }
    for (f, (faces, &nv)) in info
        .finger_faces
        .iter()
        .zip(&info.finger_num_vertices)
        .enumerate()
    {
        if let Some(bad) = faces.iter().flatten().find(|&&v| v as usize >= nv) {
            return refuse(format!(
                "finger {f}: face refers to vertex {bad}, but it has {nv}"
            ));
        }
    }
    let c = &info.camera;
    if !(1..=MAX_IMAGE_SIDE).contains(&c.width) || !(1..=MAX_IMAGE_SIDE).contains(&c.height) {
        return refuse(format!(
            "camera image size {} × {} is outside 1..={MAX_IMAGE_SIDE} pixels a side",
            c.width, c.height
        ));
    }
    if let Some((f, &nv)) = info
        .finger_num_vertices
        .iter()
        .enumerate()
        .find(|(_, n)| **n > MAX_FINGER_VERTICES)
    {
        return refuse(format!(
            "finger {f} declares {nv} vertices, more than {MAX_FINGER_VERTICES}"
        ));
    }
    if info.tendons_per_finger > MAX_TENDONS_PER_FINGER {
        return refuse(format!(
            "{} tendons per finger declared, more than {MAX_TENDONS_PER_FINGER}",
            info.tendons_per_finger
        ));
    }
    Ok(())
}

/// Largest image side an episode may declare, pixels.
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// Most vertices a finger of an episode may declare.
pub const MAX_FINGER_VERTICES: usize = 1 << 22;
/// Most tendons a finger of an episode may declare.
pub const MAX_TENDONS_PER_FINGER: usize = 64;
/// Largest uncompressed size a chunk may declare, bytes (a 640 × 480 frame takes 2.5 MB).
pub const MAX_CHUNK_BYTES: u64 = 1 << 30;

#[cfg(feature = "mcap")]
pub(super) fn check_frame(
    path: &Path,
    info: &EpisodeInfo,
    frame: &EpisodeFrame,
) -> Result<(), IoError> {
    let item = format!("frame at {} ns", frame.time_ns);
    let refuse = |message: String| Err(IoError::invalid(path, item.clone(), message));
    let pixels = info.camera.width as usize * info.camera.height as usize;
    if frame.color_rgb8.len() != 3 * pixels || frame.depth_m.len() != pixels {
        return refuse(format!(
            "images hold {} colour bytes and {} depths, the camera has {pixels} pixels",
            frame.color_rgb8.len(),
            frame.depth_m.len()
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
            return refuse(format!("has {len} {what} for {n} fingers"));
        }
    }
    for f in 0..n {
        let nv = info.finger_num_vertices[f];
        if frame.finger_vertices_in_hand[f].len() != nv {
            return refuse(format!(
                "finger {f} has {} vertices, expected {nv}",
                frame.finger_vertices_in_hand[f].len()
            ));
        }
        if frame.tendon_pull_m[f].len() != info.tendons_per_finger {
            return refuse(format!(
                "finger {f} has {} tendons",
                frame.tendon_pull_m[f].len()
            ));
        }
        if let Some(bad) = frame.contact_vertices[f]
            .iter()
            .find(|&&v| v as usize >= nv)
        {
            return refuse(format!("finger {f} contact vertex {bad} out of range"));
        }
        if !frame.contact_vertices[f].windows(2).all(|w| w[0] < w[1]) {
            return refuse(format!("finger {f} contact ids not sorted and distinct"));
        }
        let finite = frame.finger_vertices_in_hand[f]
            .iter()
            .chain(&frame.markers_in_hand[f])
            .all(moe_geom::math::is_finite_point)
            && frame.tendon_pull_m[f].iter().all(|v| v.is_finite());
        if !finite {
            return refuse(format!("finger {f} has a non-finite value"));
        }
    }
    if frame.depth_m.iter().any(|d| !d.is_finite()) {
        return refuse("non-finite depth".into());
    }
    for o in &frame.obstacles {
        let nv = o.vertices_in_world.len();
        if o.faces.iter().flatten().any(|&v| v as usize >= nv)
            || !o
                .vertices_in_world
                .iter()
                .all(moe_geom::math::is_finite_point)
        {
            return refuse(format!("obstacle '{}' has a bad vertex or face", o.name));
        }
    }
    Ok(())
}

#[cfg(all(test, feature = "mcap"))]
mod tests {
    use std::collections::BTreeMap;
    use std::io::{Seek, Write};

    use super::topic::INFO_TOPIC;
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
            Path::new(moe_io::MEMORY),
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
        assert_eq!(topics.len(), topic::Topic::ALL.len() + 1);
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
            moe_geom::assert_err!(
                parse_episode(path, &data[..cut]),
                IoError::Parse { path: p, .. } if p == path,
                "cut at {cut}"
            );
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
        let mut w = EpisodeWriter::new(sink.clone(), &info(), Path::new(moe_io::MEMORY)).unwrap();
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
        moe_geom::assert_err!(
            w.write_frame(&f),
            IoError::InvalidData { path, item, message } if path == Path::new("x.mcap")
                && item == "frame at 33333333 ns" && message == "finger 1 has a non-finite value"
        );
        w.write_frame(&frame(2)).unwrap();
        assert!(
            w.write_frame(&frame(1))
                .unwrap_err()
                .to_string()
                .contains("backwards")
        );
        let mut bad = info();
        bad.finger_faces[1] = vec![[0, 1, 7]];
        moe_geom::assert_err!(
            EpisodeWriter::new(std::io::Cursor::new(Vec::new()), &bad, Path::new("x.mcap")),
            IoError::InvalidData { path, item, message } if path == Path::new("x.mcap")
                && item == "episode info"
                && message.starts_with("finger 1: face refers to vertex 7,")
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
    fn declared_sizes_are_bounded() {
        let path = Path::new("b.mcap");
        assert!(check_info(path, &info()).is_ok());
        let limit = |mut bad: EpisodeInfo, edit: &dyn Fn(&mut EpisodeInfo), limit: &str| {
            edit(&mut bad);
            let err = check_info(path, &bad).unwrap_err();
            assert!(
                matches!(&err, IoError::InvalidData { item, .. } if item == "episode info"),
                "{err:?}"
            );
            assert!(err.to_string().contains(limit), "{err}");
        };
        limit(
            info(),
            &|i| i.tendons_per_finger = MAX_TENDONS_PER_FINGER + 1,
            "more than 64",
        );
        limit(info(), &|i| i.camera.width = MAX_IMAGE_SIDE + 1, "1..=8192");
        let mut at_limit = info();
        at_limit.tendons_per_finger = MAX_TENDONS_PER_FINGER;
        assert!(check_info(path, &at_limit).is_ok());
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        let path = Path::new("g.mcap");
        for garbage in [&b""[..], b"not an mcap file at all"] {
            moe_geom::assert_err!(
                parse_episode(path, garbage),
                IoError::Parse { path: p, .. } if p == path
            );
        }
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
        moe_geom::assert_err!(
            write_episode(&other, &info(), &[frame(0), bad]),
            IoError::InvalidData { path, item, message } if *path == other
                && item == "frame at 66666666 ns"
                && message.starts_with("images hold 0 colour bytes")
        );
        assert!(!other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
