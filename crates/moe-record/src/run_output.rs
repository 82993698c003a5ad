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
//! | `/estimate/forces` | `foxglove.SceneUpdate` (protobuf) | estimated loads as arrows, hand frame (runs with forces) |
//! | `/estimate/finger_force` | `moe.FingerForces` (JSON) | net force on every finger, N, for Foxglove's Plot panel (runs with forces) |
//! | `/truth/mesh` | `foxglove.SceneUpdate` (protobuf) | true finger meshes, contact vertices red (episodes with ground truth) |
//! | `/truth/contacts` | `foxglove.SceneUpdate` (protobuf) | true contact points, world frame |
//! | `/obstacles` | `foxglove.SceneUpdate` (protobuf) | obstacle meshes, world frame |
//!
//! The force topics are written only by a run whose estimator estimates force (the physics
//! estimator): [`RunInfo::force_arrow_m_per_n`] says so, and every frame then carries
//! [`RunFrame::forces`]. A load's arrow ends at the load's place on the estimated surface and
//! points along the force the world exerts on the finger (into the finger); its length is the
//! force's magnitude times `force_arrow_m_per_n` (recorded in `/run/info`). The finger forces
//! plot as `/estimate/finger_force.fingers[0].magnitude_n` (or `.x_n`, `.y_n`, `.z_n`, hand
//! frame; `.pressed_probability`).
//!
//! The file holds no timings, so the same episode and model give the same bytes.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use foxglove::messages as fg;
use moe_geom::math::UnitQuat;
use moe_geom::{Iso3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::episode::{
    EpisodeInfo, ObstacleMesh, add_channel, camera_calibration, color_image, contact_mesh_entity,
    encode, fg_color, fg_pose, fg_transform, mcap_err, mcap_writer, mesh_entity, obstacle_entities,
    schema_of, spheres_entity, timestamp, write_info, write_message,
};
use moe_io::IoError;

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
    /// Length of a force arrow per newton of force, metres, for a run whose estimator
    /// estimates force (it then writes `/estimate/forces` and `/estimate/finger_force`, and
    /// every frame carries [`RunFrame::forces`]); `None` for one that does not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_arrow_m_per_n: Option<f64>,
}

/// One load an estimator found: where the world presses a finger and how hard (hand frame).
#[derive(Debug, Clone, PartialEq)]
pub struct RunLoad {
    /// Finger index.
    pub finger: usize,
    /// The load's place on the estimated surface, hand frame, metres.
    pub location_in_hand: Point3,
    /// The force the world exerts on the finger there, hand frame, newtons.
    pub force_n: Vector3,
}

/// What an estimator that estimates force found in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RunForces {
    /// Per finger: the net force the world exerts on it, hand frame, newtons.
    pub finger_force_n: Vec<Vector3>,
    /// Per finger: the probability that it is pressed, where the estimator says it.
    pub pressed_probability: Option<Vec<f64>>,
    /// The loads found (drawn as arrows).
    pub loads: Vec<RunLoad>,
}

/// One finger of a `/estimate/finger_force` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerForceMessage {
    /// Finger index.
    pub finger: usize,
    /// The net force on the finger, hand frame, newtons: x.
    pub x_n: f64,
    /// y.
    pub y_n: f64,
    /// z.
    pub z_n: f64,
    /// Its magnitude, newtons.
    pub magnitude_n: f64,
    /// Probability that the finger is pressed (where the estimator says it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pressed_probability: Option<f64>,
    /// Loads found on the finger.
    pub loads: usize,
}

/// The JSON body of `/estimate/finger_force` (schema `moe.FingerForces`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerForcesMessage {
    /// Time of the frame.
    pub timestamp: JsonTime,
    /// The frame the forces are in (`hand`).
    pub frame_id: String,
    /// Every finger, in order.
    pub fingers: Vec<FingerForceMessage>,
}

/// A time as Foxglove's JSON messages write it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonTime {
    /// Whole seconds.
    pub sec: u64,
    /// Nanoseconds within the second.
    pub nsec: u32,
}

/// The JSON schema of `/estimate/finger_force` messages, so that Foxglove offers their fields
/// in the Plot panel's message paths.
const FINGER_FORCES_SCHEMA: &str = r#"{"title":"moe.FingerForces","description":"Net force the world exerts on every finger, hand frame, newtons","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0}}},"frame_id":{"type":"string"},"fingers":{"type":"array","items":{"type":"object","properties":{"finger":{"type":"integer"},"x_n":{"type":"number"},"y_n":{"type":"number"},"z_n":{"type":"number"},"magnitude_n":{"type":"number"},"pressed_probability":{"type":"number"},"loads":{"type":"integer"}}}}}}"#;

