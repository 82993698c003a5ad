//! The whole per-frame pipeline on the committed example episode: markers → SR-ARAP (from the
//! markers, or registered to the depth image as well) → the shipped DGCNN → contact points in
//! the world; and markers → the physics estimator (dented
//! shape, loads) → contact points.
//!
//! And the committed episode replayed whole as a stream at 30, 10 and 5 Hz (`stream/…`).
//!
//! `cargo bench -p moe-lab --bench pipeline`

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_arap::ShapeConfig;
use moe_geom::depth::{AssociationOptions, associate_depth};
use moe_geom::{
    DepthImage, FingerParams, HandModel, HandPreset, HandShape, Observation, WorldFromHand,
};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;
use moe_touch::{PaperPipeline, Pipeline};

fn pipeline(
    hand: &HandModel,
    episode: &moe_record::Episode,
    options: ShapeConfig,
) -> PaperPipeline {
    let model = if options.depth.enabled {
        "models/contact-two-finger-depth.safetensors"
    } else {
        "models/contact-two-finger.safetensors"
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let model = load_contact_model(&root.join(model), hand).expect("the shipped model loads");
    let detector = MarkerDetector::for_episode(&episode.info, hand, DetectorConfig::default())
        .expect("detector");
    Pipeline::paper(hand.clone(), detector, model, options).expect("pipeline")
}

/// The committed example episode and the hand that recorded it.
fn committed_episode() -> (moe_record::Episode, HandModel) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let episode =
        moe_record::read_episode(&root.join("fixtures/episodes/plate_tip_front_small.mcap"))
            .expect("the committed episode reads");
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("hand");
    (episode, hand)
}

fn bench_pipeline(c: &mut Criterion) {
    let (episode, hand) = committed_episode();
    // The frame with the plate pressed in.
    let frame = &episode.frames[3];
    let input = frame.rgbd();
    // The wrist pose alone, untimed: every iteration is a frame of its own.
    let pose = Observation::new().with_world_from_hand(WorldFromHand::new(frame.world_from_hand));
    let mut from_rest = pipeline(&hand, &episode, ShapeConfig::default());
    c.bench_function(
        "pipeline/two-finger frame, SR-ARAP 50 iterations from rest",
        |b| b.iter(|| black_box(from_rest.process(black_box(input), &pose).expect("runs"))),
    );
    let tracked_options = ShapeConfig {
        iterations: 10,
        warm_start: true,
        ..ShapeConfig::default()
    };
    let mut tracked = pipeline(&hand, &episode, tracked_options);
    tracked.process(input, &pose).expect("runs");
    c.bench_function(
        "pipeline/two-finger frame, tracked (10 iterations, warm start)",
        |b| b.iter(|| black_box(tracked.process(black_box(input), &pose).expect("runs"))),
    );
    // SR-ARAP registered to the frame's depth image ([depth] defaults) and the network trained
    // on such shapes.
    let depth_options = ShapeConfig {
        depth: moe_arap::ShapeDepth {
            enabled: true,
            ..moe_arap::ShapeDepth::default()
        },
        ..ShapeConfig::default()
    };
    let mut with_depth = pipeline(&hand, &episode, depth_options);
    c.bench_function(
        "pipeline/two-finger frame, SR-ARAP registered to depth, from rest",
        |b| b.iter(|| black_box(with_depth.process(black_box(input), &pose).expect("runs"))),
    );
}

/// The pipeline with the physics estimator's stages (nominal material, default settings, then
/// those of `fixtures/physics/depth.toml`, with the depth image as observation) on the pressed
/// frame: a lone frame (the pipeline reset before each), and the frame held in a stream (each
/// iteration 50 ms after the previous one).
fn bench_physics_pipeline(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let with_depth: moe_physics::PhysicsConfig =
        moe_io::read_config(&root.join("fixtures/physics/depth.toml")).expect("depth.toml reads");
    for (name, config) in [
        ("physics", moe_physics::PhysicsConfig::default()),
        ("physics with depth", with_depth),
    ] {
        bench_physics_config(c, name, &config);
    }
}

