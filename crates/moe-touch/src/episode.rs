//! Recording simulated episodes: what the wrist camera sees of a scene, with the ground truth
//! attached, frame by frame, ready for `moe_io::EpisodeWriter`.

use moe_geom::{Iso3, Point3};
use moe_io::{CameraInfo, EpisodeFrame, EpisodeInfo, ObstacleMesh};
use moe_tendon_sim::camera::{RenderItem, RgbdCamera};
use moe_tendon_sim::randomize::TrajectoryFrame;
use moe_tendon_sim::surface::obstacle_surface;
use moe_tendon_sim::{Scene, SimError};

/// Radius of the painted red markers, metres (5 mm stickers).
pub const MARKER_RADIUS_M: f64 = 0.0025;
/// Colour of the silicone fingers in the rendered images.
pub const FINGER_ALBEDO: [u8; 3] = [215, 210, 200];
/// Colour of obstacles in the rendered images.
pub const OBSTACLE_ALBEDO: [u8; 3] = [90, 120, 170];

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
    /// An obstacle whose surface cannot be meshed.
    pub fn new(scene: &Scene, name: &str, seed: u64) -> Result<Self, SimError> {
        let camera = scene.config().camera;
        let k = camera.intrinsics;
        let hand = scene.hand();
        let info = EpisodeInfo {
            scene: name.to_owned(),
            camera: CameraInfo {
                width: k.width,
                height: k.height,
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            hand_from_camera: *camera.hand_from_camera.iso(),
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
            tendons_per_finger: hand
                .fingers()
                .first()
                .map_or(0, |f| f.model.tendon_routes().len()),
        };
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
    /// Invalid camera parameters.
    pub fn frame(
        &self,
        scene: &Scene,
        saved: &TrajectoryFrame,
        index: u64,
    ) -> Result<EpisodeFrame, SimError> {
        let frame = &saved.frame;
        let t = frame.time_secs;
        let hand_from_world = frame.world_from_hand.inverse();
        let markers_in_hand: Vec<Vec<Point3>> = frame
            .fingers
            .iter()
            .zip(scene.hand().fingers())
            .map(|(g, f)| {
                f.model
                    .marker_vertices()
                    .iter()
                    .map(|&m| g.vertices_in_hand[m as usize])
                    .collect()
            })
            .collect();
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
        let obstacle_in_hand: Vec<Vec<Point3>> = obstacles
            .iter()
            .map(|o| {
                o.vertices_in_world
                    .iter()
                    .map(|p| hand_from_world * p)
                    .collect()
            })
            .collect();
        let mut items: Vec<RenderItem<'_>> = frame
            .fingers
            .iter()
            .zip(scene.hand().fingers())
            .zip(&markers_in_hand)
            .map(|((g, f), m)| RenderItem {
                vertices_in_hand: &g.vertices_in_hand,
                faces: f.model.mesh().faces(),
                albedo: FINGER_ALBEDO,
                markers_in_hand: m,
                marker_radius_m: MARKER_RADIUS_M,
            })
            .collect();
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
            tendon_pull_m: saved.tendon_values.clone(),
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
