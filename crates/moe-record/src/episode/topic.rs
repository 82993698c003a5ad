//! The per-frame topics of an episode: each topic's name, schema, encoder and decoder in one
//! place.

use std::path::Path;

use foxglove::messages as fg;
use moe_geom::{Iso3, Point3};
use serde::{Deserialize, Serialize};

use super::foxglove::{
    camera_calibration, color_image, contact_mesh_entity, decode, encode, faces_of, fg_transform,
    first_triangles, format_err, iso_from, obstacle_entities, points_of, schema_of, spheres_entity,
    timestamp,
};
use super::{EpisodeFrame, EpisodeInfo, ObstacleMesh};
use moe_io::IoError;

/// The episode info's topic (one message, before any frame).
pub(super) const INFO_TOPIC: &str = "/episode/info";

/// JSON body of `/hand/contacts`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactLabels {
    fingers: Vec<Vec<u32>>,
}

/// One per-frame topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Topic {
    /// `/camera/color`: `foxglove.RawImage`, `rgb8`.
    Color,
    /// `/camera/depth`: `foxglove.RawImage`, `32FC1` metres.
    Depth,
    /// `/camera/calibration`: `foxglove.CameraCalibration`.
    Calibration,
    /// `/tf`: `foxglove.FrameTransforms`.
    Transforms,
    /// `/hand/tendons`: `foxglove.JointStates`.
    Tendons,
    /// `/hand/mesh`: `foxglove.SceneUpdate`, true finger meshes coloured by contact.
    HandMesh,
    /// `/hand/contacts`: `moe.ContactLabels` (JSON).
    Contacts,
    /// `/hand/markers`: `foxglove.SceneUpdate`, true marker centres.
    Markers,
    /// `/obstacles`: `foxglove.SceneUpdate`, obstacle meshes in the world frame.
    Obstacles,
}

/// A frame's contents as its topics are decoded, before they are put together.
#[derive(Debug, Default)]
pub(super) struct FrameParts {
    color_rgb8: Option<Vec<u8>>,
    depth_m: Option<Vec<f32>>,
    world_from_hand: Option<Iso3>,
    tendon_pull_m: Option<Vec<Vec<f64>>>,
    finger_vertices_in_hand: Option<Vec<Vec<Point3>>>,
    contact_vertices: Option<Vec<Vec<u32>>>,
    markers_in_hand: Option<Vec<Vec<Point3>>>,
    obstacles: Option<Vec<ObstacleMesh>>,
}

impl FrameParts {
    /// The frame, once every topic has been decoded.
    pub(super) fn into_frame(self, time_ns: u64) -> Option<EpisodeFrame> {
        Some(EpisodeFrame {
            time_ns,
            color_rgb8: self.color_rgb8?,
            depth_m: self.depth_m?,
            world_from_hand: self.world_from_hand?,
            tendon_pull_m: self.tendon_pull_m?,
            finger_vertices_in_hand: self.finger_vertices_in_hand?,
            contact_vertices: self.contact_vertices?,
            markers_in_hand: self.markers_in_hand?,
            obstacles: self.obstacles?,
        })
    }
}

impl Topic {
    /// Every topic, in the order each frame writes them.
    pub(super) const ALL: [Topic; 9] = [
        Topic::Color,
        Topic::Depth,
        Topic::Calibration,
        Topic::Transforms,
        Topic::Tendons,
        Topic::HandMesh,
        Topic::Contacts,
        Topic::Markers,
        Topic::Obstacles,
    ];

