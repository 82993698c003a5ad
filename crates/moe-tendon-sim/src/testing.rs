//! Fixtures for tests and benchmarks: scenes that model no experiment and exist to pin the
//! simulator's behaviour (golden digests, step timings). The paper's scenes are in
//! [`paper_scenes`](crate::paper_scenes).

use moe_geom::FingerParams;

use crate::obstacle::{ObstacleConfig, ObstacleShape};
use crate::scene::SceneConfig;
use crate::trajectory::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, PoseKeyframe, PoseTrajectory,
};

/// A short regression scene (8 steps) whose rounded state digest is pinned by the golden
/// fixture `fixtures/golden/sim_short_scene.json`: a two-finger hand, finger 0 pulls its +x
/// tendon, a plate presses finger 1's outer side, the wrist moves up slowly.
pub fn golden_short_scene() -> SceneConfig {
    let p = FingerParams::default();
    SceneConfig {
        duration_secs: 0.08,
        wrist: PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(0.0, [0.0, 0.0, 0.0]),
                PoseKeyframe::at(1.0, [0.0, 0.0, 0.01]),
            ],
        },
        actuation: vec![ActuationSchedule {
            mode: ActuationMode::Displacement,
            keyframes: vec![
                ActuationKeyframe {
                    time_secs: 0.0,
                    values: vec![0.0; 4],
                },
                ActuationKeyframe {
                    time_secs: 0.1,
                    values: vec![0.002, -0.002, 0.0, 0.0],
                },
            ],
        }],
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.001, 0.03, 0.02],
            },
            // Finger 1 sits at x = −0.025 with its +x side facing the palm axis; its outer side
            // is at x ≈ −0.025 − r.
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [-0.025 - p.radius_at(0.03) - 0.0015, 0.0, 0.05]),
                    PoseKeyframe::at(0.08, [-0.025 - p.radius_at(0.03) + 0.002, 0.0, 0.05]),
                ],
            },
        }],
        ..SceneConfig::default()
    }
}
