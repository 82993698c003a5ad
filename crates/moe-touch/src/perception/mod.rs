//! Marker perception (paper §4.2, Fig. 1 i–ii): from a wrist RGB-D frame to the hand-frame
//! position of every marker of every finger, or `None` where a marker is not seen.
//!
//! Per frame:
//! 1. **Segmentation**: a pixel is a marker pixel when its HSV colour passes the hue window,
//!    saturation and value thresholds of [`DetectorConfig`](crate::perception::DetectorConfig)
//!    (integer arithmetic; the grey silicone fails on saturation before any hue is computed).
//! 2. **Back-projection**: marker pixels with valid depth (finite, positive; NaN, zero and
//!    negative depth are missing) are lifted into the camera frame with the pinhole intrinsics.
//! 3. **Pre-grouping**: the lifted points are binned into cubic voxels of `voxel_m` (1 mm) in
//!    the camera frame, each voxel standing for its pixels by their mean point. A 640 × 480
//!    frame of the two-finger hand has some 5,000 marker pixels but a few hundred voxels,
//!    so DBSCAN runs on hundreds of points, not on every pixel — and every pixel still counts in
//!    the centre, which is computed from the pixels of the cluster's cells.
//! 4. **Clustering**: DBSCAN (linfa-clustering) on the voxel points in 3-D, radius
//!    `dbscan_eps_m`, core size `dbscan_min_points` (counting the point itself). Clusters with
//!    fewer than `min_cluster_pixels` pixels or a radius above `max_cluster_radius_m` are
//!    rejected (red noise, a red object).
//! 5. **Centre**: [`CentreMethod::SurfaceFit`](crate::perception::CentreMethod::SurfaceFit)
//!    by default (the private `centre` module explains why a plain centroid is biased on a
//!    curved finger), mapped into the hand frame with the calibrated `hand_from_camera`.
//! 6. **Identity**: clusters are assigned to markers by optimal (minimum total distance)
//!    one-to-one assignment within per-marker gates. Without a usable prior (the first frame,
//!    after [`reset`](crate::perception::MarkerDetector::reset), or when every track has been
//!    lost) the expected positions are the rest markers; after that each marker's own track predicts it by constant
//!    velocity. Markers still unmatched are then predicted along their finger from the
//!    neighbours found in this frame and matched in further rounds, which finds the markers of
//!    a finger that starts out bent. A marker no cluster matches is `None` — never a guess —
//!    and keeps its track for `max_missing_frames`, so that it gets its own identity back when
//!    it reappears.

mod assign;
mod centre;
mod segment;
mod track;

use linfa::traits::Transformer;
use linfa_clustering::{Dbscan, DbscanParamsError};
use moe_geom::CameraIntrinsics;
use moe_geom::{HandFromCamera, HandKeypoints, HandModel, Point3, Real};
use serde::{Deserialize, Serialize};

pub use centre::CentreMethod;
pub use track::Prior;

use crate::TouchError;

