//! The per-frame pipeline on the committed episode with the shipped model.

use moe_arap::MultiShapeEstimator;
use moe_arap::ShapeConfig;
use moe_geom::{
    ContactInput, FingerParams, HandEstimator, HandModel, HandPreset, Observation, Staged,
    WorldFromHand,
};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;
use moe_touch::{
    FrameEstimate, FrameStage, PhysicsPipeline, Pipeline, RgbdFrame, StreamEvent, TouchError,
};

use crate::common::fixtures;

pub(crate) fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

pub(crate) fn episode() -> moe_record::Episode {
    moe_record::read_episode(&fixtures().join("episodes/plate_tip_front_small.mcap")).unwrap()
}

fn detector(hand: &HandModel, episode: &moe_record::Episode) -> MarkerDetector {
    MarkerDetector::for_episode(&episode.info, hand, DetectorConfig::default()).unwrap()
}

/// The threshold at which the pipeline-equality test turns probabilities into contact points.
const CHAIN_THRESHOLD: f64 = 0.4;

fn model_path() -> std::path::PathBuf {
    fixtures().join("../models/contact-two-finger.safetensors")
}

/// `moe-touch run` of `episode` through the paper's pipeline with `model`, into `out`; more
/// arguments follow.
fn dgcnn_run<'a>(
    episode: &'a std::path::Path,
    model: &'a std::path::Path,
    out: &'a std::path::Path,
) -> Vec<&'a str> {
    let s = |p: &'a std::path::Path| p.to_str().unwrap();
    vec![
        "run",
        "--episode",
        s(episode),
        "--contact",
        "dgcnn",
        "--model",
        s(model),
        "--out",
        s(out),
    ]
}

#[test]
fn the_pipeline_equals_the_stages_run_one_by_one() {
    let hand = hand();
    let episode = episode();
    let model = load_contact_model(&model_path(), &hand).unwrap();
    // Below the card's threshold, so that the frame chain is checked on contact points whatever
    // the shipped model finds at its own (the equality of the maps does not depend on it).
    let threshold = CHAIN_THRESHOLD.min(model.threshold());
    let options = ShapeConfig::default();
    let mut pipeline = Pipeline::new(
        hand.clone(),
        detector(&hand, &episode),
        Staged::new(
            MultiShapeEstimator::new(hand.clone(), options.clone()).unwrap(),
            load_contact_model(&model_path(), &hand).unwrap(),
        ),
        threshold,
    )
    .unwrap();
    let mut d = detector(&hand, &episode);
    let mut arap = MultiShapeEstimator::new(hand.clone(), options.clone()).unwrap();
    let mut contact_frames = 0;
    for frame in &episode.frames {
        let pose = WorldFromHand::new(frame.world_from_hand);
        let est = pipeline
            .process(frame.rgbd(), &Observation::new().with_world_from_hand(pose))
            .unwrap();
        let det = d.detect(&frame.color_rgb8, &frame.depth_m).unwrap();
        let shape = arap.estimate(&det.keypoints).unwrap().shape;
        let map = model
            .estimate_map(&ContactInput::new(
                &shape,
                Observation::from_keypoints(&det.keypoints),
            ))
            .unwrap();
        assert_eq!(est.keypoints, det.keypoints);
        assert_eq!(est.shape, shape);
        assert_eq!(est.contact, map);
        let points = map.contacts_above(threshold, &shape).unwrap();
        assert_eq!(est.contacts_in_hand, points);
        assert_eq!(est.contacts_in_world.len(), points.len());
        for (w, h) in est.contacts_in_world.iter().zip(&points) {
            assert!((w.point - frame.world_from_hand * h.point).norm() < 1e-12);
            assert_eq!((w.finger, w.vertex), (h.finger, h.vertex));
        }
        contact_frames += usize::from(!points.is_empty());
        let t = est.timings;
        assert!(t.total_ms >= t.markers_ms + t.estimate_ms + t.points_ms - 1e-9);
        assert!(est.fingers_without_markers.is_empty());
    }
    assert!(
        contact_frames > 0,
        "the plate presses the tip: some vertex is above {threshold}"
    );
}

/// What a frame's estimate says apart from its wall times.
fn same_estimate<D: PartialEq + std::fmt::Debug>(a: &FrameEstimate<D>, b: &FrameEstimate<D>) {
    assert_eq!(a.details, b.details);
    assert_eq!(a.vertex_force_n, b.vertex_force_n);
    assert_eq!(a.keypoints, b.keypoints);
    assert_eq!(a.shape, b.shape);
    assert_eq!(a.contact, b.contact);
    assert_eq!(a.contacts_in_hand, b.contacts_in_hand);
    assert_eq!(a.contacts_in_world, b.contacts_in_world);
}

#[test]
fn frames_out_of_order_are_refused_and_a_gap_or_reset_starts_a_fresh_stream() {
    let hand = hand();
    let episode = episode();
    // The paper's chain, whose stages carry marker tracks (and a warm start when asked), and
    // the physics pipeline, which carries the free finger's simulation through the stream.
    stream_contract(&episode, || {
        Pipeline::new(
            hand.clone(),
            detector(&hand, &episode),
            Staged::new(
                MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap(),
                load_contact_model(&model_path(), &hand).unwrap(),
            ),
            CHAIN_THRESHOLD,
        )
        .unwrap()
    });
    stream_contract(&episode, || physics_pipeline(&hand, &episode));
    // The physics pipeline's horizon is its estimator's stream: a gap the estimator does not
    // bridge (0.5 s against its 0.2 s) is reported as a restart, and the frame is a fresh
    // pipeline's.
    let f = &episode.frames;
    let mut p = physics_pipeline(&hand, &episode);
    p.process(f[1].rgbd(), &f[1].observation()).unwrap();
    let mut late = f[2].clone();
    late.time_ns = f[1].time_ns + 500_000_000;
    let after_gap = p.process(late.rgbd(), &late.observation()).unwrap();
    assert!(
        matches!(after_gap.stream, StreamEvent::Restarted { gap_secs } if (gap_secs - 0.5).abs() < 1e-9),
        "{:?}",
        after_gap.stream
    );
    same_estimate(
        &after_gap,
        &physics_pipeline(&hand, &episode)
            .process(late.rgbd(), &late.observation())
            .unwrap(),
    );
}

