//! The result of running the pipeline over an episode, as MCAP with Foxglove's schemas: the
//! input camera image beside the estimates, and the ground truth where the episode has it.
//!
//! | topic | schema (encoding) | content |
//! |---|---|---|
//! | `/run/info` | `moe.RunInfo` (JSON) | once: scene, model, threshold, camera, finger layout |
//! | `/camera/color` | `foxglove.RawImage` (protobuf) | the input image, `rgb8` |
//! | `/camera/calibration` | `foxglove.CameraCalibration` (protobuf) | pinhole intrinsics |
//! | `/tf` | `foxglove.FrameTransforms` (protobuf) | `world→hand`, `hand→camera`, `hand→finger_i` |
//! | `/estimate/markers` | `foxglove.SceneUpdate` (protobuf) | detected markers, hand frame |
//! | `/estimate/mesh` | `foxglove.SceneUpdate` (protobuf) | estimated finger meshes, blue (0) to red (1) by contact probability |
//! | `/estimate/contacts` | `foxglove.SceneUpdate` (protobuf) | estimated contact points, world frame |
//! | `/truth/mesh` | `foxglove.SceneUpdate` (protobuf) | true finger meshes, contact vertices red (episodes with ground truth) |
//! | `/truth/contacts` | `foxglove.SceneUpdate` (protobuf) | true contact points, world frame |
//! | `/obstacles` | `foxglove.SceneUpdate` (protobuf) | obstacle meshes, world frame |
//!
//! The file holds no timings, so the same episode and model give the same bytes.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use foxglove::messages as fg;
use moe_geom::{Iso3, Point3};
use serde::{Deserialize, Serialize};

use crate::episode::{
    EpisodeInfo, ObstacleMesh, add_channel, camera_calibration, color_image, contact_mesh_entity,
    encode, fg_color, fg_transform, mcap_err, mcap_writer, mesh_entity, obstacle_entities,
    schema_of, spheres_entity, write_info, write_message,
};
use crate::error::IoError;

/// What stays fixed over a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunInfo {
    /// The contact model that ran (its file name).
    pub model: String,
    /// Its contact threshold.
    pub threshold: f64,
    /// The input episode's fixed information (scene, camera, finger layout).
    pub episode: EpisodeInfo,
}

/// The ground truth of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RunTruth {
    /// True vertices of every finger, hand frame.
    pub vertices_in_hand: Vec<Vec<Point3>>,
    /// True contact vertex ids of every finger.
    pub contact_vertices: Vec<Vec<u32>>,
    /// Obstacles, world frame.
    pub obstacles: Vec<ObstacleMesh>,
}

/// One frame's input and estimates.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFrame {
    /// Time since the start of the episode, nanoseconds.
    pub time_ns: u64,
    /// The input colour image, RGB8.
    pub color_rgb8: Vec<u8>,
    /// Where the hand was.
    pub world_from_hand: Iso3,
    /// Detected markers of every finger, hand frame (`None`: not seen).
    pub markers_in_hand: Vec<Vec<Option<Point3>>>,
    /// Estimated vertices of every finger, hand frame.
    pub vertices_in_hand: Vec<Vec<Point3>>,
    /// Contact probability of every vertex.
    pub contact_probability: Vec<Vec<f64>>,
    /// Estimated contact points, world frame.
    pub contacts_in_world: Vec<Point3>,
    /// The ground truth, where the episode has it.
    pub truth: Option<RunTruth>,
}

/// The per-frame topics of a run file, in the order each frame writes them (`/run/info` comes
/// once, first).
pub const RUN_TOPICS: [&str; 9] = [
    "/camera/color",
    "/camera/calibration",
    "/tf",
    "/estimate/markers",
    "/estimate/mesh",
    "/estimate/contacts",
    "/truth/mesh",
    "/truth/contacts",
    "/obstacles",
];

/// Blue (0) to red (1): the colour of a contact probability on a mesh.
pub fn probability_colour(p: f64) -> [u8; 3] {
    let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
    [
        (255.0 * p).round() as u8,
        40,
        (255.0 * (1.0 - p)).round() as u8,
    ]
}

