//! Dumps an episode's sensor data as plain files, for tools outside Rust (such as
//! `tools/episode_to_rosbag.py`, which writes it as a ROS 2 recording with another library):
//! `frames.json` (intrinsics, the camera's mounting, and per frame its time, the hand's pose and
//! the tendon pulls) and `color_K.bin` (RGB8) / `depth_K.bin` (f32 metres, little-endian) per
//! frame `K`.
//!
//! `cargo run -p moe-record --example export_episode -- EP.mcap OUT_DIR`

use std::path::PathBuf;

use moe_geom::Iso3;

fn pose(iso: &Iso3) -> serde_json::Value {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    serde_json::json!({ "translation": [t.x, t.y, t.z], "rotation_xyzw": [q.i, q.j, q.k, q.w] })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [episode, out] = args.as_slice() else {
        return Err("usage: export_episode EP.mcap OUT_DIR".into());
    };
    let episode = moe_record::read_episode(episode.as_ref())?;
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)?;
    let mut frames = Vec::new();
    for (k, f) in episode.frames.iter().enumerate() {
        std::fs::write(out.join(format!("color_{k}.bin")), &f.color_rgb8)?;
        let depth: Vec<u8> = f.depth_m.iter().flat_map(|d| d.to_le_bytes()).collect();
        std::fs::write(out.join(format!("depth_{k}.bin")), depth)?;
        frames.push(serde_json::json!({
            "time_ns": f.time_ns,
            "world_from_hand": pose(&f.world_from_hand),
            "tendon_pull_m": f.tendon_pull_m,
        }));
    }
    let c = episode.info.camera;
    let doc = serde_json::json!({
        "camera": { "width": c.width, "height": c.height, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy },
        "hand_from_camera": pose(&episode.info.hand_from_camera),
        "frames": frames,
    });
    std::fs::write(out.join("frames.json"), serde_json::to_string_pretty(&doc)?)?;
    println!("{} frames to {}", episode.frames.len(), out.display());
    Ok(())
}