/// Parameters of marker detection. The defaults suit the recorded episodes (5 mm red markers,
/// a 640 × 480 wrist camera 3–12 cm from them) and are a starting point for a real camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    /// Hue of the markers, degrees (0 = red). Default 0.
    pub hue_center_deg: Real,
    /// Largest hue difference from `hue_center_deg`, degrees. Default 20.
    pub hue_tolerance_deg: Real,
    /// Smallest HSV saturation, 0–1. Default 0.55 (marker red 0.89; the silicone 0.07 and the
    /// recorder's blue obstacles 0.47 fall below).
    pub min_saturation: Real,
    /// Smallest HSV value, 0–1. Default 0.15 (dark, shadowed pixels have unreliable hue).
    pub min_value: Real,
    /// Side of the voxels that pre-group the marker points for DBSCAN, metres. Default 0.001
    /// (a 5 mm marker fills some 20 voxels, whatever its distance and the image resolution).
    pub voxel_m: Real,
    /// DBSCAN neighbourhood radius, metres. Default 0.0018 (voxels of one marker are 1 mm
    /// apart; neighbouring markers of the parametric finger are 4 mm apart edge to edge, less
    /// once depth noise — along lines of sight that run nearly along the finger — scatters
    /// their points: at 2.5 mm, two markers merged in noisy frames).
    pub dbscan_eps_m: Real,
    /// DBSCAN core-point size, counting the point itself. Default 3.
    pub dbscan_min_points: usize,
    /// Fewest marker pixels with depth in an accepted cluster. Default 4 (a marker 10 cm away
    /// covers about 25 pixels at 160 × 120 seen head-on, a few where it is seen edge-on).
    pub min_cluster_pixels: usize,
    /// Largest distance from a cluster's centroid to any of its points in an accepted cluster,
    /// metres. Default 0.005 (twice the 2.5 mm marker radius).
    pub max_cluster_radius_m: Real,
    /// How a cluster's centre is computed. Default `surface-fit`.
    pub centre: CentreMethod,

    /// Gate around a rest-pose or along-the-finger prediction, metres. Default 0.005 (half the
    /// marker spacing of the parametric finger, so a match cannot be a neighbour).
    pub rest_gate_m: Real,
    /// Gate around a tracked marker's prediction, metres. Default 0.004.
    pub track_gate_m: Real,
    /// Growth of the track gate per frame the marker has been missing, metres. Default 0.0005.
    pub gate_growth_m: Real,
    /// Frames a marker may be missing before its track is dropped. Default 30.
    pub max_missing_frames: u32,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            hue_center_deg: 0.0,
            hue_tolerance_deg: 20.0,
            min_saturation: 0.55,
            min_value: 0.15,
            voxel_m: 0.001,
            dbscan_eps_m: 0.0018,
            dbscan_min_points: 3,
            min_cluster_pixels: 4,
            max_cluster_radius_m: 0.005,
            centre: CentreMethod::SurfaceFit,
            rest_gate_m: 0.005,
            track_gate_m: 0.004,
            gate_growth_m: 0.0005,
            max_missing_frames: 30,
        }
    }
}

impl DetectorConfig {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`TouchError::InvalidDetector`] naming the first bad one.
    pub fn validate(&self) -> Result<(), TouchError> {
        let reals = [
            ("hue_center_deg", self.hue_center_deg, (-360.0, 360.0)),
            ("hue_tolerance_deg", self.hue_tolerance_deg, (0.0, 180.0)),
            ("min_saturation", self.min_saturation, (0.0, 1.0)),
            ("min_value", self.min_value, (0.0, 1.0)),
            ("dbscan_eps_m", self.dbscan_eps_m, (1e-6, 0.1)),
            ("voxel_m", self.voxel_m, (1e-5, 0.05)),
            (
                "max_cluster_radius_m",
                self.max_cluster_radius_m,
                (1e-5, 1.0),
            ),
            ("rest_gate_m", self.rest_gate_m, (0.0, 1.0)),
            ("track_gate_m", self.track_gate_m, (0.0, 1.0)),
            ("gate_growth_m", self.gate_growth_m, (0.0, 1.0)),
        ];
        for (name, value, (lo, hi)) in reals {
            if !(value >= lo && value <= hi) {
                return Err(TouchError::InvalidDetector {
                    name,
                    value,
                    reason: "out of range (see DetectorConfig's documentation)",
                });
            }
        }
        let counts = [
            ("dbscan_min_points", self.dbscan_min_points, 2, 1000),
            ("min_cluster_pixels", self.min_cluster_pixels, 1, 1_000_000),
            (
                "max_missing_frames",
                self.max_missing_frames as usize,
                0,
                1_000_000,
            ),
        ];
        for (name, value, lo, hi) in counts {
            if !(lo..=hi).contains(&value) {
                return Err(TouchError::InvalidDetector {
                    name,
                    value: value as Real,
                    reason: "out of range (see DetectorConfig's documentation)",
                });
            }
        }
        Ok(())
    }
}

/// What became of a cluster.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "fate")]
pub enum ClusterFate {
    /// It is this marker.
    Assigned {
        /// Finger index.
        finger: usize,
        /// Marker index on the finger (0 at the base).
        marker: usize,
        /// Distance from the marker's expected position, metres (the assignment cost).
        distance_m: Real,
        /// Where the expected position came from.
        prior: Prior,
    },
    /// Fewer pixels than `min_cluster_pixels`.
    TooSmall,
    /// Radius above `max_cluster_radius_m`.
    TooLarge,
    /// No unmatched marker expects a cluster within its gate here.
    OutsideGates,
}