/// Writes a run to any seekable sink.
pub struct RunWriter<W: Write + Seek> {
    path: PathBuf,
    writer: mcap::Writer<W>,
    channels: [u16; 9],
    info: RunInfo,
    sequence: u32,
}

impl<W: Write + Seek> std::fmt::Debug for RunWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunWriter")
            .field("scene", &self.info.episode.scene)
            .field("messages", &self.sequence)
            .finish()
    }
}

impl<W: Write + Seek> RunWriter<W> {
    /// Starts a run file: header, schemas, channels and the run info. `path` names the
    /// destination in errors.
    ///
    /// # Errors
    /// Inconsistent episode info (as for episodes), or a write failure.
    pub fn new(sink: W, info: &RunInfo, path: &Path) -> Result<Self, IoError> {
        crate::episode::check_info(path, &info.episode)?;
        let mut writer = mcap_writer(sink, path)?;
        write_info(&mut writer, path, "/run/info", "moe.RunInfo", info)?;
        let scene = || schema_of::<fg::SceneUpdate>();
        let schemas = [
            schema_of::<fg::RawImage>(),
            schema_of::<fg::CameraCalibration>(),
            schema_of::<fg::FrameTransforms>(),
            scene(),
            scene(),
            scene(),
            scene(),
            scene(),
            scene(),
        ];
        let mut channels = [0u16; RUN_TOPICS.len()];
        for ((slot, topic), schema) in channels.iter_mut().zip(RUN_TOPICS).zip(schemas) {
            *slot = add_channel(&mut writer, path, topic, schema, "protobuf")?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            channels,
            info: info.clone(),
            sequence: 1,
        })
    }

    /// Appends one frame (one chunk).
    ///
    /// # Errors
    /// A frame that does not fit the run info, or a write failure.
    pub fn write_frame(&mut self, frame: &RunFrame) -> Result<(), IoError> {
        let path = self.path.clone();
        let messages = self.encode(frame)?;
        for (channel, data) in self.channels.iter().zip(messages) {
            let Some(data) = data else { continue };
            write_message(
                &mut self.writer,
                &path,
                *channel,
                &mut self.sequence,
                frame.time_ns,
                &data,
            )?;
        }
        self.writer.flush().map_err(|e| mcap_err(&path, e))
    }

    /// Writes the summary and returns the sink.
    ///
    /// # Errors
    /// A write failure.
    pub fn finish(mut self) -> Result<W, IoError> {
        self.writer.finish().map_err(|e| mcap_err(&self.path, e))?;
        Ok(self.writer.into_inner())
    }

    fn encode(&self, frame: &RunFrame) -> Result<Vec<Option<Vec<u8>>>, IoError> {
        let path = self.path.as_path();
        let info = &self.info.episode;
        let t = frame.time_ns;
        let cam = &info.camera;
        let fingers = info.finger_faces.len();
        let pixels = cam.width as usize * cam.height as usize;
        let item = format!("run frame at {t} ns");
        let refuse = |message: String| Err(IoError::invalid(path, item.clone(), message));
        if frame.color_rgb8.len() != 3 * pixels {
            return refuse(format!(
                "{} colour bytes for a camera of {pixels} pixels",
                frame.color_rgb8.len()
            ));
        }
        let truth_lists = frame.truth.as_ref().map_or([fingers; 2], |tr| {
            [tr.vertices_in_hand.len(), tr.contact_vertices.len()]
        });
        for (what, len) in [
            ("marker lists", frame.markers_in_hand.len()),
            ("vertex lists", frame.vertices_in_hand.len()),
            ("contact probability lists", frame.contact_probability.len()),
            ("true vertex lists", truth_lists[0]),
            ("true contact lists", truth_lists[1]),
        ] {
            if len != fingers {
                return refuse(format!("{len} {what} for {fingers} fingers"));
            }
        }
        for (f, &n) in info.finger_num_vertices.iter().enumerate() {
            let (v, p) = (&frame.vertices_in_hand[f], &frame.contact_probability[f]);
            if v.len() != n || p.len() != n {
                return refuse(format!(
                    "finger {f} has {} vertices and {} contact probabilities, expected {n}",
                    v.len(),
                    p.len()
                ));
            }
            if let Some(tr) = &frame.truth {
                if tr.vertices_in_hand[f].len() != n {
                    return refuse(format!(
                        "finger {f} has {} true vertices, expected {n}",
                        tr.vertices_in_hand[f].len()
                    ));
                }
                if let Some(i) = tr.contact_vertices[f].iter().find(|&&i| i as usize >= n) {
                    return refuse(format!(
                        "finger {f}: true contact vertex {i} is out of range ({n} vertices)"
                    ));
                }
            }
        }
        let mut transforms = vec![
            fg_transform(t, "world", "hand", &frame.world_from_hand),
            fg_transform(t, "hand", "camera", &info.hand_from_camera),
        ];
        for (i, iso) in info.hand_from_finger.iter().enumerate() {
            transforms.push(fg_transform(t, "hand", &format!("finger_{i}"), iso));
        }
        let update = |entities: Vec<fg::SceneEntity>| {
            encode(&fg::SceneUpdate {
                deletions: vec![],
                entities,
            })
        };
        let markers = update(
            frame
                .markers_in_hand
                .iter()
                .enumerate()
                .map(|(f, ms)| {
                    let seen: Vec<Point3> = ms.iter().flatten().copied().collect();
                    spheres_entity(
                        t,
                        "hand",
                        format!("markers_{f}"),
                        &seen,
                        0.004,
                        [0.1, 1.0, 0.2, 1.0],
                    )
                })
                .collect(),
        );
        let rgba = |c: [u8; 3]| {
            fg_color([
                f64::from(c[0]) / 255.0,
                f64::from(c[1]) / 255.0,
                f64::from(c[2]) / 255.0,
                1.0,
            ])
            .expect("some")
        };
        let mesh = update(
            (0..fingers)
                .map(|f| {
                    let colors = frame.contact_probability[f]
                        .iter()
                        .map(|&p| rgba(probability_colour(p)))
                        .collect();
                    mesh_entity(
                        t,
                        "hand",
                        format!("finger_{f}"),
                        &frame.vertices_in_hand[f],
                        &info.finger_faces[f],
                        Some(colors),
                    )
                })
                .collect(),
        );
        let contacts = update(vec![spheres_entity(
            t,
            "world",
            "contacts".into(),
            &frame.contacts_in_world,
            0.002,
            [1.0, 0.1, 0.1, 1.0],
        )]);
        let (truth_mesh, truth_contacts, obstacles) = match &frame.truth {
            None => (None, None, None),
            Some(tr) => {
                let mut entities = Vec::with_capacity(fingers);
                let mut points = Vec::new();
                for f in 0..fingers {
                    for &v in &tr.contact_vertices[f] {
                        points.push(frame.world_from_hand * tr.vertices_in_hand[f][v as usize]);
                    }
                    entities.push(contact_mesh_entity(
                        t,
                        format!("true_finger_{f}"),
                        &tr.vertices_in_hand[f],
                        &info.finger_faces[f],
                        &tr.contact_vertices[f],
                    ));
                }
                let obstacles = obstacle_entities(t, &tr.obstacles);
                (
                    Some(update(entities)),
                    Some(update(vec![spheres_entity(
                        t,
                        "world",
                        "true_contacts".into(),
                        &points,
                        0.002,
                        [1.0, 0.85, 0.0, 1.0],
                    )])),
                    Some(update(obstacles)),
                )
            }
        };
        Ok(vec![
            Some(encode(&color_image(t, cam, &frame.color_rgb8))),
            Some(encode(&camera_calibration(t, cam))),
            Some(encode(&fg::FrameTransforms { transforms })),
            Some(markers),
            Some(mesh),
            Some(contacts),
            truth_mesh,
            truth_contacts,
            obstacles,
        ])
    }
}

