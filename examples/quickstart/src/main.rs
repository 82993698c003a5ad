//! The README's Rust example: the physics pipeline over the committed demo episode (a plate
//! pressing a fingertip), run from the repository's root: `cargo run -p moe-touch-quickstart`.
//! Its only dependency is `moe-touch`; it prints what `python/examples/quickstart.py` prints.

use moe_touch::moe_io::read_config;
use moe_touch::moe_record::read_episode;
use moe_touch::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let episode = read_episode("fixtures/episodes/plate_tip_front_small.mcap".as_ref())?;
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default())?;
    let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())?;
    let settings: PhysicsConfig = read_config("fixtures/physics/occluding-contact.toml".as_ref())?;
    let mut pipeline = Pipeline::physics(hand, detector, &HandMaterial::default(), &settings)?;
    for frame in &episode.frames {
        // The frame's images, and what the robot knows of it: tendon pulls, wrist pose, time.
        let r = pipeline.process(frame.rgbd(), &frame.observation())?;
        let forces_mn: Vec<String> = r
            .details
            .finger_forces_n()
            .iter()
            .map(|f| format!("{:.1}", 1e3 * f.norm()))
            .collect();
        println!(
            "{:.2} s: {} markers, {} contact points, finger forces [{}] mN",
            frame.time_secs(),
            r.markers.found,
            r.contacts_in_world.len(),
            forces_mn.join(", ")
        );
    }
    Ok(())
}
