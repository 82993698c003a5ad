//! Bad input at the runtime's public boundaries, fuzzed: `Pipeline::process` and
//! `PhysicsEstimator::estimate` on the committed episode's frames with one to three faults each
//! — NaN, infinite and huge values, poses that are not rigid, pulls out of range, time going
//! backwards, markers missing, images of the wrong size, depth all holes or all zeros — and a
//! pipeline and an estimator kept across cases, so that faults meet whatever stream state the
//! cases before left. Each case must give a typed error or an estimate whose every number is
//! finite (a degraded frame counts as an estimate); a panic is caught and fails the test.
//!
//! `MOE_FUZZ_CASES` cases per boundary (default 150; the figures in docs/results.md are from
//! 100,000 by hand: `MOE_FUZZ_CASES=100000 cargo test --release -p moe-touch-cli --test it
//! fuzz_boundaries -- --nocapture`).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use moe_geom::nalgebra::{Quaternion, Translation3, UnitQuaternion};
use moe_geom::{
    CameraIntrinsics, DepthImage, HandEstimator, HandKeypoints, Iso3, Observation, Point3, Real,
    SeededRng, Vector3, WorldFromHand,
};
use moe_physics::FingerReport;
use moe_record::EpisodeFrame;

use super::pipeline::{episode, hand, physics_pipeline};

/// The faults of a pipeline case, by number.
const PIPELINE_FAULTS: [&str; 12] = [
    "a bad pull",
    "every pull 50 mm",
    "a finger's pulls one short",
    "a bad time",
    "a pose that is not rigid",
    "no pose",
    "an image of the wrong size",
    "depth all one bad value",
    "every pixel marker red",
    "colour noise",
    "a quarter of the depth NaN",
    "reset",
];

/// The faults of an estimator case, by number.
const ESTIMATOR_FAULTS: [&str; 12] = [
    "a bad marker coordinate",
    "every marker missing",
    "a finger's markers missing",
    "a marker 5 cm astray",
    "a finger one marker short",
    "one finger's keypoints",
    "a bad pull",
    "a bad time",
    "a pose that is not rigid",
    "no pose",
    "depth all holes, all zeros or the wrong size",
    "a finger's markers a thousand times further",
];

fn cases() -> usize {
    std::env::var("MOE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(150)
}

/// A value that breaks something: NaN, an infinity, a huge or a negative number.
fn bad(rng: &mut SeededRng) -> Real {
    match rng.below(7) {
        0 => Real::NAN,
        1 => Real::INFINITY,
        2 => Real::NEG_INFINITY,
        3 => 1e300,
        4 => -1e9,
        5 => rng.uniform_range(-1.0, 1.0),
        _ => 0.0,
    }
}

/// A wrist pose that is not one: NaN or infinite parts, or a quaternion that is not of unit
/// length (not rigid).
fn bad_pose(rng: &mut SeededRng, pose: &Iso3) -> Iso3 {
    match rng.below(3) {
        0 => Iso3::from_parts(Translation3::new(bad(rng), 0.0, 0.0), pose.rotation),
        1 => Iso3::from_parts(
            pose.translation,
            UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.5, bad(rng), 0.0)),
        ),
        _ => Iso3::from_parts(
            pose.translation,
            UnitQuaternion::new_unchecked(Quaternion::new(0.0, 0.0, 0.0, 0.0)),
        ),
    }
}

/// An estimate's finger reports, and why it is not acceptable (if it is not).
type Checked = (Vec<FingerReport>, Option<String>);

/// Tally of one boundary's cases.
#[derive(Debug, Default)]
struct Tally {
    estimated: usize,
    degraded: usize,
    errors: usize,
    bad: Vec<String>,
    slowest_ms: Real,
    slowest: String,
}

impl Tally {
    /// Counts one case's outcome (its finger reports and why its estimate is not acceptable,
    /// or its error, or its panic); whether it panicked.
    fn record<E>(&mut self, case: usize, outcome: std::thread::Result<Result<Checked, E>>) -> bool {
        match outcome {
            Ok(Ok((fingers, why))) => {
                self.estimated += 1;
                self.degraded += usize::from(fingers.iter().any(|r| r.degraded));
                if let Some(why) = why {
                    self.bad.push(format!("case {case}: {why}"));
                }
                false
            }
            Ok(Err(_)) => {
                self.errors += 1;
                false
            }
            Err(_) => {
                self.bad.push(format!("case {case}: panicked"));
                true
            }
        }
    }