/// One DBSCAN cluster of a frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClusterReport {
    /// Centre in the hand frame, metres.
    pub centre_in_hand: [Real; 3],
    /// Pixel `(column, row)` of the centre's projection.
    pub centre_px: [Real; 2],
    /// Marker pixels with depth in the cluster.
    pub pixels: usize,
    /// Largest distance from the centroid to a point of the cluster, metres.
    pub radius_m: Real,
    /// Accepted as a marker, or why not.
    #[serde(flatten)]
    pub fate: ClusterFate,
}

/// What a frame's detection saw and decided.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerDiagnostics {
    /// Marker-coloured pixels.
    pub red_pixels: usize,
    /// Of those, with valid depth.
    pub red_pixels_with_depth: usize,
    /// Voxels clustered by DBSCAN.
    pub cells: usize,
    /// Every cluster DBSCAN found, with its fate.
    pub clusters: Vec<ClusterReport>,
    /// Whether the frame started without a usable prior (rest-pose matching).
    pub tracking_lost: bool,
    /// Per finger, per marker: distance from its expected position to its cluster, metres, or
    /// `None` when it was not found.
    pub assignment_distance_m: Vec<Vec<Option<Real>>>,
    /// Markers found.
    pub found: usize,
    /// Markers not found.
    pub missing: usize,
}

impl MarkerDiagnostics {
    /// Clusters rejected for each reason: too small, too large, outside every gate.
    pub fn rejected(&self) -> (usize, usize, usize) {
        let count =
            |f: fn(&ClusterFate) -> bool| self.clusters.iter().filter(|c| f(&c.fate)).count();
        (
            count(|f| matches!(f, ClusterFate::TooSmall)),
            count(|f| matches!(f, ClusterFate::TooLarge)),
            count(|f| matches!(f, ClusterFate::OutsideGates)),
        )
    }
}

/// One frame's result.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerDetection {
    /// Every marker of every finger in the hand frame, `None` where it was not found.
    pub keypoints: HandKeypoints,
    /// What the detector saw and decided.
    pub diagnostics: MarkerDiagnostics,
}

/// Finds and tracks the hand's markers in wrist-camera frames; see the module documentation.
#[derive(Debug, Clone)]
pub struct MarkerDetector {
    intrinsics: CameraIntrinsics,
    hand_from_camera: HandFromCamera,
    config: DetectorConfig,
    test: segment::RedTest,
    tracker: track::Tracker,
}

impl MarkerDetector {
    /// A detector for a camera with `intrinsics` mounted at `hand_from_camera`, looking at the
    /// markers of `hand`.
    ///
    /// # Errors
    /// Intrinsics that are not finite and positive ([`TouchError::Geometry`]), a mounting pose
    /// that is not finite or a bad parameter ([`TouchError::InvalidDetector`]). (A hand always
    /// has markers: [`moe_geom::FingerModel`] refuses a finger without them.)
    pub fn new(
        intrinsics: CameraIntrinsics,
        hand_from_camera: HandFromCamera,
        hand: &HandModel,
        config: DetectorConfig,
    ) -> Result<Self, TouchError> {
        intrinsics.validate()?;
        config.validate()?;
        let iso = hand_from_camera.iso();
        let finite = iso.translation.vector.iter().all(|v| v.is_finite())
            && iso.rotation.coords.iter().all(|v| v.is_finite());
        if !finite {
            return Err(TouchError::InvalidDetector {
                name: "hand_from_camera",
                value: Real::NAN,
                reason: "must be finite",
            });
        }
        let tracker = track::Tracker::new(hand);
        Ok(Self {
            intrinsics,
            hand_from_camera,
            test: segment::RedTest::new(&config),
            config,
            tracker,
        })
    }

    /// A detector for the camera of a recorded episode (its intrinsics and mounting).
    ///
    /// # Errors
    /// As [`MarkerDetector::new`].
    pub fn for_episode(
        info: &moe_record::EpisodeInfo,
        hand: &HandModel,
        config: DetectorConfig,
    ) -> Result<Self, TouchError> {
        Self::new(
            info.camera.into(),
            moe_geom::Transform::new(info.hand_from_camera),
            hand,
            config,
        )
    }

    /// The parameters.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// The camera intrinsics.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// The camera mounting.
    pub fn hand_from_camera(&self) -> HandFromCamera {
        self.hand_from_camera
    }