/// The physics pipeline with the default material and settings.
pub(crate) fn physics_pipeline(hand: &HandModel, episode: &moe_record::Episode) -> PhysicsPipeline {
    PhysicsPipeline::physics(
        hand.clone(),
        detector(hand, episode),
        &moe_physics::HandMaterial::default(),
        &moe_physics::PhysicsConfig::default(),
    )
    .unwrap()
}

/// Out-of-order frames are refused and change nothing; a gap beyond the memory's horizon and
/// `reset()` each start a stream whose estimate is a fresh pipeline's, bit for bit.
fn stream_contract<E>(episode: &moe_record::Episode, make: impl Fn() -> Pipeline<E>)
where
    E: HandEstimator + std::fmt::Debug,
    E::Details: PartialEq + std::fmt::Debug,
{
    let f = &episode.frames;
    let mut p = make();
    assert_eq!(
        p.process(f[0].rgbd(), &f[0].observation()).unwrap().stream,
        StreamEvent::Started
    );
    let gap = match p.process(f[1].rgbd(), &f[1].observation()).unwrap().stream {
        StreamEvent::Continued { gap_secs } => gap_secs,
        other => panic!("{other:?}"),
    };
    assert!((gap - 0.2).abs() < 1e-9, "{gap}");
    // A repeated time and a time back in the stream are refused, naming both times.
    for k in [1, 0] {
        let failure = p.process(f[k].rgbd(), &f[k].observation()).unwrap_err();
        assert_eq!(failure.stage, FrameStage::Input);
        assert_eq!(failure.stream, None);
        let err = failure.error;
        assert!(
            matches!(err, TouchError::StreamOutOfOrder { time_secs, previous_secs }
                if time_secs == 1e-9 * f[k].time_ns as f64 && previous_secs == 0.2),
            "{err}"
        );
        assert!(
            err.to_string()
                .contains("not after the previous frame's 0.2 s"),
            "{err}"
        );
    }
    // Images that do not fit the camera fail perception alone: the markers stage, in the
    // stream at the frame's time, with the stream's memory kept.
    let mut cropped = f[2].clone();
    cropped.depth_m.pop();
    let failure = p
        .process(cropped.rgbd(), &cropped.observation())
        .unwrap_err();
    assert_eq!(failure.stage, FrameStage::Markers);
    assert!(
        matches!(failure.error, TouchError::ImageSize { .. }),
        "{}",
        failure.error
    );
    assert!(matches!(
        failure.stream,
        Some(StreamEvent::Continued { .. })
    ));
    assert!(failure.keypoints.is_none());
    // The refused frames changed nothing, nor did the failed perception but for the time it
    // took in the stream: the next frame is that of a stream that skipped frame 2's time.
    let mut undisturbed = make();
    undisturbed
        .process(f[0].rgbd(), &f[0].observation())
        .unwrap();
    undisturbed
        .process(f[1].rgbd(), &f[1].observation())
        .unwrap();
    let mut f2 = f[2].clone();
    f2.time_ns += 1;
    let skipped = p.process(f2.rgbd(), &f2.observation()).unwrap();
    let mut after_skip = make();
    after_skip
        .process(f[0].rgbd(), &f[0].observation())
        .unwrap();
    after_skip
        .process(f[1].rgbd(), &f[1].observation())
        .unwrap();
    same_estimate(
        &skipped,
        &after_skip.process(f2.rgbd(), &f2.observation()).unwrap(),
    );
    let mut p = make();
    p.process(f[0].rgbd(), &f[0].observation()).unwrap();
    p.process(f[1].rgbd(), &f[1].observation()).unwrap();
    same_estimate(
        &p.process(f[2].rgbd(), &f[2].observation()).unwrap(),
        &undisturbed
            .process(f[2].rgbd(), &f[2].observation())
            .unwrap(),
    );
    // A gap beyond the horizon: the stream restarts, and says so, as a fresh pipeline.
    let mut late = f[3].clone();
    late.time_ns += 5_000_000_000;
    let after_gap = p.process(late.rgbd(), &late.observation()).unwrap();
    match after_gap.stream {
        StreamEvent::Restarted { gap_secs } => assert!((gap_secs - 5.2).abs() < 1e-9),
        other => panic!("{other:?}"),
    }
    same_estimate(
        &after_gap,
        &make().process(late.rgbd(), &late.observation()).unwrap(),
    );
    // reset: the next frame starts a stream, whatever its time, as in a fresh pipeline.
    p.reset();
    let again = p.process(f[4].rgbd(), &f[4].observation()).unwrap();
    assert_eq!(again.stream, StreamEvent::Started);
    same_estimate(
        &again,
        &make().process(f[4].rgbd(), &f[4].observation()).unwrap(),
    );
    // Frames without a time carry the stream over and say so.
    let untimed = p
        .process(f[5].rgbd(), &f[5].observation().untimed())
        .unwrap();
    assert_eq!(untimed.stream, StreamEvent::Untimed);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = make().with_memory_horizon(bad).unwrap_err();
        assert!(matches!(err, TouchError::InvalidParameter { .. }), "{err}");
    }
}