/// Writes a whole run atomically: nothing appears at `path` unless every frame was written.
///
/// # Errors
/// As [`RunWriter`], or a failing write.
pub fn write_run(path: &Path, info: &RunInfo, frames: &[RunFrame]) -> Result<(), IoError> {
    let mut writer = RunWriter::new(std::io::Cursor::new(Vec::new()), info, path)?;
    for frame in frames {
        writer.write_frame(frame)?;
    }
    let bytes = writer.finish()?.into_inner();
    crate::atomic::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> RunInfo {
        RunInfo {
            model: "m.safetensors".into(),
            threshold: 0.5,
            episode: EpisodeInfo {
                scene: "unit".into(),
                camera: crate::CameraInfo {
                    width: 2,
                    height: 2,
                    fx: 100.0,
                    fy: 100.0,
                    cx: 0.5,
                    cy: 0.5,
                },
                hand_from_camera: Iso3::identity(),
                hand_from_finger: vec![Iso3::identity()],
                finger_faces: vec![vec![[0, 1, 2]]],
                finger_num_vertices: vec![3],
                tendons_per_finger: 1,
            },
        }
    }

    fn frame(truth: bool) -> RunFrame {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.01, 0.0, 0.0),
            Point3::new(0.0, 0.01, 0.0),
        ];
        RunFrame {
            time_ns: 5,
            color_rgb8: vec![7; 12],
            world_from_hand: Iso3::translation(0.0, 0.0, 0.5),
            markers_in_hand: vec![vec![Some(v[0]), None]],
            vertices_in_hand: vec![v.clone()],
            contact_probability: vec![vec![0.1, 0.9, f64::NAN]],
            contacts_in_world: vec![Point3::new(0.01, 0.0, 0.5)],
            truth: truth.then(|| RunTruth {
                vertices_in_hand: vec![v],
                contact_vertices: vec![vec![1]],
                obstacles: vec![],
            }),
        }
    }

    fn write(frames: &[RunFrame]) -> Result<Vec<u8>, IoError> {
        let mut w = RunWriter::new(
            std::io::Cursor::new(Vec::new()),
            &info(),
            Path::new("r.mcap"),
        )?;
        for f in frames {
            w.write_frame(f)?;
        }
        Ok(w.finish()?.into_inner())
    }

    #[test]
    fn a_run_file_has_its_topics_with_foxglove_schemas() {
        let bytes = write(&[frame(true), frame(false)]).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
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
        assert_eq!(topics.len(), RUN_TOPICS.len() + 1);
        assert!(topics.contains(&("/camera/color".into(), "foxglove.RawImage".into())));
        assert!(topics.contains(&("/estimate/mesh".into(), "foxglove.SceneUpdate".into())));
        assert!(topics.contains(&("/run/info".into(), "moe.RunInfo".into())));
        // The frame without ground truth writes no truth messages: 9 + 6 messages and the info.
        let stats = summary.stats.expect("statistics");
        assert_eq!(stats.message_count, 1 + 9 + 6);
        // Same input, same bytes.
        assert_eq!(bytes, write(&[frame(true), frame(false)]).unwrap());
    }

    #[test]
    fn a_frame_that_does_not_fit_is_refused() {
        let mut f = frame(true);
        f.contact_probability[0].pop();
        let does_not_fit = |f: RunFrame, what: &str| {
            moe_geom::assert_err!(
                write(&[f]),
                IoError::InvalidData { path, item, message }
                    if path == Path::new("r.mcap")
                        && item == "run frame at 5 ns"
                        && message.starts_with(what),
                "{what}"
            );
        };
        does_not_fit(
            f,
            "finger 0 has 3 vertices and 2 contact probabilities, expected 3",
        );
        let mut f = frame(true);
        f.truth.as_mut().unwrap().contact_vertices[0] = vec![3];
        does_not_fit(f, "finger 0: true contact vertex 3 is out of range");
        let mut f = frame(false);
        f.color_rgb8.pop();
        does_not_fit(f, "11 colour bytes");
        let mut f = frame(true);
        f.markers_in_hand.pop();
        does_not_fit(f, "0 marker lists for 1 fingers");
    }
}
