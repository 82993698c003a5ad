//! Recording simulated episodes: what the wrist camera sees of a scene, with the ground truth
//! attached, frame by frame, ready for `moe_record::EpisodeWriter`.

use moe_geom::{HandModel, Iso3, Point3};
use moe_record::{EpisodeFrame, EpisodeInfo, ObstacleMesh};
use moe_tendon_sim::camera::{RenderItem, RgbdCamera};
use moe_tendon_sim::{ActuationMode, Scene, SimError, SimFrame, obstacle_surface};

/// Radius of the painted red markers, metres (5 mm stickers).
pub const MARKER_RADIUS_M: f64 = 0.0025;
pub use moe_tendon_sim::camera::{FINGER_ALBEDO, OBSTACLE_ALBEDO};

/// The marker centres of every finger of `hand` whose vertices (hand frame) are `fingers`.
pub fn markers_of(hand: &HandModel, fingers: &[&[Point3]]) -> Vec<Vec<Point3>> {
    hand.fingers()
        .iter()
        .zip(fingers)
        .map(|(f, v)| {
            f.model
                .marker_vertices()
                .iter()
                .map(|&m| v[m as usize])
                .collect()
        })
        .collect()
}

/// What the wrist camera renders of the hand: one item per finger, the silicone colour with
/// the markers (`markers`, as [`markers_of`] gives them) painted red.
pub fn finger_items<'a>(
    hand: &'a HandModel,
    fingers: &[&'a [Point3]],
    markers: &'a [Vec<Point3>],
) -> Vec<RenderItem<'a>> {
    hand.fingers()
        .iter()
        .zip(fingers)
        .zip(markers)
        .map(|((f, v), m)| RenderItem {
            vertices_in_hand: v,
            faces: f.model.mesh().faces(),
            albedo: FINGER_ALBEDO,
            markers_in_hand: m,
            marker_radius_m: MARKER_RADIUS_M,
        })
        .collect()
}

/// The vertices of `obstacles` (world frame) in the hand frame of a hand at `world_from_hand`.
pub fn obstacles_in_hand(world_from_hand: &Iso3, obstacles: &[ObstacleMesh]) -> Vec<Vec<Point3>> {
    let hand_from_world = world_from_hand.inverse();
    obstacles
        .iter()
        .map(|o| {
            o.vertices_in_world
                .iter()
                .map(|p| hand_from_world * p)
                .collect()
        })
        .collect()
}

/// The saved frame nearest in time to `t` seconds, with its index (`None` when nothing was
/// saved).
pub fn saved_frame_at(frames: &[SimFrame], t: f64) -> Option<(usize, &SimFrame)> {
    frames.iter().enumerate().min_by(|a, b| {
        (a.1.time_secs - t)
            .abs()
            .total_cmp(&(b.1.time_secs - t).abs())
    })
}

/// Records a scene's saved frames as episode frames.
#[derive(Debug)]
pub struct EpisodeRecorder {
    camera: RgbdCamera,
    info: EpisodeInfo,
    /// Obstacle surfaces in their own frames.
    obstacle_surfaces: Vec<(Vec<Point3>, Vec<[u32; 3]>)>,
    seed: u64,
}