fn bench_physics_config(c: &mut Criterion, name: &str, config: &moe_physics::PhysicsConfig) {
    let (episode, hand) = committed_episode();
    let physics = || {
        let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())
            .expect("detector");
        moe_touch::PhysicsPipeline::physics(
            hand.clone(),
            detector,
            &moe_physics::HandMaterial::default(),
            config,
        )
        .expect("pipeline")
    };
    let mut frame = episode.frames[3].clone();
    let mut lone = physics();
    c.bench_function(
        &format!("pipeline/two-finger frame, {name} from rest"),
        |b| {
            b.iter(|| {
                lone.reset();
                black_box(
                    lone.process(frame.rgbd(), black_box(&frame.observation()))
                        .expect("runs"),
                )
            })
        },
    );
    let mut stream = physics();
    stream
        .process(frame.rgbd(), &frame.observation())
        .expect("runs");
    c.bench_function(
        &format!("pipeline/two-finger frame, {name} tracked (50 ms frames)"),
        |b| {
            b.iter(|| {
                frame.time_ns += 50_000_000;
                black_box(
                    stream
                        .process(frame.rgbd(), black_box(&frame.observation()))
                        .expect("runs"),
                )
            })
        },
    );
}

/// The committed episode replayed as a stream, whole, as `moe-touch run` does it: every frame
/// in order from a fresh stream (markers, the physics estimator with the default settings,
/// contact points), with the frames re-timed to 30, 10 and 5 Hz (the recorded pulls and poses,
/// the time between frames changed). One iteration is the whole episode; the name says how many
/// frames, so the time per frame is the figure over that. `moe-touch run --report` gives the
/// same streams' median, p99 and largest frame.
fn bench_physics_stream(c: &mut Criterion) {
    let (episode, hand) = committed_episode();
    let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())
        .expect("detector");
    let mut pipeline = moe_touch::PhysicsPipeline::physics(
        hand.clone(),
        detector,
        &moe_physics::HandMaterial::default(),
        &moe_physics::PhysicsConfig::default(),
    )
    .expect("pipeline");
    for hz in [30u64, 10, 5] {
        let frames: Vec<_> = episode
            .frames
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let mut f = f.clone();
                f.time_ns = k as u64 * 1_000_000_000 / hz;
                f
            })
            .collect();
        c.bench_function(
            &format!(
                "stream/committed episode at {hz} Hz, physics, {} frames from a fresh stream",
                frames.len()
            ),
            |b| {
                b.iter(|| {
                    pipeline.reset();
                    for f in &frames {
                        black_box(
                            pipeline
                                .process(f.rgbd(), black_box(&f.observation()))
                                .expect("runs"),
                        );
                    }
                })
            },
        );
    }
}

/// Which depth pixels see which finger on the pressed frame, predicted from the frame's true
/// shape (the z-buffer of both fingers' meshes, then the grid, silhouette band and gate of the
/// default options): what giving an estimator the depth image costs before it uses it. The
/// benchmark's name says how many pixels each finger keeps.
fn bench_depth_association(c: &mut Criterion) {
    let (episode, hand) = committed_episode();
    let frame = &episode.frames[3];
    let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())
        .expect("detector");
    let depth = DepthImage::new(
        &frame.depth_m,
        *detector.intrinsics(),
        detector.hand_from_camera(),
    )
    .expect("the frame fits its camera");
    let shape = HandShape {
        fingers: frame.finger_vertices_in_hand.clone(),
    };
    let options = AssociationOptions::default();
    let kept: Vec<String> = associate_depth(&hand, &shape, &depth, &options)
        .expect("associates")
        .iter()
        .map(|f| f.points.len().to_string())
        .collect();
    c.bench_function(
        &format!(
            "depth/association, stride 4 ({} pixels kept per finger)",
            kept.join(" and ")
        ),
        |b| {
            b.iter(|| {
                black_box(
                    associate_depth(&hand, &shape, black_box(&depth), &options).expect("runs"),
                )
            })
        },
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = bench_pipeline, bench_physics_pipeline, bench_physics_stream, bench_depth_association
}
criterion_main!(benches);
