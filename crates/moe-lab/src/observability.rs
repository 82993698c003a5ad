//! How well a marker layout lets the physics estimator locate a press, whatever the
//! estimator: the Cramér–Rao bound of the press's place along and around the finger and of its
//! force ([`moe_physics::PhysicsEstimator::location_bounds`]), at every movable surface vertex
//! of finger 0 of the two-finger hand (default finger, default material and settings, zero
//! pulls, gravity along the hand's −z), for each layout of the study: the camera row of 7 (the
//! paper's), two rows of 7 at ±35°, the camera row and rows of 7 on the sides (±90°), and the
//! camera row with a ring of 6 at the tip; and, with a depth model (the default), the wrist
//! camera's depth image alone and the camera row with depth, under the model's noise and under
//! its harsher variant. Per layout and region (tip z > 80 % of the length
//! with the cap, middle 40–70 %, base 12–35 %): median and 90th percentile, for one frame and
//! for a held press of several frames (independent marker noise per frame: the bound over √N).
//! The report prints as Markdown tables
//! ([`ObservabilityReport::table`](crate::observability::ObservabilityReport::table));
//! [`bound_map_svg`](crate::observability::bound_map_svg) draws the bound on each layout's
//! unrolled surface.

use moe_geom::{
    FingerModel, FingerParams, HandModel, HandPreset, MarkerLayoutPreset, Point3, Real, Vector3,
};
use moe_physics::{
    BoundOptions, DepthBoundModel, DepthCoverage, HandMaterial, PhysicsConfig, PhysicsEstimator,
    PlaceBound, RegionBound, quantile, region_bounds,
};
use serde::Serialize;

use crate::LabError;

mod map;

pub use map::bound_map_svg;

/// Sides of the finger at mid height (40–70 % of the length): name and the range of the
/// angle's magnitude around the axis from the camera side, degrees.
const SIDES: [(&str, Real, Real); 3] = [
    ("camera", 0.0, 45.0),
    ("flanks", 45.0, 135.0),
    ("back", 135.0, 180.0),
];

/// One layout's bound for one number of frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayoutSummary {
    /// What is observed: the marker layout's name, `depth` (the depth image alone), or the
    /// layout `+ depth`; the depth rows with the harsher noise say so.
    pub layout: String,
    /// Its markers on the finger.
    pub markers: usize,
    /// Frames of the held press (1: one frame).
    pub frames: usize,
    /// Median and 90th percentile per region (tip, middle, base).
    pub regions: Vec<RegionBound>,
    /// At mid height, by side: median along and around bounds, mm.
    pub mid_height_by_side: Vec<SideSummary>,
}

/// The median bound on one side of the finger at mid height.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SideSummary {
    /// The side: `camera` (0–45° from the camera side), `flanks` (45–135°), `back`.
    pub side: &'static str,
    /// Movable vertices on that side at mid height.
    pub vertices: usize,
    /// Median bound along the finger's axis, mm.
    pub along_mm_median: Real,
    /// Median bound around it, mm.
    pub around_mm_median: Real,
}

/// A layout's finger and its bound at every movable vertex.
#[derive(Debug, Clone)]
pub struct LayoutBounds {
    /// The layout.
    pub layout: MarkerLayoutPreset,
    /// What is observed (as [`LayoutSummary::layout`] names it).
    pub observed: String,
    /// The markers observed: the layout's, or none for the depth image alone.
    pub observed_markers: usize,
    /// Finger 0 of the two-finger hand with that layout.
    pub finger: FingerModel,
    /// The bound at every movable surface vertex.
    pub bounds: Vec<PlaceBound>,
}

/// The bound's depth observation of a rendering camera: its intrinsics, mount, range, grazing
/// limit and noise (white, correlated, quantisation). The bound leaves out the second
/// imager's holes and the flying pixels, so with a camera that has them it is optimistic.
pub fn depth_bound_model(camera: &moe_tendon_sim::camera::RgbdCamera) -> DepthBoundModel {
    let noise = &camera.noise;
    DepthBoundModel {
        intrinsics: camera.intrinsics,
        hand_from_camera: *camera.hand_from_camera.iso(),
        noise: moe_physics::DepthNoise {
            sigma_base_m: noise.depth_std_base_m,
            sigma_per_m2: noise.depth_std_per_m2,
            correlated_sigma_m: noise.depth_correlated_std_m,
            quantum_m: noise.depth_quantum_m,
        },
        min_range_m: noise.min_depth_m,
        max_range_m: noise.max_depth_m,
        grazing_deg: noise.grazing_dropout_deg,
    }
}