#[test]
fn the_physics_pipeline_reports_a_held_press_in_every_frame_after_its_onset() {
    // The committed episode: the plate presses the tip of finger 0 in frames 2–4 (0.4–0.8 s).
    let hand = hand();
    let episode = episode();
    let mut p = physics_pipeline(&hand, &episode);
    let mut onset = None;
    let mut held = 0;
    for (k, frame) in episode.frames.iter().enumerate() {
        let est = p.process(frame.rgbd(), &frame.observation()).unwrap();
        let pressed = !frame.contact_vertices[0].is_empty();
        let on_finger = |f: usize| est.contacts_in_hand.iter().any(|c| c.finger == f);
        if pressed && onset.is_none() && on_finger(0) {
            onset = Some(k);
        }
        if pressed && onset.is_some_and(|o| k > o) {
            // No flicker: every later frame of the press reports it, on the pressed finger, with
            // a force, and nothing on the free finger.
            assert!(on_finger(0), "frame {k}: the held press was dropped");
            assert!(!on_finger(1), "frame {k}: contact on the free finger");
            let loads = &est.details.loads;
            assert!(loads.iter().any(|l| l.finger == 0 && l.magnitude_n > 0.0));
            held += 1;
        }
    }
    assert_eq!(onset, Some(2), "the press is found in its first frame");
    assert_eq!(held, 2);
}

#[test]
fn a_finger_without_markers_is_reported_and_the_stream_goes_on() {
    let hand = hand();
    let episode = episode();
    let model = load_contact_model(&model_path(), &hand).unwrap();
    let threshold = model.threshold();
    let mut pipeline = Pipeline::new(
        hand.clone(),
        detector(&hand, &episode),
        Staged::new(
            MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap(),
            model,
        ),
        threshold,
    )
    .unwrap();
    let width = episode.info.camera.width as usize;
    for (k, frame) in episode.frames.iter().enumerate() {
        // Frames 2–4: no depth on the right half of the image, where finger 0 is.
        let mut depth = frame.depth_m.clone();
        if (2..5).contains(&k) {
            for (i, d) in depth.iter_mut().enumerate() {
                if i % width >= width / 2 {
                    *d = 0.0;
                }
            }
        }
        let est = pipeline
            .process(
                RgbdFrame {
                    color_rgb8: &frame.color_rgb8,
                    depth_m: &depth,
                },
                &Observation::new().with_world_from_hand(WorldFromHand::new(frame.world_from_hand)),
            )
            .unwrap();
        if (2..5).contains(&k) {
            assert_eq!(est.fingers_without_markers, vec![0], "frame {k}");
            assert_eq!(
                est.shape.fingers[0],
                hand.rest_vertices_in_hand(0),
                "frame {k}"
            );
        } else {
            assert!(est.fingers_without_markers.is_empty(), "frame {k}");
        }
    }
    // Images of the wrong size are an error, not a panic.
    let err = pipeline
        .process(
            RgbdFrame {
                color_rgb8: &[],
                depth_m: &[],
            },
            &Observation::new().with_world_from_hand(WorldFromHand::identity()),
        )
        .unwrap_err()
        .error;
    assert!(matches!(err, TouchError::ImageSize { .. }), "{err}");
}

#[test]
fn the_run_command_writes_a_deterministic_result_and_a_report() {
    use crate::common::{assert_one_line_error, run, run_json, run_ok, scratch, stable};
    let dir = scratch("run-cli");
    let episode = fixtures().join("episodes/plate_tip_front_small.mcap");
    let model = model_path();
    let out = dir.join("result.mcap");
    let report = dir.join("report.json");
    let a = [
        dgcnn_run(&episode, &model, &out).as_slice(),
        &["--report", report.to_str().unwrap(), "--json"],
    ]
    .concat();
    let summary = run_json(&a);
    insta::assert_json_snapshot!("run_summary", stable(summary.clone(), &dir));
    assert_eq!(summary["frames"], 7);
    assert!(summary["truncated"].is_null());
    assert!(summary["shape_bcd_mm"].as_f64().unwrap() < 1.0, "{summary}");
    assert_eq!(summary["contact"]["contact_frames"], 3);
    let full: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(full["per_frame"].as_array().unwrap().len(), 7);
    insta::assert_json_snapshot!("run_report", stable(full.clone(), &dir));
    // Same episode and model, same bytes.
    let again = dir.join("again.mcap");
    assert!(run(&dgcnn_run(&episode, &model, &again)).status.success());
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());

    // An episode cut short runs its complete frames and says so.
    let bytes = std::fs::read(&episode).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 5]).unwrap();
    let cut_out = dir.join("cut-result.mcap");
    let o = run_ok(&[dgcnn_run(&cut, &model, &cut_out).as_slice(), &["--json"]].concat());
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let frames = s["frames"].as_u64().unwrap();
    assert!((1..7).contains(&frames), "{frames} frames");
    assert!(
        s["truncated"].as_str().unwrap().contains("complete frames"),
        "{s}"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("warning:"));

    // Another hand than the episode's and the model's: one clear error, nothing written.
    let wrong = dir.join("wrong.mcap");
    let o = run(&[
        dgcnn_run(&episode, &model, &wrong).as_slice(),
        &["--hand", "three-finger"],
    ]
    .concat());
    let err = assert_one_line_error(&o);
    assert!(err.contains("three-finger"), "{err}");
    assert!(!wrong.exists());

    // An episode that repeats a frame's time: the repeat is refused and marked, naming the
    // times, and the run goes on and writes the result and the report.
    let recorded = moe_record::read_episode(&episode).unwrap();
    let mut frames = recorded.frames[..3].to_vec();
    frames.push(recorded.frames[2].clone());
    frames.push(recorded.frames[3].clone());
    let repeated = dir.join("repeated.mcap");
    moe_record::write_episode(&repeated, &recorded.info, &frames).unwrap();
    let repeated_out = dir.join("repeated-result.mcap");
    let repeated_report = dir.join("repeated-report.json");
    let args = [
        dgcnn_run(&repeated, &model, &repeated_out).as_slice(),
        &["--report", repeated_report.to_str().unwrap()],
    ]
    .concat();
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("1 of 5 frames not estimated"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&repeated_report).unwrap()).unwrap();
    assert_eq!(report["failed_frames"], 1);
    let marked = &report["per_frame"][3];
    assert_eq!(marked["failure"]["stage"], "input");
    assert!(
        marked["failure"]["error"]
            .as_str()
            .unwrap()
            .contains("frame time 0.4 s is not after the previous frame's 0.4 s"),
        "{marked}"
    );
    assert!(marked["stream"].is_null());
    // The refused frame changed nothing: the next one continues the stream.
    assert_eq!(report["per_frame"][4]["stream"]["kind"], "continued");
    assert!(repeated_out.exists());
    // --strict: the same outputs, and a failed run naming the first failed frame.
    std::fs::remove_file(&repeated_out).unwrap();
    let o = run(&[args.as_slice(), &["--strict"]].concat());
    let err = assert_one_line_error(&o);
    assert!(
        err.contains("--strict: 1 of 5 frames were not estimated"),
        "{err}"
    );
    assert!(
        err.contains("frame time 0.4 s is not after the previous frame's 0.4 s"),
        "{err}"
    );
    assert!(repeated_out.exists());
}