/// Colour of the force arrows (RGBA), here and in results written as ROS 2 messages.
pub(crate) const FORCE_COLOR: [f64; 4] = [1.0, 0.62, 0.0, 1.0];

/// Colour and diameter of the markers found.
pub(crate) const MARKER_COLOR: [f64; 4] = [0.1, 1.0, 0.2, 1.0];
/// Diameter of a found marker's sphere, metres.
pub(crate) const MARKER_DIAMETER_M: f64 = 0.004;
/// Colour of the estimated contact points.
pub(crate) const CONTACT_COLOR: [f64; 4] = [1.0, 0.1, 0.1, 1.0];
/// Diameter of a contact point's sphere, metres.
pub(crate) const CONTACT_DIAMETER_M: f64 = 0.002;

/// A vertex's colour for contact probability `p` ([`probability_colour`]), RGBA in `[0, 1]`.
pub(crate) fn probability_rgba(p: f64) -> [f64; 4] {
    let [r, g, b] = probability_colour(p);
    [r, g, b, 255].map(|c| f64::from(c) / 255.0)
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
    /// The episode frame's time, nanoseconds ([`crate::EpisodeFrame::time_ns`]).
    pub time_ns: u64,
    /// The input colour image, RGB8.
    pub color_rgb8: Vec<u8>,
    /// Where the hand was.
    pub world_from_hand: Iso3,
    /// Detected markers of every finger, hand frame (`None`: not seen).
    pub markers_in_hand: Vec<Vec<Option<Point3>>>,
    /// Estimated vertices of every finger, hand frame; a finger with no estimate in this frame
    /// (a frame whose estimate failed) has none, and no contact probabilities either.
    pub vertices_in_hand: Vec<Vec<Point3>>,
    /// Contact probability of every vertex (none for a finger without vertices).
    pub contact_probability: Vec<Vec<f64>>,
    /// Estimated contact points, world frame.
    pub contacts_in_world: Vec<Point3>,
    /// The ground truth, where the episode has it.
    pub truth: Option<RunTruth>,
    /// The estimated forces, for a run whose estimator estimates force (see
    /// [`RunInfo::force_arrow_m_per_n`]).
    pub forces: Option<RunForces>,
}

