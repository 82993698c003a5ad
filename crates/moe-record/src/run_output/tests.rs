//! Tests of `run_output`.

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
        force_arrow_m_per_n: None,
    }
}

fn forces() -> RunForces {
    RunForces {
        finger_force_n: vec![Vector3::new(0.0, 0.0, -0.2)],
        pressed_probability: Some(vec![0.9]),
        loads: vec![RunLoad {
            finger: 0,
            location_in_hand: Point3::new(0.01, 0.0, 0.0),
            force_n: Vector3::new(0.0, 0.0, -0.2),
        }],
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
        forces: None,
    }
}

fn write(frames: &[RunFrame]) -> Result<Vec<u8>, IoError> {
    write_with(&info(), frames)
}

fn write_with(info: &RunInfo, frames: &[RunFrame]) -> Result<Vec<u8>, IoError> {
    let mut w = RunWriter::new(std::io::Cursor::new(Vec::new()), info, Path::new("r.mcap"))?;
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
    // Without forces, no force topics.
    assert_eq!(topics.len(), RUN_TOPICS.len() - 2 + 1);
    assert!(!topics.iter().any(|(t, _)| t.starts_with("/estimate/f")));
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
fn a_run_with_forces_draws_arrows_and_a_plottable_message() {
    let mut info = info();
    info.force_arrow_m_per_n = Some(0.1);
    let mut f = frame(false);
    f.forces = Some(forces());
    let mut quiet = frame(false);
    quiet.time_ns = 1_500_000_007;
    quiet.forces = Some(RunForces {
        finger_force_n: vec![Vector3::zeros()],
        pressed_probability: Some(vec![0.0]),
        loads: vec![],
    });
    let bytes = write_with(&info, &[f, quiet]).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let schema_of_topic = |topic: &str| {
        summary
            .channels
            .values()
            .find(|c| c.topic == topic)
            .and_then(|c| {
                c.schema
                    .as_ref()
                    .map(|s| (s.name.clone(), s.encoding.clone()))
            })
    };
    assert_eq!(
        schema_of_topic("/estimate/forces"),
        Some(("foxglove.SceneUpdate".into(), "protobuf".into()))
    );
    assert_eq!(
        schema_of_topic("/estimate/finger_force"),
        Some(("moe.FingerForces".into(), "jsonschema".into()))
    );
    let mut arrows = Vec::new();
    let mut plots = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/estimate/forces" => {
                let u = <fg::SceneUpdate as foxglove::Decode>::decode(&m.data[..]).unwrap();
                assert_eq!(u.entities.len(), 1);
                assert_eq!(u.entities[0].frame_id, "hand");
                arrows.push(u.entities[0].arrows.clone());
            }
            "/estimate/finger_force" => {
                assert_eq!(m.channel.message_encoding, "json");
                let body: FingerForcesMessage = serde_json::from_slice(&m.data).unwrap();
                plots.push((m.log_time, body));
            }
            _ => {}
        }
    }
    // One arrow in the first frame, none in the second (the arrows are replaced).
    assert_eq!(arrows.len(), 2);
    assert_eq!(arrows[0].len(), 1);
    assert!(arrows[1].is_empty());
    let a = &arrows[0][0];
    // 0.2 N at 0.1 m/N: 20 mm long, pointing along −z and ending at the load's place.
    assert!((a.shaft_length + a.head_length - 0.02).abs() < 1e-12);
    let pose = a.pose.unwrap();
    let p = pose.position.unwrap();
    let q = pose.orientation.unwrap();
    let rotation = UnitQuat::new_normalize(moe_geom::nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
    let direction = rotation * Vector3::x();
    assert!(
        (direction - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-9,
        "{direction}"
    );
    let tip = Point3::new(p.x, p.y, p.z) + 0.02 * direction;
    assert!((tip - Point3::new(0.01, 0.0, 0.0)).norm() < 1e-12, "{tip}");
    assert_eq!(plots.len(), 2);
    let (time, first) = &plots[0];
    assert_eq!(*time, 5);
    assert_eq!(first.fingers.len(), 1);
    assert!((first.fingers[0].magnitude_n - 0.2).abs() < 1e-12);
    assert_eq!(first.fingers[0].z_n, -0.2);
    assert_eq!(first.fingers[0].loads, 1);
    assert_eq!(first.fingers[0].pressed_probability, Some(0.9));
    assert_eq!(
        plots[1].1.timestamp,
        JsonTime {
            sec: 1,
            nsec: 500_000_007
        }
    );
    assert_eq!(plots[1].1.fingers[0].magnitude_n, 0.0);

    // Forces that do not fit, or forces in a run without them (and the reverse): refused.
    let refused = |info: &RunInfo, f: RunFrame, what: &str| {
        moe_geom::assert_err!(
            write_with(info, &[f]),
            IoError::InvalidData { message, .. } if message.contains(what),
            "{what}"
        );
    };
    let mut f = frame(false);
    f.forces = Some(forces());
    refused(&super::tests::info(), f.clone(), "no force_arrow_m_per_n");
    refused(&info, frame(false), "carries no forces");
    let mut bad = f.clone();
    bad.forces.as_mut().unwrap().loads[0].finger = 1;
    refused(&info, bad, "load 0 is on finger 1 of 1 fingers");
    let mut bad = f.clone();
    bad.forces
        .as_mut()
        .unwrap()
        .finger_force_n
        .push(Vector3::zeros());
    refused(&info, bad, "2 finger forces for 1 fingers");
    let mut bad = f;
    bad.forces.as_mut().unwrap().loads[0].force_n.x = f64::NAN;
    refused(&info, bad, "load 0 has a non-finite place or force");
    let mut zero = info.clone();
    zero.force_arrow_m_per_n = Some(0.0);
    moe_geom::assert_err!(write_with(&zero, &[]), IoError::InvalidData { .. });
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

/// A frame without an estimate (a failed frame) is written with its image and markers, and its
/// finger meshes are deleted from the scene rather than drawn; one list empty and the other
/// not is still refused.
#[test]
fn a_frame_without_an_estimate_deletes_its_meshes() {
    let mut failed = frame(true);
    failed.time_ns = 9;
    failed.vertices_in_hand = vec![Vec::new()];
    failed.contact_probability = vec![Vec::new()];
    failed.contacts_in_world.clear();
    let bytes = write(&[frame(true), failed]).unwrap();
    let mut meshes = Vec::new();
    let mut images = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/estimate/mesh" => {
                let u = <fg::SceneUpdate as foxglove::Decode>::decode(&m.data[..]).unwrap();
                meshes.push((
                    m.log_time,
                    u.entities.iter().map(|e| e.id.clone()).collect::<Vec<_>>(),
                    u.deletions.iter().map(|d| d.id.clone()).collect::<Vec<_>>(),
                ));
            }
            "/camera/color" => images += 1,
            _ => {}
        }
    }
    assert_eq!(images, 2);
    assert_eq!(
        meshes,
        [
            (5, vec!["finger_0".to_owned()], vec![]),
            (9, vec![], vec!["finger_0".to_owned()]),
        ]
    );
    let mut half = frame(true);
    half.vertices_in_hand = vec![Vec::new()];
    assert!(write(&[half]).is_err());
}