#[test]
fn the_foxglove_layout_shows_only_topics_a_run_writes() {
    let text = std::fs::read_to_string(fixtures().join("foxglove/run_layout.json")).unwrap();
    let layout: serde_json::Value = serde_json::from_str(&text).unwrap();
    let panels = layout["configById"].as_object().unwrap();
    assert!(panels.len() >= 3);
    let mut named = 0;
    for (id, config) in panels {
        let mut topics: Vec<String> = config["topics"]
            .as_object()
            .map(|t| t.keys().cloned().collect())
            .unwrap_or_default();
        if let Some(t) = config["imageMode"]["imageTopic"].as_str() {
            topics.push(t.to_owned());
        }
        // A plot's message paths: the topic, then the fields (`/topic.field[0].x`).
        for path in config["paths"].as_array().into_iter().flatten() {
            let value = path["value"].as_str().unwrap();
            let (topic, fields) = value.split_once('.').unwrap();
            if topic == "/estimate/finger_force" {
                // The fields are those of the messages a run writes.
                assert!(fields.starts_with("fingers["), "{id}: {value}");
                let (_, field) = fields.split_once("].").unwrap();
                let message = moe_record::FingerForceMessage {
                    finger: 0,
                    x_n: 0.0,
                    y_n: 0.0,
                    z_n: 0.0,
                    magnitude_n: 0.0,
                    pressed_probability: Some(0.0),
                    loads: 0,
                };
                let written = serde_json::to_value(&message).unwrap();
                assert!(written.get(field).is_some(), "{id}: {value}");
            }
            topics.push(topic.to_owned());
        }
        for t in topics {
            assert!(moe_record::RUN_TOPICS.contains(&t.as_str()), "{id}: {t}");
            named += 1;
        }
    }
    assert!(named >= 12, "{named}");
    assert!(panels.contains_key("Plot!force"));
}