/// The per-frame topics of a run file, in the order each frame writes them (`/run/info` comes
/// once, first). The force topics are in runs with forces only; the truth topics in frames with
/// ground truth only.
pub const RUN_TOPICS: [&str; 11] = [
    "/camera/color",
    "/camera/calibration",
    "/tf",
    "/estimate/markers",
    "/estimate/mesh",
    "/estimate/contacts",
    "/estimate/forces",
    "/estimate/finger_force",
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

/// A viridis-like colour ramp, `t` from 0 (dark blue) to 1 (yellow); NaN is 0: the colour of a
/// scalar map on a mesh or in a figure.
pub fn viridis_colour(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    [c(0), c(1), c(2)]
}

/// Writes a run to any seekable sink.
pub struct RunWriter<W: Write + Seek> {
    path: PathBuf,
    writer: mcap::Writer<W>,
    /// The channel of every topic of [`RUN_TOPICS`] the file has.
    channels: [Option<u16>; RUN_TOPICS.len()],
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
        if let Some(scale) = info.force_arrow_m_per_n
            && !(scale.is_finite() && scale > 0.0)
        {
            return Err(IoError::invalid(
                path,
                "run info",
                format!("force_arrow_m_per_n = {scale} must be finite and positive"),
            ));
        }
        let mut writer = mcap_writer(sink, path, "")?;
        write_info(&mut writer, path, "/run/info", "moe.RunInfo", info)?;
        let scene = || Some((schema_of::<fg::SceneUpdate>(), "protobuf"));
        let forces = info.force_arrow_m_per_n.is_some();
        let finger_forces = (
            "moe.FingerForces".to_owned(),
            "jsonschema".to_owned(),
            FINGER_FORCES_SCHEMA.as_bytes().to_vec(),
        );
        let schemas = [
            Some((schema_of::<fg::RawImage>(), "protobuf")),
            Some((schema_of::<fg::CameraCalibration>(), "protobuf")),
            Some((schema_of::<fg::FrameTransforms>(), "protobuf")),
            scene(),
            scene(),
            scene(),
            scene().filter(|_| forces),
            forces.then_some((finger_forces, "json")),
            scene(),
            scene(),
            scene(),
        ];
        let mut channels = [None; RUN_TOPICS.len()];
        for ((slot, topic), schema) in channels.iter_mut().zip(RUN_TOPICS).zip(schemas) {
            if let Some((schema, encoding)) = schema {
                *slot = Some(add_channel(&mut writer, path, topic, schema, encoding)?);
            }
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
            let (Some(channel), Some(data)) = (channel, data) else {
                continue;
            };
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

    /// The messages of one frame, one per topic of [`RUN_TOPICS`] (`None`: not written).
    fn encode(&self, frame: &RunFrame) -> Result<Vec<Option<Vec<u8>>>, IoError> {
        let info = &self.info.episode;
        let t = frame.time_ns;
        let cam = &info.camera;
        self.check_frame(frame)?;
        let transforms = self.transforms(frame);
        let markers = markers_update(frame);
        let mesh = self.mesh_update(frame);
        let contacts = scene_update(vec![spheres_entity(
            t,
            "world",
            "contacts".into(),
            &frame.contacts_in_world,
            CONTACT_DIAMETER_M,
            CONTACT_COLOR,
        )]);
        let [forces, finger_forces] = self
            .force_messages(frame)?
            .map_or([None, None], |m| m.map(Some));
        let [truth_mesh, truth_contacts, obstacles] = match &frame.truth {
            Some(tr) => self.truth_messages(frame, tr).map(Some),
            None => [None, None, None],
        };
        Ok(vec![
            Some(encode(&color_image(t, cam, &frame.color_rgb8))),
            Some(encode(&camera_calibration(t, cam))),
            Some(encode(&fg::FrameTransforms { transforms })),
            Some(markers),
            Some(mesh),
            Some(contacts),
            forces,
            finger_forces,
            truth_mesh,
            truth_contacts,
            obstacles,
        ])
    }

    /// The error for `frame`, which does not fit the run: `message` says why.
    fn refuse(&self, frame: &RunFrame, message: String) -> IoError {
        let t = frame.time_ns;
        IoError::invalid(&self.path, format!("run frame at {t} ns"), message)
    }

    /// Checks the frame's image, list and vertex sizes against the episode info.
    fn check_frame(&self, frame: &RunFrame) -> Result<(), IoError> {
        let info = &self.info.episode;
        let cam = &info.camera;
        let fingers = info.finger_faces.len();
        let pixels = cam.width as usize * cam.height as usize;
        let refuse = |message: String| Err(self.refuse(frame, message));
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
            // Both empty: no estimate of the finger in this frame (a failed frame).
            let unestimated = v.is_empty() && p.is_empty();
            if !unestimated && (v.len() != n || p.len() != n) {
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
        Ok(())
    }

    /// The frame's transforms: `world→hand`, `hand→camera` and `hand→finger_i`.
    fn transforms(&self, frame: &RunFrame) -> Vec<fg::FrameTransform> {
        let info = &self.info.episode;
        let t = frame.time_ns;
        let mut transforms = vec![
            fg_transform(t, "world", "hand", &frame.world_from_hand),
            fg_transform(t, "hand", "camera", &info.hand_from_camera),
        ];
        for (i, iso) in info.hand_from_finger.iter().enumerate() {
            transforms.push(fg_transform(t, "hand", &format!("finger_{i}"), iso));
        }
        transforms
    }

    /// The `/estimate/mesh` update: every estimated finger mesh coloured by contact probability;
    /// the mesh of a finger without an estimate in this frame is deleted.
    fn mesh_update(&self, frame: &RunFrame) -> Vec<u8> {
        let info = &self.info.episode;
        let t = frame.time_ns;
        let unestimated = |f: usize| frame.vertices_in_hand[f].is_empty();
        let deletions = (0..info.finger_faces.len())
            .filter(|&f| unestimated(f))
            .map(|f| fg::SceneEntityDeletion {
                timestamp: timestamp(t),
                r#type: fg::scene_entity_deletion::Type::MatchingId as i32,
                id: format!("finger_{f}"),
            })
            .collect();
        encode(&fg::SceneUpdate {
            deletions,
            entities: (0..info.finger_faces.len())
                .filter(|&f| !unestimated(f))
                .map(|f| {
                    let colors = frame.contact_probability[f]
                        .iter()
                        .map(|&p| fg_color(probability_rgba(p)).expect("some"))
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
        })
    }

    /// The `/estimate/forces` and `/estimate/finger_force` messages (`None` in a run without
    /// forces); refuses forces that do not fit the run info or the hand.
    fn force_messages(&self, frame: &RunFrame) -> Result<Option<[Vec<u8>; 2]>, IoError> {
        let t = frame.time_ns;
        let fingers = self.info.episode.finger_faces.len();
        match (&frame.forces, self.info.force_arrow_m_per_n) {
            (None, None) => Ok(None),
            (Some(_), None) => Err(self.refuse(
                frame,
                "carries forces, but the run info has no force_arrow_m_per_n".to_owned(),
            )),
            (None, Some(_)) => Err(self.refuse(
                frame,
                "carries no forces in a run with forces (force_arrow_m_per_n)".to_owned(),
            )),
            (Some(fo), Some(scale)) => {
                if let Err(message) = check_forces(fo, fingers) {
                    return Err(self.refuse(frame, message));
                }
                Ok(Some([
                    scene_update(vec![arrows_entity(t, &fo.loads, scale)]),
                    finger_forces_message(t, fo, &self.path)?,
                ]))
            }
        }
    }

    /// The `/truth/mesh`, `/truth/contacts` and `/obstacles` updates of the ground truth `tr`.
    fn truth_messages(&self, frame: &RunFrame, tr: &RunTruth) -> [Vec<u8>; 3] {
        let info = &self.info.episode;
        let t = frame.time_ns;
        let fingers = info.finger_faces.len();
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
        [
            scene_update(entities),
            scene_update(vec![spheres_entity(
                t,
                "world",
                "true_contacts".into(),
                &points,
                0.002,
                [1.0, 0.85, 0.0, 1.0],
            )]),
            scene_update(obstacles),
        ]
    }
}

/// A `SceneUpdate` of `entities` (no deletions), encoded.
fn scene_update(entities: Vec<fg::SceneEntity>) -> Vec<u8> {
    encode(&fg::SceneUpdate {
        deletions: vec![],
        entities,
    })
}

/// The `/estimate/markers` update: every finger's detected markers, hand frame.
fn markers_update(frame: &RunFrame) -> Vec<u8> {
    let t = frame.time_ns;
    scene_update(
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
                    MARKER_DIAMETER_M,
                    MARKER_COLOR,
                )
            })
            .collect(),
    )
}

/// Checks a frame's forces against the hand; the message says what does not fit.
fn check_forces(fo: &RunForces, fingers: usize) -> Result<(), String> {
    if fo.finger_force_n.len() != fingers {
        return Err(format!(
            "{} finger forces for {fingers} fingers",
            fo.finger_force_n.len()
        ));
    }
    if let Some(p) = &fo.pressed_probability
        && p.len() != fingers
    {
        return Err(format!(
            "{} pressed probabilities for {fingers} fingers",
            p.len()
        ));
    }
    if let Some(f) = fo
        .finger_force_n
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(format!("the force on finger {f} is not finite"));
    }
    for (i, l) in fo.loads.iter().enumerate() {
        if l.finger >= fingers {
            return Err(format!(
                "load {i} is on finger {} of {fingers} fingers",
                l.finger
            ));
        }
        if !(l.location_in_hand.iter().all(|c| c.is_finite())
            && l.force_n.iter().all(|c| c.is_finite()))
        {
            return Err(format!("load {i} has a non-finite place or force"));
        }
    }
    Ok(())
}

/// The loads as arrows in the hand frame: each ends at its place and points along its force,
/// `scale` metres long per newton (a load without force draws nothing).
fn arrows_entity(time_ns: u64, loads: &[RunLoad], scale: f64) -> fg::SceneEntity {
    let arrows = loads
        .iter()
        .filter_map(|l| {
            let magnitude = l.force_n.norm();
            let direction = l.force_n.try_normalize(1e-12)?;
            let length = scale * magnitude;
            let tail = l.location_in_hand - length * direction;
            let rotation =
                UnitQuat::rotation_between(&Vector3::x(), &direction).unwrap_or_else(|| {
                    UnitQuat::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
                });
            Some(fg::ArrowPrimitive {
                pose: Some(fg_pose(&tail, &rotation)),
                shaft_length: 0.75 * length,
                shaft_diameter: 0.0015,
                head_length: 0.25 * length,
                head_diameter: 0.0035,
                color: fg_color(FORCE_COLOR),
            })
        })
        .collect();
    fg::SceneEntity {
        timestamp: timestamp(time_ns),
        frame_id: "hand".to_owned(),
        id: "forces".to_owned(),
        arrows,
        ..Default::default()
    }
}

/// The `/estimate/finger_force` message of a frame.
fn finger_forces_message(time_ns: u64, fo: &RunForces, path: &Path) -> Result<Vec<u8>, IoError> {
    let message = FingerForcesMessage {
        timestamp: JsonTime {
            sec: time_ns / 1_000_000_000,
            nsec: (time_ns % 1_000_000_000) as u32,
        },
        frame_id: "hand".to_owned(),
        fingers: fo
            .finger_force_n
            .iter()
            .enumerate()
            .map(|(f, v)| FingerForceMessage {
                finger: f,
                x_n: v.x,
                y_n: v.y,
                z_n: v.z,
                magnitude_n: v.norm(),
                pressed_probability: fo.pressed_probability.as_ref().map(|p| p[f]),
                loads: fo.loads.iter().filter(|l| l.finger == f).count(),
            })
            .collect(),
    };
    serde_json::to_vec(&message)
        .map_err(|e| IoError::invalid(path, format!("run frame at {time_ns} ns"), e.to_string()))
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
    moe_io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests;