    /// Runs one case (`applied`: its faults), timed and with panics caught, checks its
    /// estimate with `check` and counts it; whether it panicked.
    fn run<T, E>(
        &mut self,
        case: usize,
        applied: &[&str],
        call: impl FnOnce() -> Result<T, E>,
        check: impl FnOnce(T) -> Checked,
    ) -> bool {
        let start = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(call));
        self.time(start, applied);
        self.record(case, outcome.map(|r| r.map(check)))
    }

    fn time(&mut self, start: Instant, applied: &[&str]) {
        let ms = 1e3 * start.elapsed().as_secs_f64();
        if ms > self.slowest_ms {
            self.slowest_ms = ms;
            self.slowest = applied.join(", ");
        }
    }

    fn report(&self, boundary: &str, cases: usize) {
        eprintln!(
            "fuzz {boundary}: {cases} cases: {} estimated ({} with a degraded finger), {} typed errors, {} panics or non-finite estimates; slowest case {:.0} ms ({})",
            self.estimated,
            self.degraded,
            self.errors,
            self.bad.len(),
            self.slowest_ms,
            self.slowest
        );
        assert!(
            self.bad.is_empty(),
            "{boundary}: {} bad cases, the first: {}",
            self.bad.len(),
            self.bad[0]
        );
    }
}

/// Why an estimate is not acceptable: a non-finite number where it gives one.
fn non_finite(shape: &[Vec<Point3>], contact: &[Vec<Real>]) -> Option<String> {
    if let Some(f) = shape
        .iter()
        .position(|v| v.iter().any(|p| !p.coords.iter().all(|c| c.is_finite())))
    {
        return Some(format!("finger {f}: a non-finite vertex"));
    }
    contact
        .iter()
        .position(|c| {
            c.iter()
                .any(|p| !(p.is_finite() && (0.0..=1.0).contains(p)))
        })
        .map(|f| format!("finger {f}: a contact probability outside [0, 1]"))
}

/// One case of the pipeline: a frame with faults, in the stream the cases before left.
fn pipeline_case(
    rng: &mut SeededRng,
    frames: &[EpisodeFrame],
    time: &mut Real,
) -> (
    EpisodeFrame,
    Option<Real>,
    Option<WorldFromHand>,
    bool,
    Vec<&'static str>,
) {
    let mut f = frames[rng.below(frames.len() as u64) as usize].clone();
    *time += 0.2;
    let mut t = Some(*time);
    let mut pose = Some(WorldFromHand::new(f.world_from_hand));
    let mut reset = false;
    let mut applied = Vec::new();
    for _ in 0..1 + rng.below(3) {
        let fault = rng.below(12) as usize;
        applied.push(PIPELINE_FAULTS[fault]);
        match fault {
            0 => {
                let finger = rng.below(f.tendon_pull_m.len() as u64) as usize;
                let k = rng.below(f.tendon_pull_m[finger].len() as u64) as usize;
                f.tendon_pull_m[finger][k] = bad(rng);
            }
            1 => f.tendon_pull_m.iter_mut().flatten().for_each(|p| *p = 0.05),
            2 => {
                f.tendon_pull_m[rng.below(2) as usize].pop();
            }
            3 => {
                t = match rng.below(5) {
                    0 => Some(Real::NAN),
                    1 => Some(Real::INFINITY),
                    2 => Some(*time - rng.uniform_range(0.0, 5.0)),
                    3 => Some(*time + 1e15),
                    _ => None,
                }
            }
            4 => pose = Some(WorldFromHand::new(bad_pose(rng, &f.world_from_hand))),
            5 => pose = None,
            6 => {
                let cut = 1 + rng.below(1000) as usize;
                if rng.below(2) == 0 {
                    f.color_rgb8
                        .truncate(f.color_rgb8.len().saturating_sub(cut));
                } else {
                    f.depth_m.extend(std::iter::repeat_n(0.5, cut));
                }
            }
            7 => {
                let v = [f32::NAN, 0.0, f32::INFINITY, -0.3][rng.below(4) as usize];
                f.depth_m.iter_mut().for_each(|z| *z = v);
            }
            8 => f
                .color_rgb8
                .chunks_exact_mut(3)
                .for_each(|p| p.copy_from_slice(&[230, 20, 20])),
            9 => f
                .color_rgb8
                .iter_mut()
                .for_each(|c| *c = rng.below(256) as u8),
            10 => {
                let n = f.depth_m.len();
                for _ in 0..n / 4 {
                    f.depth_m[rng.below(n as u64) as usize] = f32::NAN;
                }
            }
            _ => reset = true,
        }
    }
    (f, t, pose, reset, applied)
}

#[test]
fn fuzz_boundaries_the_pipeline_never_panics_and_never_gives_a_non_finite_estimate() {
    let hand = hand();
    let episode = episode();
    let frames = &episode.frames;
    let mut pipeline = physics_pipeline(&hand, &episode);
    let mut rng = SeededRng::new(0x5eed_f0dd);
    let mut tally = Tally::default();
    let mut time = 0.0;
    let n = cases();
    for case in 0..n {
        let (f, t, pose, reset, applied) = pipeline_case(&mut rng, frames, &mut time);
        if reset {
            pipeline.reset();
        }
        let mut observation = Observation::new().with_tendon_pulls(&f.tendon_pull_m);
        observation.world_from_hand = pose;
        observation.time_secs = t;
        let call = || pipeline.process(f.rgbd(), &observation);
        if tally.run(case, &applied, call, |e| {
            (
                e.details.fingers,
                non_finite(&e.shape.fingers, &e.contact.fingers),
            )
        }) {
            pipeline = physics_pipeline(&hand, &episode);
        }
    }
    tally.report("Pipeline::process", n);
}