impl EpisodeRecorder {
    /// Prepares the recording of `scene` (named `name`) with the scene's camera; `seed` fixes the
    /// sensor noise.
    ///
    /// # Errors
    /// An obstacle whose surface cannot be meshed; [`SimError::ForceDriven`] for a scene with a
    /// force-driven finger (an episode records tendon pulls in metres, not tensions);
    /// [`SimError::Geometry`] for fingers with different numbers of tendons.
    pub fn new(scene: &Scene, name: &str, seed: u64) -> Result<Self, SimError> {
        if let Some(finger) = scene
            .config()
            .actuation
            .iter()
            .position(|s| s.mode == ActuationMode::Force)
        {
            return Err(SimError::ForceDriven { finger, tendon: 0 });
        }
        let camera = scene.config().camera;
        let hand = scene.hand();
        let info = EpisodeInfo::for_hand(
            name,
            camera.intrinsics.into(),
            *camera.hand_from_camera.iso(),
            hand,
        )?;
        let obstacle_surfaces = scene
            .config()
            .obstacles
            .iter()
            .map(|o| obstacle_surface(&o.shape))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            camera,
            info,
            obstacle_surfaces,
            seed,
        })
    }

    /// The episode's fixed information.
    pub fn info(&self) -> &EpisodeInfo {
        &self.info
    }

    /// Renders the camera images of a saved frame and packs it with its ground truth.
    ///
    /// # Errors
    /// Invalid camera parameters; [`SimError::ForceDriven`] for a force-driven tendon, which
    /// an episode cannot record (it records pulls in metres).
    pub fn frame(
        &self,
        scene: &Scene,
        saved: &SimFrame,
        index: u64,
    ) -> Result<EpisodeFrame, SimError> {
        let frame = saved;
        let t = frame.time_secs;
        let finger_vertices: Vec<&[Point3]> = frame
            .fingers
            .iter()
            .map(|g| g.vertices_in_hand.as_slice())
            .collect();
        let markers_in_hand = markers_of(scene.hand(), &finger_vertices);
        let obstacles: Vec<ObstacleMesh> = scene
            .obstacles()
            .iter()
            .zip(&self.obstacle_surfaces)
            .enumerate()
            .map(|(k, (o, (v, f)))| {
                let pose: Iso3 = o.pose_at(t);
                ObstacleMesh {
                    name: format!("obstacle_{k}"),
                    vertices_in_world: v.iter().map(|p| pose * p).collect(),
                    faces: f.clone(),
                }
            })
            .collect();
        let obstacle_in_hand = obstacles_in_hand(&frame.world_from_hand, &obstacles);
        let mut items = finger_items(scene.hand(), &finger_vertices, &markers_in_hand);
        for (o, v) in obstacles.iter().zip(&obstacle_in_hand) {
            items.push(RenderItem {
                vertices_in_hand: v,
                faces: &o.faces,
                albedo: OBSTACLE_ALBEDO,
                markers_in_hand: &[],
                marker_radius_m: 0.0,
            });
        }
        let image = self.camera.render(&items, self.seed.wrapping_add(index))?;
        Ok(EpisodeFrame {
            time_ns: (t * 1e9).round() as u64,
            color_rgb8: image.color,
            depth_m: image.depth_m,
            world_from_hand: frame.world_from_hand,
            tendon_pull_m: saved.tendon_pulls_m()?,
            finger_vertices_in_hand: frame
                .fingers
                .iter()
                .map(|g| g.vertices_in_hand.clone())
                .collect(),
            contact_vertices: frame
                .fingers
                .iter()
                .map(|g| {
                    g.labels
                        .iter()
                        .enumerate()
                        .filter(|(_, l)| **l)
                        .map(|(i, _)| i as u32)
                        .collect()
                })
                .collect(),
            markers_in_hand,
            obstacles,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_tendon_sim::{ActuationKeyframe, ActuationSchedule, SceneConfig};

    #[test]
    fn force_driven_scenes_are_not_recorded() {
        let schedule = |mode| ActuationSchedule {
            mode,
            keyframes: vec![ActuationKeyframe {
                time_secs: 0.0,
                values: vec![0.0; 4],
            }],
        };
        let config = |second| SceneConfig {
            duration_secs: 0.01,
            actuation: vec![schedule(ActuationMode::Displacement), schedule(second)],
            ..SceneConfig::default()
        };
        let scene = Scene::new(config(ActuationMode::Force)).unwrap();
        assert!(matches!(
            EpisodeRecorder::new(&scene, "force", 0),
            Err(SimError::ForceDriven {
                finger: 1,
                tendon: 0
            })
        ));
        let scene = Scene::new(config(ActuationMode::Displacement)).unwrap();
        assert!(EpisodeRecorder::new(&scene, "pull", 0).is_ok());
    }

    #[test]
    fn hands_with_uneven_tendon_counts_are_not_recorded() {
        use moe_geom::{FingerModel, FingerParams, HandPreset};
        let preset = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let mut fingers = preset.fingers().to_vec();
        let f = &fingers[1].model;
        fingers[1].model = FingerModel::from_parts(
            f.mesh().clone(),
            f.marker_vertices().to_vec(),
            f.base_vertices().to_vec(),
            f.tendon_routes()[..2].to_vec(),
        )
        .unwrap();
        let config = SceneConfig {
            duration_secs: 0.01,
            ..SceneConfig::default()
        };
        let scene = Scene::with_hand(config, HandModel::new(fingers).unwrap()).unwrap();
        assert!(matches!(
            EpisodeRecorder::new(&scene, "uneven", 0),
            Err(SimError::Geometry(
                moe_geom::GeomError::FingerLengthMismatch {
                    finger: 1,
                    expected: 4,
                    got: 2,
                    ..
                }
            ))
        ));
    }
}