/// The finger of the study with `layout`.
pub fn study_params(layout: MarkerLayoutPreset) -> FingerParams {
    FingerParams {
        marker_layout: layout.layout(),
        ..FingerParams::default()
    }
}

/// Finger 0 of a hand alone, as the bound takes it: its physics model with the default
/// material and settings, zero pulls, gravity along the hand's −z.
pub struct FingerAlone {
    estimator: PhysicsEstimator,
    pulls: Vec<Real>,
    gravity: Vector3,
}

impl FingerAlone {
    /// Finger 0 of `hand`.
    ///
    /// # Errors
    /// A finger the physics model cannot be built for.
    pub fn of(hand: &HandModel) -> Result<Self, LabError> {
        let one = HandModel::new(vec![hand.fingers()[0].clone()])?;
        let config = PhysicsConfig::default();
        let estimator = PhysicsEstimator::new(&one, &HandMaterial::default(), &config)?;
        let gravity = Vector3::new(0.0, 0.0, -Vector3::from(config.gravity_m_s2).norm());
        let pulls = vec![0.0; one.fingers()[0].model.tendon_routes().len()];
        Ok(Self {
            estimator,
            pulls,
            gravity,
        })
    }

    /// Gravity in the hand frame, m/s².
    pub fn gravity(&self) -> Vector3 {
        self.gravity
    }

    /// The bound at every movable vertex ([`PhysicsEstimator::location_bounds`]).
    ///
    /// # Errors
    /// Invalid `options`, a failing solve.
    pub fn location_bounds(&mut self, options: &BoundOptions) -> Result<Vec<PlaceBound>, LabError> {
        Ok(self
            .estimator
            .location_bounds(0, &self.pulls, self.gravity, options)?)
    }

    /// What the camera of `depth` sees of the finger ([`PhysicsEstimator::depth_coverage`]).
    ///
    /// # Errors
    /// An invalid model, a failing solve.
    pub fn depth_coverage(&mut self, depth: &DepthBoundModel) -> Result<DepthCoverage, LabError> {
        Ok(self
            .estimator
            .depth_coverage(0, &self.pulls, self.gravity, depth)?)
    }
}

/// The bound of every movable vertex of finger 0 of the two-finger hand with `layout`, seen as
/// `options` says (its markers, the depth image of the default wrist camera, or both).
///
/// # Errors
/// Invalid `options`, a failing solve.
pub fn layout_bounds(
    layout: MarkerLayoutPreset,
    options: &BoundOptions,
) -> Result<LayoutBounds, LabError> {
    let hand = HandModel::preset(HandPreset::TwoFinger, &study_params(layout))?;
    let mut alone = FingerAlone::of(&hand)?;
    let finger = hand.fingers()[0].model.clone();
    let bounds = alone.location_bounds(options)?;
    let observed = match (options.markers, options.depth.is_some()) {
        (true, false) => layout.name().to_owned(),
        (true, true) => format!("{} + depth", layout.name()),
        (false, _) => "depth".to_owned(),
    };
    let observed_markers = if options.markers {
        finger.marker_vertices().len()
    } else {
        0
    };
    Ok(LayoutBounds {
        layout,
        observed,
        observed_markers,
        finger,
        bounds,
    })
}

/// Angle of a point around the finger's axis from the camera side (+x), degrees, −180 to 180.
pub fn angle_around_axis_deg(p: &Point3) -> Real {
    p.y.atan2(p.x).to_degrees()
}

impl LayoutBounds {
    /// The finger's length (its highest rest vertex).
    fn length(&self) -> Real {
        self.finger
            .mesh()
            .vertices()
            .iter()
            .map(|p| p.z)
            .fold(Real::MIN, Real::max)
    }

    /// The bounds whose vertex lies between heights `lo` and `hi` (fractions of the length).
    fn in_band(&self, lo: Real, hi: Real) -> impl Iterator<Item = &PlaceBound> {
        let length = self.length();
        self.bounds
            .iter()
            .filter(move |b| (lo..=hi).contains(&(b.rest_in_finger.z / length)))
    }