/// The demo's episode, model and settings are built into the binary: run from a directory far
/// from the checkout (as an installed tool is), it writes its outputs where a relative `--out`
/// says, against the working directory.
#[test]
fn the_demo_runs_from_any_directory() {
    use crate::common::{run_in, scratch};
    let dir = scratch("demo-elsewhere");
    for method in ["physics", "dgcnn"] {
        let o = run_in(&dir, &["demo", "--contact", method, "--out", method]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for file in ["result.mcap", "report.json", "figure.png"] {
            assert!(dir.join(method).join(file).is_file(), "{method}: {file}");
        }
        let table = String::from_utf8_lossy(&o.stdout);
        let estimator = match method {
            // The episode's own settings, from the binary, not a file of the checkout.
            "physics" => "occluding-contact.toml (built in)",
            _ => "the paper's pipeline",
        };
        assert!(table.contains(estimator), "{method}: {table}");
    }
}

#[test]
fn the_demo_needs_no_arguments_and_writes_its_outputs() {
    use crate::common::{run_ok, scratch};
    let dir = scratch("demo");
    let out = dir.join("demo");
    let o = run_ok(&["demo", "--out", out.to_str().unwrap()]);
    let table = String::from_utf8_lossy(&o.stdout);
    for row in [
        "frames",
        "markers found",
        "shape BCD",
        "contact BCD",
        "frames per second",
        "estimated force",
    ] {
        assert!(table.contains(row), "{row} missing from\n{table}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["frames"], 7);
    // The physics estimator with the settings for an occluding object (the plate hides the
    // pressed tip's markers): every contact frame found, no false alarm, placed within 3 mm
    // (contact BCD), with a force per finger in the report and per frame.
    assert!(table.contains("occluding-contact.toml"), "{table}");
    let fingers = report["forces"]["fingers"].as_array().unwrap();
    assert_eq!(fingers.len(), 2);
    assert!(
        fingers[0]["max_magnitude_n"].as_f64().unwrap() > 0.0,
        "{report}"
    );
    let c = &report["contact"];
    assert_eq!(c["misses"], 0, "{c}");
    assert_eq!(c["false_alarms"], 0, "{c}");
    assert!(c["bcd_mm"].as_f64().unwrap() <= 3.0, "{c}");
    for frame in report["per_frame"].as_array().unwrap() {
        assert_eq!(frame["finger_forces"].as_array().unwrap().len(), 2);
    }
    // The pipeline's default settings (an empty settings file) still find the press on the
    // right finger, and the table names what they ran with.
    let defaults = dir.join("defaults.toml");
    std::fs::write(&defaults, "").unwrap();
    let plain = dir.join("plain");
    let o = crate::common::run_ok(&[
        "demo",
        "--out",
        plain.to_str().unwrap(),
        "--physics-config",
        defaults.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("defaults.toml"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(plain.join("report.json")).unwrap()).unwrap();
    let c = &report["contact"];
    assert!(
        c["contact_frames"].as_u64().unwrap() - c["misses"].as_u64().unwrap() >= 2,
        "{c}"
    );
    // With the depth image the plate that hides the tip is in view: the press is placed within
    // 3 mm. (Where the free finger's predicted tip lies in front of the plate that has pushed
    // it, the image sees the plate behind the prediction; taken for empty space there, it put
    // the press 6.5 mm off.)
    let depth = dir.join("depth");
    crate::common::run_ok(&[
        "demo",
        "--out",
        depth.to_str().unwrap(),
        "--physics-config",
        fixtures().join("physics/depth.toml").to_str().unwrap(),
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(depth.join("report.json")).unwrap()).unwrap();
    let c = &report["contact"];
    assert!(c["bcd_mm"].as_f64().unwrap() <= 3.0, "{c}");
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    for want in ["result.mcap", "figure.png"] {
        assert!(names.iter().any(|n| n == want), "{want} in {names:?}");
    }
    // Estimate and truth of both fingers of one frame.
    assert_eq!(
        names.iter().filter(|n| n.ends_with(".ply")).count(),
        4,
        "{names:?}"
    );
    let png = std::fs::read(out.join("figure.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let ply = names
        .iter()
        .find(|n| n.contains("estimate_finger_0"))
        .unwrap();
    let data = moe_io::read_ply(&out.join(ply)).unwrap();
    assert_eq!(data.points.len(), 1024);
    assert!(data.scalars.iter().any(|(n, _)| n == "contact_probability"));

    // The physics estimator's options without it: one line, nothing written.
    let settings = fixtures().join("physics/exact-markers.toml");
    let refused = dir.join("refused");
    let o = crate::common::run(&[
        "demo",
        "--out",
        refused.to_str().unwrap(),
        "--contact",
        "dgcnn",
        "--physics-config",
        settings.to_str().unwrap(),
    ]);
    let err = crate::common::assert_one_line_error(&o);
    assert!(
        err.contains("--physics-config is for --contact physics"),
        "{err}"
    );
    assert!(!refused.exists());
}

/// The pipeline finds the markers itself and needs the wrist pose: an observation that carries
/// markers, or lacks the pose, is refused before anything changes, and the stream goes on.
#[test]
fn an_observation_with_markers_or_without_a_pose_is_refused() {
    let hand = hand();
    let episode = episode();
    let mut p = physics_pipeline(&hand, &episode);
    let f = &episode.frames;
    let keypoints = hand.rest_keypoints();
    let failure = p
        .process(f[0].rgbd(), &f[0].observation().with_keypoints(&keypoints))
        .unwrap_err();
    assert_eq!(failure.stage, FrameStage::Input);
    let err = failure.error;
    assert!(
        matches!(err, TouchError::InvalidObservation { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("already carries markers"), "{err}");
    let mut no_pose = Observation::new().with_tendon_pulls(&f[0].tendon_pull_m);
    no_pose = no_pose.with_time(f[0].time_secs());
    let err = p.process(f[0].rgbd(), &no_pose).unwrap_err().error;
    assert!(
        matches!(err, TouchError::MissingObservation { what } if what.contains("world_from_hand")),
        "{err}"
    );
    // The physics estimator needs the pulls: its own error, through the pipeline, at the
    // estimate stage, with the markers that were found.
    let no_pulls = Observation::new()
        .with_world_from_hand(WorldFromHand::new(f[0].world_from_hand))
        .with_time(f[0].time_secs());
    let failure = p.process(f[0].rgbd(), &no_pulls).unwrap_err();
    assert_eq!(failure.stage, FrameStage::Estimate);
    assert_eq!(failure.stream, Some(StreamEvent::Started));
    assert!(failure.markers.as_ref().is_some_and(|m| m.found > 0));
    assert!(
        matches!(
            failure.error,
            TouchError::Physics(moe_physics::PhysicsError::Missing { .. })
        ),
        "{}",
        failure.error
    );
    // The stream goes on: the estimator's refusal came after the frame had entered the stream
    // at frame 0's time, so the next frame continues it, the estimator from rest.
    let next = p.process(f[1].rgbd(), &f[1].observation()).unwrap();
    assert!(
        matches!(next.stream, StreamEvent::Recovered { gap_secs: Some(g) } if (g - 0.2).abs() < 1e-9),
        "{:?}",
        next.stream
    );
    // The paper's pipeline is the staged SR-ARAP and network, and says nothing more.
    let model = load_contact_model(&model_path(), &hand).unwrap();
    let mut paper = Pipeline::paper(
        hand.clone(),
        detector(&hand, &episode),
        model,
        ShapeConfig::default(),
    )
    .unwrap();
    let est = paper.process(f[3].rgbd(), &f[3].observation()).unwrap();
    assert_eq!(est.details, ());
    assert_eq!(est.vertex_force_n, None);
    assert_eq!(est.shape.fingers.len(), hand.num_fingers());
}

#[test]
fn a_contact_threshold_outside_the_unit_interval_is_refused() {
    let hand = hand();
    let episode = episode();
    for threshold in [-0.1, 1.5, f64::NAN] {
        let err = Pipeline::new(
            hand.clone(),
            detector(&hand, &episode),
            Staged::new(
                MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap(),
                load_contact_model(&model_path(), &hand).unwrap(),
            ),
            threshold,
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                TouchError::InvalidParameter {
                    name: "contact threshold",
                    ..
                }
            ),
            "{err}"
        );
    }
}

/// Every model committed in `models/` loads with its card for the hand it was trained on, and
/// on the hand at rest (which touches nothing) it reports probabilities in [0, 1] and no vertex
/// over its card's threshold.
#[test]
fn every_committed_model_loads_and_finds_no_contact_at_rest() {
    let hand = hand();
    let dir = fixtures().join("../models");
    let mut models: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "safetensors"))
        .collect();
    models.sort();
    assert!(models.len() >= 2, "{models:?}");
    let rest = moe_geom::HandShape::rest(&hand);
    for path in &models {
        let model = load_contact_model(path, &hand).unwrap();
        let map = model.estimate_map(&ContactInput::shape(&rest)).unwrap();
        let threshold = model.threshold();
        for (f, finger) in map.fingers.iter().enumerate() {
            for (v, &p) in finger.iter().enumerate() {
                assert!(
                    (0.0..=1.0).contains(&p),
                    "{path:?} finger {f} vertex {v}: {p}"
                );
                assert!(
                    p < threshold,
                    "{path:?} finger {f} vertex {v}: {p} at rest (threshold {threshold})"
                );
            }
        }
    }
}

/// The grasp evaluation's `--true-labels` source places exactly the simulator's contact
/// vertices, only where the pipeline's estimated shape has them: the same presses and the same
/// number of points as the simulator's own contacts, a plane that differs from theirs, and both
/// near the plate's normal.
#[test]
fn the_grasps_true_labels_are_the_simulators_vertices_on_the_estimated_shape() {
    use moe_lab::grasp::{GraspContacts, GraspOptions, run_grasp_trial};
    let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
    let model = load_contact_model(&model_path(), &hand).unwrap();
    // One plane, through the contact points: the presses and points of both sources are then
    // the same.
    let options = GraspOptions {
        refinements: 0,
        fingertip_plane: false,
        ..GraspOptions::default()
    };
    let truth = run_grasp_trial(
        &hand,
        GraspContacts::<moe_contact::DgcnnEstimator>::Simulator,
        30.0,
        1,
        0,
        &options,
    )
    .unwrap();
    let labels = run_grasp_trial(
        &hand,
        GraspContacts::SimulatorLabelsOnEstimatedShape {
            contact: &model,
            shape: moe_arap::ShapeConfig::default(),
        },
        30.0,
        1,
        0,
        &options,
    )
    .unwrap();
    assert_eq!(labels.first_press, truth.first_press);
    assert!(truth.fits[0].estimated_contacts > 0);
    assert_eq!(
        labels.fits[0].estimated_contacts,
        truth.fits[0].estimated_contacts
    );
    // The same vertices in the same order; the simulator's own source fits its true points.
    let ids = |points: &[moe_geom::ContactPoint]| -> Vec<(usize, u32)> {
        points.iter().map(|c| (c.finger, c.vertex)).collect()
    };
    assert_eq!(ids(&labels.plane_points), ids(&truth.true_points));
    assert_eq!(truth.plane_points, truth.true_points);
    assert_eq!(labels.true_points, truth.true_points);
    // Placed on the estimated shape: moved, but by no more than the shape's error (Table 1:
    // at most 7 mm per vertex on held-out frames).
    let moved: Vec<f64> = labels
        .plane_points
        .iter()
        .zip(&labels.true_points)
        .map(|(a, b)| (a.point - b.point).norm())
        .collect();
    assert!(moved.iter().any(|&d| d > 1e-4), "{moved:?}");
    assert!(moved.iter().all(|&d| d < 0.01), "{moved:?}");
    let (on_shape, exact) = (
        labels.normal_error_deg.unwrap(),
        truth.normal_error_deg.unwrap(),
    );
    assert!(exact < 5.0, "the simulator's contacts: {exact}°");
    assert!(on_shape != exact, "the positions are the estimated shape's");
    assert!(
        on_shape < 15.0,
        "labels on the estimated shape: {on_shape}°"
    );
}

/// An estimator that reports the rest shape without contact and keeps what it was told of the
/// depth image: valid pixels, the camera's intrinsics and mount.
struct DepthWitness {
    hand: HandModel,
    seen: Vec<Option<(usize, moe_geom::CameraIntrinsics, moe_geom::HandFromCamera)>>,
}

impl HandEstimator for DepthWitness {
    type Details = ();
    type Error = std::convert::Infallible;

    fn estimate(
        &mut self,
        observation: &Observation<'_>,
    ) -> Result<moe_geom::HandEstimate, Self::Error> {
        self.seen.push(
            observation
                .depth
                .map(|d| (d.valid_pixels(), *d.intrinsics(), *d.hand_from_camera())),
        );
        let shape = moe_geom::HandShape::rest(&self.hand);
        let labels: Vec<Vec<bool>> = shape.fingers.iter().map(|f| vec![false; f.len()]).collect();
        Ok(moe_geom::HandEstimate {
            contact: moe_geom::ContactMap::from_labels(&labels),
            shape,
            vertex_force_n: None,
            details: (),
        })
    }
}

/// The pipeline passes each frame's depth image on to its estimator with the camera that took
/// it, and refuses an observation that brings its own.
#[test]
fn the_estimator_sees_the_frames_depth_image_with_its_camera() {
    let hand = hand();
    let episode = episode();
    let d = detector(&hand, &episode);
    let (intrinsics, mount) = (*d.intrinsics(), d.hand_from_camera());
    let witness = DepthWitness {
        hand: hand.clone(),
        seen: Vec::new(),
    };
    let mut pipeline = Pipeline::new(hand.clone(), d, witness, 0.5).unwrap();
    for frame in &episode.frames {
        pipeline
            .process(frame.rgbd(), &frame.observation())
            .unwrap();
    }
    let seen = &pipeline.estimator().seen;
    assert_eq!(seen.len(), episode.frames.len());
    for (frame, seen) in episode.frames.iter().zip(seen) {
        let valid = frame
            .depth_m
            .iter()
            .filter(|z| z.is_finite() && **z > 0.0)
            .count();
        assert_eq!(*seen, Some((valid, intrinsics, mount)));
        assert!(valid > 10_000, "{valid} depth pixels");
    }
    let f = &episode.frames[0];
    let image = moe_geom::DepthImage::new(&f.depth_m, intrinsics, mount).unwrap();
    let err = pipeline
        .process(f.rgbd(), &f.observation().with_depth(image))
        .unwrap_err()
        .error;
    assert!(
        matches!(err, TouchError::InvalidObservation { .. }),
        "{err}"
    );
}

/// With `fixtures/physics/depth.toml` the pipeline hands each frame's depth image to the
/// physics estimator, which pools it into observations of both fingers in every frame; with
/// the defaults it reads none.
#[test]
fn the_depth_settings_read_every_frames_depth_image() {
    let hand = hand();
    let episode = episode();
    let settings: moe_physics::PhysicsConfig =
        moe_io::read_config(&fixtures().join("physics/depth.toml")).unwrap();
    assert!(settings.depth.enabled);
    for (config, expect_depth) in [
        (settings, true),
        (moe_physics::PhysicsConfig::default(), false),
    ] {
        let mut p = PhysicsPipeline::physics(
            hand.clone(),
            detector(&hand, &episode),
            &moe_physics::HandMaterial::default(),
            &config,
        )
        .unwrap();
        for (k, f) in episode.frames.iter().enumerate() {
            let e = p.process(f.rgbd(), &f.observation()).unwrap();
            for (finger, r) in e.details.fingers.iter().enumerate() {
                assert_eq!(
                    r.depth_rows > 0 && r.depth_pixels >= r.depth_rows,
                    expect_depth,
                    "frame {k}, finger {finger}: {r:?}"
                );
            }
        }
    }
}

/// The paper's chain with SR-ARAP registered to each frame's depth image, end to end: the
/// committed episode's shapes come closer to the true ones than from the markers alone, and
/// the model trained on such shapes runs on them.
#[test]
fn run_registers_the_shape_to_the_depth_image_when_asked() {
    use crate::common::{run_json, scratch};
    let dir = scratch("run-depth-shape");
    let episode = fixtures().join("episodes/plate_tip_front_small.mcap");
    let shape = dir.join("shape.toml");
    std::fs::write(&shape, "[depth]\nenabled = true\n").unwrap();
    let depth_model = model_path().with_file_name("contact-two-finger-depth.safetensors");
    let summary = |model: &std::path::Path, extra: &[&str]| {
        let out = dir.join(format!("r{}.mcap", extra.len()));
        let args = [
            dgcnn_run(&episode, model, &out).as_slice(),
            &["--json"],
            extra,
        ]
        .concat();
        run_json(&args)
    };
    let markers_only = summary(&model_path(), &[]);
    let registered = summary(&depth_model, &["--shape-config", shape.to_str().unwrap()]);
    let bcd = |s: &serde_json::Value| s["shape_bcd_mm"].as_f64().unwrap();
    assert!(
        bcd(&registered) < bcd(&markers_only),
        "shape BCD with depth {} mm, markers alone {} mm",
        bcd(&registered),
        bcd(&markers_only)
    );
    assert_eq!(registered["frames"], 7);
}

/// A frame whose estimate fails mid-stream (a tendon pull read as NaN) is one failed frame: it
/// reports the markers it found and why, and the next frame succeeds, its estimator started
/// again from rest: the estimate of a fresh physics estimator given that frame's markers.
#[test]
fn a_frame_whose_estimate_fails_mid_stream_is_one_frame_and_the_next_recovers() {
    let hand = hand();
    let episode = episode();
    let f = &episode.frames;
    let mut p = physics_pipeline(&hand, &episode);
    for frame in &f[..3] {
        p.process(frame.rgbd(), &frame.observation()).unwrap();
    }
    let mut bad = f[3].clone();
    bad.tendon_pull_m[1][0] = f64::NAN;
    let failure = p.process(bad.rgbd(), &bad.observation()).unwrap_err();
    assert_eq!(failure.stage, FrameStage::Estimate);
    assert!(
        matches!(
            failure.error,
            TouchError::Physics(moe_physics::PhysicsError::NonFinite {
                what: "tendon pull",
                finger: 1,
                index: 0
            })
        ),
        "{}",
        failure.error
    );
    assert!(
        failure.to_string().starts_with("estimate stage: "),
        "{failure}"
    );
    let found = failure.keypoints.as_ref().expect("perception ran");
    assert_eq!(
        found.fingers.iter().flatten().flatten().count(),
        failure.markers.as_ref().unwrap().found
    );
    assert!(matches!(
        failure.stream,
        Some(StreamEvent::Continued { .. })
    ));
    // The next frame: estimated, from an estimator at rest.
    let next = p.process(f[4].rgbd(), &f[4].observation()).unwrap();
    assert!(
        matches!(next.stream, StreamEvent::Recovered { gap_secs: Some(g) } if (g - 0.2).abs() < 1e-9),
        "{:?}",
        next.stream
    );
    let mut fresh = moe_physics::PhysicsEstimator::new(
        &hand,
        &moe_physics::HandMaterial::default(),
        &moe_physics::PhysicsConfig::default(),
    )
    .unwrap();
    let detector = detector(&hand, &episode);
    let depth = moe_geom::DepthImage::new(
        &f[4].depth_m,
        *detector.intrinsics(),
        detector.hand_from_camera(),
    )
    .unwrap();
    let alone = fresh
        .estimate(
            &f[4]
                .observation()
                .with_keypoints(&next.keypoints)
                .with_depth(depth),
        )
        .unwrap();
    assert_eq!(next.shape, alone.shape);
    assert_eq!(next.details, alone.details);
    // And the frame after it continues that stream.
    let after = p.process(f[5].rgbd(), &f[5].observation()).unwrap();
    assert!(matches!(after.stream, StreamEvent::Continued { .. }));
}

/// A run goes on past a frame it cannot estimate: the report marks that frame (stage, error),
/// counts it, scores the others against the ground truth, and the result file has every frame.
#[test]
fn a_run_goes_on_past_a_failed_frame_and_marks_it() {
    let hand = hand();
    let episode = episode();
    let mut frames = episode.frames.clone();
    frames[3].tendon_pull_m[0][1] = f64::NAN;
    let mut p = physics_pipeline(&hand, &episode);
    let (out, report) = moe_lab::run::run_episode(&mut p, &episode.info, &frames, None).unwrap();
    assert_eq!((report.frames, report.failed_frames), (frames.len(), 1));
    assert_eq!(out.len(), frames.len());
    let failed = &report.per_frame[3];
    let failure = failed.failure.as_ref().expect("marked");
    assert_eq!(failure.stage, FrameStage::Estimate);
    assert!(failure.error.contains("tendon pull"), "{}", failure.error);
    assert!(failed.markers_found > 0);
    assert!(out[3].vertices_in_hand.iter().all(Vec::is_empty));
    assert!(out[3].markers_in_hand.iter().flatten().any(Option::is_some));
    assert!(
        failed
            .finger_forces
            .as_ref()
            .is_some_and(|f| f.iter().all(|f| f.magnitude_n == 0.0 && f.error.is_some()))
    );
    assert!(matches!(
        report.per_frame[4].stream,
        Some(StreamEvent::Recovered { .. })
    ));
    assert!(
        report
            .per_frame
            .iter()
            .enumerate()
            .all(|(k, f)| (k == 3) == f.failure.is_some())
    );
    // The figures against the ground truth are over the six estimated frames.
    let contact = report.contact.as_ref().expect("ground truth");
    assert_eq!(contact.frames, frames.len() as u64 - 1);
    assert!(report.shape_bcd_mm.is_some_and(f64::is_finite));
    assert_eq!(report.forces.as_ref().unwrap().fingers[0].failed_frames, 1);
    // The result file takes the failed frame.
    let path = crate::common::scratch("failed-frame-run").join("r.mcap");
    let mut info = moe_lab::run::run_info(&episode.info, "physics", p.threshold());
    info.force_arrow_m_per_n = Some(0.2);
    moe_record::write_run(&path, &info, &out).unwrap();
    let summary = report.summary(&path);
    assert!(summary.contains("1 of 7 frames not estimated"), "{summary}");
}

/// The short form of the soak: the committed episode looped for 80 frames with gaps, resets
/// and refused frames at periods that never coincide. Every refused frame is counted and
/// nothing else fails; the stream restarts after every gap, reset and refusal (whose frame's
/// time is skipped: the next frame comes two spacings, 0.4 s, after the last one estimated,
/// beyond the 0.2 s horizon) and nowhere else.
#[test]
fn a_looped_stream_with_gaps_resets_and_refusals_goes_on() {
    let hand = hand();
    let episode = episode();
    let mut p = physics_pipeline(&hand, &episode);
    let options = moe_lab::soak::SoakOptions {
        frames: 80,
        window: 40,
        gap_every: 25,
        reset_every: 51,
        refuse_every: 37,
        ..Default::default()
    };
    let mut progress = Vec::new();
    let report = moe_lab::soak::soak(&mut p, &episode.frames, &options, &mut |k, n| {
        progress.push((k, n))
    })
    .unwrap();
    assert_eq!(progress, [(40, 80), (80, 80)]);
    assert_eq!(report.refused_on_purpose, 2, "frames 37 and 74");
    assert_eq!(
        report.unexpected_failures, 0,
        "{:?}",
        report.first_unexpected_failure
    );
    assert_eq!(report.windows.len(), 2);
    let restarts: usize = report.windows.iter().map(|w| w.restarts).sum();
    assert_eq!(
        restarts,
        1 + 3 + 1 + 1,
        "the start, gaps at 25, 50, 75, the reset at 51, frame 38 after the refusal"
    );
    let estimated: usize = report.windows.iter().map(|w| w.frame_ms.frames).sum();
    assert_eq!(estimated, 78);
    assert!(report.p99_drift.is_some() && report.median_drift.is_some());
    if cfg!(target_os = "linux") {
        assert!(
            report
                .windows
                .iter()
                .all(|w| w.resident_mib.is_some_and(|m| m > 0.0))
        );
        assert!(report.resident_growth.is_some());
    }
    // The command runs the same study.
    let o = crate::common::run(&[
        "eval",
        "soak",
        "--episode",
        fixtures()
            .join("episodes/plate_tip_front_small.mcap")
            .to_str()
            .unwrap(),
        "--frames",
        "12",
        "--window",
        "6",
        "--refuse-every",
        "5",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["refused_on_purpose"], 2);
    assert_eq!(json["unexpected_failures"], 0);
    // Bad options are refused in one line.
    let o = crate::common::run(&["eval", "soak", "--episode", "x.mcap", "--window", "0"]);
    let err = crate::common::assert_one_line_error(&o);
    assert!(err.contains("window"), "{err}");
}