/// One case of the estimator: a frame's true markers (those a camera could see) with faults.
fn estimator_case(
    rng: &mut SeededRng,
    frames: &[EpisodeFrame],
    time: &mut Real,
) -> (
    EpisodeFrame,
    HandKeypoints,
    Option<Real>,
    Option<WorldFromHand>,
    u64,
    Vec<&'static str>,
) {
    let mut f = frames[rng.below(frames.len() as u64) as usize].clone();
    let mut keypoints = HandKeypoints {
        fingers: f
            .markers_in_hand
            .iter()
            .map(|m| m.iter().map(|p| Some(*p)).collect())
            .collect(),
    };
    *time += 0.2;
    let mut t = Some(*time);
    let mut pose = Some(WorldFromHand::new(f.world_from_hand));
    let mut depth = 0;
    let mut applied = Vec::new();
    for _ in 0..1 + rng.below(3) {
        let finger = rng.below(keypoints.fingers.len() as u64) as usize;
        let slots = keypoints.fingers[finger].len() as u64;
        let fault = rng.below(12) as usize;
        applied.push(ESTIMATOR_FAULTS[fault]);
        match fault {
            0 => {
                let k = rng.below(slots) as usize;
                keypoints.fingers[finger][k] = Some(Point3::new(bad(rng), 0.0, 0.01));
            }
            1 => keypoints
                .fingers
                .iter_mut()
                .flatten()
                .for_each(|m| *m = None),
            2 => keypoints.fingers[finger].iter_mut().for_each(|m| *m = None),
            3 => {
                let k = rng.below(slots) as usize;
                let shift = Vector3::new(
                    rng.uniform_range(-0.05, 0.05),
                    rng.uniform_range(-0.05, 0.05),
                    rng.uniform_range(-0.05, 0.05),
                );
                keypoints.fingers[finger][k] = keypoints.fingers[finger][k].map(|p| p + shift);
            }
            4 => {
                keypoints.fingers[finger].pop();
            }
            5 => keypoints.fingers.truncate(1),
            6 => {
                let k = rng.below(f.tendon_pull_m[finger].len() as u64) as usize;
                f.tendon_pull_m[finger][k] = bad(rng);
            }
            7 => {
                t = match rng.below(4) {
                    0 => Some(Real::NAN),
                    1 => Some(*time - rng.uniform_range(0.0, 5.0)),
                    2 => Some(-1e12),
                    _ => None,
                }
            }
            8 => pose = Some(WorldFromHand::new(bad_pose(rng, &f.world_from_hand))),
            9 => pose = None,
            10 => depth = 1 + rng.below(3),
            _ => keypoints.fingers[finger]
                .iter_mut()
                .flatten()
                .for_each(|p| p.coords *= 1e3),
        }
    }
    (f, keypoints, t, pose, depth, applied)
}

#[test]
fn fuzz_boundaries_the_physics_estimator_never_panics_and_never_gives_a_non_finite_estimate() {
    let hand = hand();
    let episode = episode();
    let frames = &episode.frames;
    let mut estimator = moe_physics::PhysicsEstimator::new(
        &hand,
        &moe_physics::HandMaterial::default(),
        &moe_physics::PhysicsConfig::default(),
    )
    .unwrap();
    let detector = moe_touch::perception::MarkerDetector::for_episode(
        &episode.info,
        &hand,
        Default::default(),
    )
    .unwrap();
    let k: CameraIntrinsics = *detector.intrinsics();
    let mount = detector.hand_from_camera();
    let pixels = (k.width * k.height) as usize;
    let holes = vec![f32::NAN; pixels];
    let zeros = vec![0.0f32; pixels];
    let mut rng = SeededRng::new(0xe57_1a7e);
    let mut tally = Tally::default();
    let mut time = 0.0;
    let n = cases();
    for case in 0..n {
        let (f, keypoints, t, pose, depth, applied) = estimator_case(&mut rng, frames, &mut time);
        let image = match depth {
            0 => DepthImage::new(&f.depth_m, k, mount).ok(),
            1 => DepthImage::new(&holes, k, mount).ok(),
            2 => DepthImage::new(&zeros, k, mount).ok(),
            // An image of the wrong size is refused where it is made.
            _ => {
                assert!(DepthImage::new(&zeros[1..], k, mount).is_err());
                None
            }
        };
        let mut observation = Observation::new()
            .with_keypoints(&keypoints)
            .with_tendon_pulls(&f.tendon_pull_m);
        observation.world_from_hand = pose;
        observation.time_secs = t;
        if let Some(image) = image {
            observation = observation.with_depth(image);
        }
        let call = || estimator.estimate(&observation);
        if tally.run(case, &applied, call, |e| {
            (
                e.details.fingers,
                non_finite(&e.shape.fingers, &e.contact.fingers),
            )
        }) {
            estimator.reset();
        }
    }
    tally.report("PhysicsEstimator::estimate", n);
}