    /// The summary per region and, at mid height, per side.
    pub fn summary(&self, frames: usize) -> LayoutSummary {
        let regions = region_bounds(&self.bounds, self.length());
        let mid_height_by_side = SIDES
            .iter()
            .map(|&(side, lo, hi)| {
                let on: Vec<&PlaceBound> = self
                    .in_band(0.4, 0.7)
                    .filter(|b| (lo..=hi).contains(&angle_around_axis_deg(&b.rest_in_finger).abs()))
                    .collect();
                let med = |f: fn(&PlaceBound) -> Real| {
                    quantile(&on.iter().map(|b| f(b)).collect::<Vec<_>>(), 0.5)
                };
                SideSummary {
                    side,
                    vertices: on.len(),
                    along_mm_median: med(|b| b.along_m * 1e3),
                    around_mm_median: med(|b| b.around_m * 1e3),
                }
            })
            .collect();
        LayoutSummary {
            layout: self.observed.clone(),
            markers: self.observed_markers,
            frames,
            regions,
            mid_height_by_side,
        }
    }
}

/// The study's report.
#[derive(Debug, Clone, Serialize)]
pub struct ObservabilityReport {
    /// Force of the press, newtons.
    pub force_n: Real,
    /// Noise of a marker coordinate, metres.
    pub marker_sigma_m: Real,
    /// The tendon pulls (`zero`).
    pub pulls: &'static str,
    /// The gravity (`along the hand's -z`).
    pub gravity: &'static str,
    /// Per layout of [`MarkerLayoutPreset::ALL`], then per depth run (depth alone, the camera row
    /// with depth; each under the default and the harsher noise), for one frame and for the
    /// held press.
    pub summaries: Vec<LayoutSummary>,
    /// Per layout and depth run, the one-frame bound at every vertex (for figures; not
    /// serialised).
    #[serde(skip)]
    pub layouts: Vec<LayoutBounds>,
}

/// Settings of the observability study.
#[derive(Debug, Clone, PartialEq)]
pub struct ObservabilityOptions {
    /// Force of the press, newtons.
    pub force_n: Real,
    /// Noise of a marker coordinate, metres.
    pub marker_sigma_m: Real,
    /// Frames of the held press of the second summary (the first is one frame); at least 2.
    pub held_frames: usize,
    /// The depth image's model: with it, the paper's camera row is also bounded with depth
    /// alone and with both, under this noise and under [`DepthBoundModel::harsher`].
    pub depth: Option<DepthBoundModel>,
}

impl Default for ObservabilityOptions {
    fn default() -> Self {
        let bound = BoundOptions::default();
        Self {
            force_n: bound.force_n,
            marker_sigma_m: bound.marker_sigma_m,
            held_frames: 5,
            depth: Some(DepthBoundModel::default()),
        }
    }
}