    /// Forgets every track: the next frame is matched against the rest pose.
    pub fn reset(&mut self) {
        self.tracker.reset();
    }

    /// Detects the markers in one frame (`color_rgb8`: row-major RGB8; `depth_m`: row-major
    /// metres along the optical axis, 0 or NaN where missing) and advances the tracks.
    ///
    /// # Errors
    /// [`TouchError::ImageSize`] when an image does not have the intrinsics' size.
    pub fn detect(
        &mut self,
        color_rgb8: &[u8],
        depth_m: &[f32],
    ) -> Result<MarkerDetection, TouchError> {
        let pixels = self.intrinsics.width as usize * self.intrinsics.height as usize;
        for (what, expected, got) in [
            ("colour image bytes", 3 * pixels, color_rgb8.len()),
            ("depth image pixels", pixels, depth_m.len()),
        ] {
            if expected != got {
                return Err(TouchError::ImageSize {
                    what,
                    expected,
                    got,
                });
            }
        }
        let seg = segment::segment(
            self.config.voxel_m,
            &self.test,
            &self.intrinsics,
            color_rgb8,
            depth_m,
        );
        let labels = self.cluster_cells(&seg)?;
        let clusters = self.measure_clusters(&seg, &labels);
        Ok(self.identify(&seg, clusters))
    }

    /// DBSCAN label of every cell.
    fn cluster_cells(&self, seg: &segment::Segmentation) -> Result<Vec<Option<usize>>, TouchError> {
        if seg.cell_points.is_empty() {
            return Ok(Vec::new());
        }
        let rows: Vec<[Real; 3]> = seg.cell_points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let obs = ndarray::ArrayView2::from(rows.as_slice());
        let labels = Dbscan::params(self.config.dbscan_min_points)
            .tolerance(self.config.dbscan_eps_m)
            .transform(&obs)
            .map_err(|e| match e {
                DbscanParamsError::MinPoints => TouchError::InvalidDetector {
                    name: "dbscan_min_points",
                    value: self.config.dbscan_min_points as Real,
                    reason: "must be at least 2",
                },
                DbscanParamsError::Tolerance => TouchError::InvalidDetector {
                    name: "dbscan_eps_m",
                    value: self.config.dbscan_eps_m,
                    reason: "must be positive",
                },
            })?;
        Ok(labels.to_vec())
    }

    /// Pixels, radius, centre and size verdict of every cluster.
    fn measure_clusters(
        &self,
        seg: &segment::Segmentation,
        labels: &[Option<usize>],
    ) -> Vec<Candidate> {
        let count = labels.iter().flatten().max().map_or(0, |m| m + 1);
        let mut members: Vec<Vec<Point3>> = vec![Vec::new(); count];
        for (p, &c) in seg.points.iter().zip(&seg.cell_of) {
            if let Some(l) = labels[c as usize] {
                members[l].push(*p);
            }
        }
        members
            .into_iter()
            .filter(|m| !m.is_empty())
            .map(|points| {
                let c = centre::centroid(&points);
                let radius_m = points.iter().map(|p| (p - c).norm()).fold(0.0, Real::max);
                let fate = if points.len() < self.config.min_cluster_pixels {
                    Some(ClusterFate::TooSmall)
                } else if radius_m > self.config.max_cluster_radius_m {
                    Some(ClusterFate::TooLarge)
                } else {
                    None
                };
                // Rejected clusters (a red card can have thousands of pixels) are reported at
                // their centroid: the surface fit is for markers.
                let centre_cam = if fate.is_none() {
                    centre::marker_centre(&points, self.config.centre)
                } else {
                    c
                };
                let centre_px = self
                    .intrinsics
                    .project(&centre_cam)
                    .map_or([Real::NAN; 2], |(u, v)| [u, v]);
                Candidate {
                    centre_in_hand: self.hand_from_camera.transform_point(&centre_cam),
                    centre_px,
                    pixels: points.len(),
                    radius_m,
                    fate,
                }
            })
            .collect()
    }