    /// The topic's name.
    pub(super) fn name(self) -> &'static str {
        match self {
            Topic::Color => "/camera/color",
            Topic::Depth => "/camera/depth",
            Topic::Calibration => "/camera/calibration",
            Topic::Transforms => "/tf",
            Topic::Tendons => "/hand/tendons",
            Topic::HandMesh => "/hand/mesh",
            Topic::Contacts => "/hand/contacts",
            Topic::Markers => "/hand/markers",
            Topic::Obstacles => "/obstacles",
        }
    }

    /// The topic of a name, `None` for topics of other tools.
    pub(super) fn from_name(name: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Schema (name, encoding, data) and message encoding.
    pub(super) fn schema(self) -> ((String, String, Vec<u8>), &'static str) {
        match self {
            Topic::Color | Topic::Depth => (schema_of::<fg::RawImage>(), "protobuf"),
            Topic::Calibration => (schema_of::<fg::CameraCalibration>(), "protobuf"),
            Topic::Transforms => (schema_of::<fg::FrameTransforms>(), "protobuf"),
            Topic::Tendons => (schema_of::<fg::JointStates>(), "protobuf"),
            Topic::HandMesh | Topic::Markers | Topic::Obstacles => {
                (schema_of::<fg::SceneUpdate>(), "protobuf")
            }
            Topic::Contacts => (
                (
                    "moe.ContactLabels".to_owned(),
                    "jsonschema".to_owned(),
                    br#"{"type":"object"}"#.to_vec(),
                ),
                "json",
            ),
        }
    }

    /// The topic's message for `frame` (checked against `info` already).
    pub(super) fn encode(
        self,
        path: &Path,
        info: &EpisodeInfo,
        frame: &EpisodeFrame,
    ) -> Result<Vec<u8>, IoError> {
        let t = frame.time_ns;
        let cam = &info.camera;
        let update = |entities: Vec<fg::SceneEntity>| {
            encode(&fg::SceneUpdate {
                deletions: vec![],
                entities,
            })
        };
        Ok(match self {
            Topic::Color => encode(&color_image(t, cam, &frame.color_rgb8)),
            Topic::Depth => encode(&fg::RawImage {
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
            }),
            Topic::Calibration => encode(&camera_calibration(t, cam)),
            Topic::Transforms => {
                let mut transforms = vec![
                    fg_transform(t, "world", "hand", &frame.world_from_hand),
                    fg_transform(t, "hand", "camera", &info.hand_from_camera),
                ];
                for (i, iso) in info.hand_from_finger.iter().enumerate() {
                    transforms.push(fg_transform(t, "hand", &format!("finger_{i}"), iso));
                }
                encode(&fg::FrameTransforms { transforms })
            }
            Topic::Tendons => encode(&fg::JointStates {
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
            }),
            Topic::HandMesh => update(
                info.finger_faces
                    .iter()
                    .enumerate()
                    .map(|(f, faces)| {
                        contact_mesh_entity(
                            t,
                            format!("finger_{f}"),
                            &frame.finger_vertices_in_hand[f],
                            faces,
                            &frame.contact_vertices[f],
                        )
                    })
                    .collect(),
            ),
            Topic::Contacts => serde_json::to_vec(&ContactLabels {
                fingers: frame.contact_vertices.clone(),
            })
            .map_err(|e| format_err(path, e.to_string()))?,
            Topic::Markers => update(
                frame
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
            ),
            Topic::Obstacles => update(obstacle_entities(t, &frame.obstacles)),
        })
    }

    /// Decodes the topic's message `data` into `parts`.
    pub(super) fn decode(
        self,
        path: &Path,
        info: &EpisodeInfo,
        data: &[u8],
        parts: &mut FrameParts,
    ) -> Result<(), IoError> {
        let name = self.name();
        match self {
            Topic::Color => {
                let color: fg::RawImage = decode(path, name, data)?;
                parts.color_rgb8 = Some(color.data.to_vec());
            }
            Topic::Depth => {
                let depth: fg::RawImage = decode(path, name, data)?;
                if !depth.data.len().is_multiple_of(4) {
                    return Err(format_err(
                        path,
                        format!("{name}: data length is not a multiple of 4"),
                    ));
                }
                parts.depth_m = Some(
                    depth
                        .data
                        .chunks(4)
                        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                        .collect(),
                );
            }
            // The calibration repeats the episode info's camera.
            Topic::Calibration => {
                let _: fg::CameraCalibration = decode(path, name, data)?;
            }
            Topic::Transforms => {
                let tf: fg::FrameTransforms = decode(path, name, data)?;
                let world_from_hand = tf
                    .transforms
                    .iter()
                    .find(|t| t.parent_frame_id == "world" && t.child_frame_id == "hand")
                    .ok_or_else(|| format_err(path, format!("{name}: no world→hand transform")))
                    .and_then(|t| iso_from(path, t))?;
                parts.world_from_hand = Some(world_from_hand);
            }
            Topic::Tendons => {
                let n = info.hand_from_finger.len();
                let tendons: fg::JointStates = decode(path, name, data)?;
                let mut pulls = vec![Vec::with_capacity(info.tendons_per_finger); n];
                for (k, joint) in tendons.joints.iter().enumerate() {
                    let f = k / info.tendons_per_finger.max(1);
                    let list = pulls.get_mut(f).ok_or_else(|| {
                        format_err(path, format!("{name}: more tendons than fingers hold"))
                    })?;
                    list.push(joint.position.ok_or_else(|| {
                        format_err(path, format!("{name}: {} has no position", joint.name))
                    })?);
                }
                parts.tendon_pull_m = Some(pulls);
            }
            Topic::HandMesh => {
                let hand: fg::SceneUpdate = decode(path, name, data)?;
                parts.finger_vertices_in_hand = Some(
                    hand.entities
                        .iter()
                        .map(|e| first_triangles(path, name, e).map(points_of))
                        .collect::<Result<Vec<_>, _>>()?,
                );
            }
            Topic::Contacts => {
                let contacts: ContactLabels = serde_json::from_slice(data)
                    .map_err(|e| format_err(path, format!("{name}: {e}")))?;
                parts.contact_vertices = Some(contacts.fingers);
            }
            Topic::Markers => {
                let markers: fg::SceneUpdate = decode(path, name, data)?;
                parts.markers_in_hand = Some(
                    markers
                        .entities
                        .iter()
                        .map(|e| {
                            e.spheres
                                .iter()
                                .map(|s| {
                                    let p = s.pose.and_then(|p| p.position).ok_or_else(|| {
                                        format_err(path, format!("{name}: sphere without position"))
                                    })?;
                                    Ok(Point3::new(p.x, p.y, p.z))
                                })
                                .collect::<Result<Vec<_>, IoError>>()
                        })
                        .collect::<Result<Vec<_>, _>>()?,
                );
            }
            Topic::Obstacles => {
                let msg: fg::SceneUpdate = decode(path, name, data)?;
                parts.obstacles = Some(
                    msg.entities
                        .iter()
                        .map(|e| {
                            let tri = first_triangles(path, name, e)?;
                            Ok(ObstacleMesh {
                                name: e.id.clone(),
                                vertices_in_world: points_of(tri),
                                faces: faces_of(path, name, tri)?,
                            })
                        })
                        .collect::<Result<Vec<_>, IoError>>()?,
                );
            }
        }
        Ok(())
    }
}