/// Runs the observability study: the bound of every layout of [`MarkerLayoutPreset::ALL`]
/// ([`layout_bounds`]) and, with [`ObservabilityOptions::depth`], of the depth image alone and
/// of the camera row with depth under that noise and the harsher one; each summarised for one
/// frame and for [`ObservabilityOptions::held_frames`] frames. `progress` is told what each run
/// observed as it is done.
///
/// # Errors
/// A force, noise or frame count the bound refuses ([`BoundOptions::validate`]), a failing
/// solve.
pub fn run_observability_study(
    options: &ObservabilityOptions,
    mut progress: impl FnMut(&str),
) -> Result<ObservabilityReport, LabError> {
    let one = BoundOptions {
        force_n: options.force_n,
        marker_sigma_m: options.marker_sigma_m,
        frames: 1,
        ..BoundOptions::default()
    };
    one.validate()?;
    let held_frames = options.held_frames;
    BoundOptions {
        frames: held_frames,
        ..one.clone()
    }
    .validate()?;
    let mut layouts = Vec::new();
    let mut summaries = Vec::new();
    let mut runs: Vec<(MarkerLayoutPreset, BoundOptions, &str)> = MarkerLayoutPreset::ALL
        .into_iter()
        .map(|layout| (layout, one.clone(), ""))
        .collect();
    if let Some(depth) = &options.depth {
        for (model, suffix) in [(depth.clone(), ""), (depth.harsher(), ", harsher noise")] {
            for markers in [false, true] {
                let seen = BoundOptions {
                    markers,
                    depth: Some(model.clone()),
                    ..one.clone()
                };
                runs.push((MarkerLayoutPreset::CameraRow, seen, suffix));
            }
        }
    }
    for (layout, seen, suffix) in runs {
        let mut single = layout_bounds(layout, &seen)?;
        single.observed.push_str(suffix);
        summaries.push(single.summary(1));
        let held = LayoutBounds {
            bounds: single
                .bounds
                .iter()
                .map(|b| b.over_frames(held_frames))
                .collect(),
            ..single.clone()
        };
        summaries.push(held.summary(held_frames));
        progress(&single.observed);
        layouts.push(single);
    }
    Ok(ObservabilityReport {
        force_n: one.force_n,
        marker_sigma_m: one.marker_sigma_m,
        pulls: "zero",
        gravity: "along the hand's -z",
        summaries,
        layouts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound is finite everywhere on the paper's finger; at mid height it is larger on the
    /// flanks (±90°, away from the camera row's bending plane) than on the camera side, and
    /// rows on the flanks bring it down there; it shrinks as one over the square root of the
    /// frames of a held press. (The back is not worse than the camera side: a press there bends
    /// the finger in the same plane, which the row sees stretch and shorten.)
    #[test]
    fn the_bound_is_finite_worse_far_from_the_markers_and_falls_with_frames() {
        let one = BoundOptions::default();
        let row = layout_bounds(MarkerLayoutPreset::CameraRow, &one).unwrap();
        assert!(
            row.bounds.len() > 800,
            "{} movable vertices",
            row.bounds.len()
        );
        for b in &row.bounds {
            assert!(
                b.along_m.is_finite() && b.around_m.is_finite() && b.force_sd_n.is_finite(),
                "{b:?}"
            );
            assert!(b.along_m > 0.0 && b.around_m > 0.0 && b.force_sd_n > 0.0);
        }
        let s = row.summary(1);
        let side = |k: usize| &s.mid_height_by_side[k];
        assert!(side(0).vertices > 20 && side(1).vertices > 20);
        for (flank, camera, what) in [
            (side(1).along_mm_median, side(0).along_mm_median, "along"),
            (side(1).around_mm_median, side(0).around_mm_median, "around"),
        ] {
            assert!(
                flank > 1.3 * camera,
                "{what}: flanks {flank} mm vs camera side {camera} mm"
            );
        }
        let sides = layout_bounds(MarkerLayoutPreset::Sides, &one)
            .unwrap()
            .summary(1);
        assert!(
            sides.mid_height_by_side[1].along_mm_median < 0.5 * side(1).along_mm_median,
            "rows on the flanks: {} mm, the camera row alone: {} mm",
            sides.mid_height_by_side[1].along_mm_median,
            side(1).along_mm_median
        );
        let five = layout_bounds(
            MarkerLayoutPreset::CameraRow,
            &BoundOptions {
                frames: 5,
                ..one.clone()
            },
        )
        .unwrap();
        for (a, b) in row.bounds.iter().zip(&five.bounds) {
            assert_eq!(a.vertex, b.vertex);
            for (x1, x5) in [
                (a.along_m, b.along_m),
                (a.around_m, b.around_m),
                (a.force_sd_n, b.force_sd_n),
            ] {
                // Exactly √5 but for the rounding of the Fisher matrices' inverses, which are
                // ill-conditioned next to the clamped base.
                let ratio = x1 / x5;
                assert!((ratio / 5f64.sqrt() - 1.0).abs() < 1e-4, "{ratio}");
            }
            // What the study reports for five frames, scaled without solving again.
            let scaled = a.over_frames(5);
            assert_eq!(scaled.vertex, b.vertex);
            for (s5, x5) in [
                (scaled.along_m, b.along_m),
                (scaled.around_m, b.around_m),
                (scaled.force_sd_n, b.force_sd_n),
            ] {
                assert!((s5 / x5 - 1.0).abs() < 1e-4, "{s5} vs {x5}");
            }
        }
        // More markers around the finger: two rows locate a press around it better.
        let two = layout_bounds(MarkerLayoutPreset::TwoRows, &one)
            .unwrap()
            .summary(1);
        for (r2, r1) in two.regions.iter().zip(&s.regions) {
            assert!(
                r2.around_mm.median < r1.around_mm.median,
                "{}: two rows {} mm, one row {} mm",
                r1.region,
                r2.around_mm.median,
                r1.around_mm.median
            );
        }
    }

    /// Fisher information adds up: observing the depth image as well as the markers can only
    /// lower the bound, at every place; noisier depth can only raise it. The camera sees a few
    /// hundred of the finger's vertices, and the depth image alone bounds the base better
    /// than the seven markers do (they sit where the base bends least).
    #[test]
    fn depth_adds_information_and_harsher_noise_removes_it() {
        let markers = BoundOptions::default();
        let depth = DepthBoundModel::default();
        let with = |markers: bool, depth: &DepthBoundModel| BoundOptions {
            markers,
            depth: Some(depth.clone()),
            ..BoundOptions::default()
        };
        let layout = MarkerLayoutPreset::CameraRow;
        let m = layout_bounds(layout, &markers).unwrap();
        let both = layout_bounds(layout, &with(true, &depth)).unwrap();
        let harsh = layout_bounds(layout, &with(true, &depth.harsher())).unwrap();
        let alone = layout_bounds(layout, &with(false, &depth)).unwrap();
        assert_eq!(
            (both.observed.as_str(), alone.observed.as_str()),
            ("camera-row + depth", "depth")
        );
        let close = |a: Real, b: Real| a <= b * (1.0 + 1e-6) + 1e-12;
        for ((m, b), h) in m.bounds.iter().zip(&both.bounds).zip(&harsh.bounds) {
            assert_eq!((m.vertex, b.vertex), (b.vertex, h.vertex));
            for (x_m, x_b, x_h) in [
                (m.along_m, b.along_m, h.along_m),
                (m.around_m, b.around_m, h.around_m),
                (m.force_sd_n, b.force_sd_n, h.force_sd_n),
            ] {
                assert!(
                    close(x_b, x_m),
                    "vertex {}: {x_b} with depth, {x_m} without",
                    m.vertex
                );
                assert!(
                    close(x_b, x_h),
                    "vertex {}: {x_b} default, {x_h} harsher",
                    m.vertex
                );
            }
        }
        let base = |l: &LayoutBounds| l.summary(1).regions[2].along_mm.median;
        assert!(
            base(&alone) < 0.7 * base(&m),
            "{} vs {}",
            base(&alone),
            base(&m)
        );
        let hand = HandModel::preset(HandPreset::TwoFinger, &study_params(layout)).unwrap();
        let coverage = FingerAlone::of(&hand)
            .unwrap()
            .depth_coverage(&depth)
            .unwrap();
        assert!(
            (100..coverage.surface_vertices / 2).contains(&coverage.vertices),
            "{coverage:?}"
        );
        assert!(
            coverage.pixels > 1e4 && coverage.depth_m.median > 0.02,
            "{coverage:?}"
        );
    }

    /// The physics settings for the D405-class camera model that camera's depth noise.
    #[test]
    fn the_d405_physics_settings_carry_the_d405_cameras_noise() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
        let camera: moe_tendon_sim::camera::RgbdCamera =
            moe_io::read_config(&root.join("cameras/d405-wrist.toml")).unwrap();
        let config =
            moe_touch::settings::load_physics_config(&root.join("physics/depth-d405.toml"))
                .unwrap();
        assert!(config.depth.enabled);
        assert_eq!(config.depth.noise, depth_bound_model(&camera).noise);
    }

    /// The bound's default camera is the virtual camera that renders the episodes: the same
    /// intrinsics, mount, noise, range and grazing limit.
    #[test]
    fn the_depth_model_is_the_virtual_cameras() {
        let model = DepthBoundModel::default();
        let camera = depth_bound_model(&moe_tendon_sim::camera::RgbdCamera::default());
        // All but the correlated part, which the bound assumes and the camera does not render.
        let assumed = moe_physics::DepthNoise {
            correlated_sigma_m: model.noise.correlated_sigma_m,
            ..camera.noise
        };
        assert_eq!(
            DepthBoundModel {
                noise: assumed,
                ..camera
            },
            model
        );
    }
}