    /// Assigns the accepted clusters to markers and advances the tracks.
    fn identify(
        &mut self,
        seg: &segment::Segmentation,
        mut clusters: Vec<Candidate>,
    ) -> MarkerDetection {
        let config = self.config;
        let n = self.tracker.len();
        let tracking_lost = !self.tracker.has_prior();
        let mut found: Vec<Option<Point3>> = vec![None; n];
        let mut distance: Vec<Option<Real>> = vec![None; n];
        let open: Vec<usize> = (0..clusters.len())
            .filter(|&c| clusters[c].fate.is_none())
            .collect();
        // Round 1: own tracks, or the rest pose when there is no prior.
        let first: Vec<(usize, Point3, Real, Prior)> = self
            .tracker
            .predictions(&config)
            .into_iter()
            .enumerate()
            .filter_map(|(k, p)| p.map(|(pos, gate, prior)| (k, pos, gate, prior)))
            .collect();
        let mut round = first;
        loop {
            let free: Vec<usize> = open
                .iter()
                .copied()
                .filter(|&c| clusters[c].fate.is_none())
                .collect();
            if round.is_empty() || free.is_empty() {
                break;
            }
            let cost: Vec<Vec<Real>> = round
                .iter()
                .map(|&(_, pos, gate, _)| {
                    free.iter()
                        .map(|&c| {
                            let d = (clusters[c].centre_in_hand - pos).norm();
                            if d <= gate { d } else { Real::INFINITY }
                        })
                        .collect()
                })
                .collect();
            let gates: Vec<Real> = round.iter().map(|r| r.2).collect();
            let mut progress = false;
            for (&(k, pos, _, prior), a) in round.iter().zip(assign::assign_gated(&cost, &gates)) {
                if let Some(j) = a {
                    let c = free[j];
                    let (finger, marker) = self.tracker.id(k);
                    let d = (clusters[c].centre_in_hand - pos).norm();
                    clusters[c].fate = Some(ClusterFate::Assigned {
                        finger,
                        marker,
                        distance_m: d,
                        prior,
                    });
                    found[k] = Some(clusters[c].centre_in_hand);
                    distance[k] = Some(d);
                    progress = true;
                }
            }
            if !progress {
                break;
            }
            // Further rounds: unmatched markers predicted along their finger from what this
            // frame has found so far.
            round = (0..n)
                .filter(|&k| found[k].is_none())
                .filter_map(|k| {
                    let (f, m) = self.tracker.id(k);
                    let neighbour_found = (0..n).any(|j| {
                        let (g, mm) = self.tracker.id(j);
                        g == f && mm.abs_diff(m) == 1 && found[j].is_some()
                    });
                    neighbour_found.then(|| {
                        (
                            k,
                            self.tracker.chain_prediction(k, &found),
                            config.rest_gate_m,
                            Prior::Chain,
                        )
                    })
                })
                .collect();
        }
        self.tracker.update(&found, config.max_missing_frames);

        let num_fingers = self.tracker.num_fingers();
        let mut keypoints = HandKeypoints {
            fingers: vec![Vec::new(); num_fingers],
        };
        let mut assignment_distance_m = vec![Vec::new(); num_fingers];
        for k in 0..n {
            let (f, _) = self.tracker.id(k);
            keypoints.fingers[f].push(found[k]);
            assignment_distance_m[f].push(distance[k]);
        }
        let found_count = found.iter().flatten().count();
        MarkerDetection {
            keypoints,
            diagnostics: MarkerDiagnostics {
                red_pixels: seg.red_pixels,
                red_pixels_with_depth: seg.points.len(),
                cells: seg.cell_points.len(),
                clusters: clusters
                    .into_iter()
                    .map(|c| ClusterReport {
                        centre_in_hand: [
                            c.centre_in_hand.x,
                            c.centre_in_hand.y,
                            c.centre_in_hand.z,
                        ],
                        centre_px: c.centre_px,
                        pixels: c.pixels,
                        radius_m: c.radius_m,
                        fate: c.fate.unwrap_or(ClusterFate::OutsideGates),
                    })
                    .collect(),
                tracking_lost,
                assignment_distance_m,
                found: found_count,
                missing: n - found_count,
            },
        }
    }
}

/// A cluster on its way through identification (`fate: None` while it is still open).
#[derive(Debug, Clone)]
struct Candidate {
    centre_in_hand: Point3,
    centre_px: [Real; 2],
    pixels: usize,
    radius_m: Real,
    fate: Option<ClusterFate>,
}
