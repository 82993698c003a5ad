//! The grasp plane rule: the incline's plane from a press's hold, as the pipeline's frame
//! estimates show it. Pure: a robot calls [`fit_grasp_plane`] with its own estimates (built
//! with [`finger_views`]); the simulated grasp trials call the same function.

use moe_geom::{
    ContactPoint, GeomError, HandModel, HandShape, Point3, RansacConfig, Real, Vector3,
    fit_plane_ransac,
};
use moe_touch::FrameEstimate;
use serde::Serialize;

use super::GraspOptions;

/// What a plane was fitted through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlaneSource {
    /// RANSAC through the contact points of the press's hold (the paper's fit).
    ContactPoints,
    /// The plane through the tips of the loaded fingers, when three or more are loaded and the
    /// tips of at least three of them were seen: per such finger the vertex of its estimated
    /// shape farthest along the press, averaged over the hold frames in which it is loaded and
    /// its most distal marker seen. Which fingers touch comes from their deformation, not from
    /// the contact classifier, so a finger whose contacts the classifier misses still counts,
    /// and contacts placed up a finger do not tilt the plane.
    LoadedFingertips,
    /// Three or more fingers loaded but only two tips seen (a finger pressed along its axis
    /// hides its distal markers from the wrist camera, and its estimated tip is then
    /// extrapolated): the plane through the two seen tips whose normal is nearest the hand's
    /// axis. All fingers touching says the axis is near the normal; the seen tips fix the rest.
    TwoFingertipsAndAxis,
    /// Three or more fingers loaded and fewer than two tips seen: the hand's own axis (all
    /// fingers touching says the palm already faces the plate; no tips say better).
    LoadedFingersAxis,
}

impl PlaneSource {
    /// Its name, as serialised: `contact-points`, `loaded-fingertips`,
    /// `two-fingertips-and-axis`, `loaded-fingers-axis`.
    pub fn name(self) -> &'static str {
        match self {
            Self::ContactPoints => "contact-points",
            Self::LoadedFingertips => "loaded-fingertips",
            Self::TwoFingertipsAndAxis => "two-fingertips-and-axis",
            Self::LoadedFingersAxis => "loaded-fingers-axis",
        }
    }
}

/// One finger in one frame of a hold, as the plane rule reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerView {
    /// The vertices of its estimated shape, world frame.
    pub vertices_in_world: Vec<Point3>,
    /// The largest distance of a vertex of its estimated shape from its rest position, metres
    /// (compared in the hand frame: a rigid move of the hand moves no vertex from rest).
    pub displacement_m: Real,
    /// Whether its most distal marker was seen: without it the shape estimate extrapolates the
    /// tip (a hidden tip of a finger pressed along its axis was placed 5.8–7.8 mm past the plate,
    /// at the uncompressed length, where the seen ones were within 2.3 mm).
    pub tip_seen: bool,
}

impl FingerView {
    /// The finite vertex farthest along `axis`: the finger's tip for a press along `axis`.
    pub fn tip(&self, axis: &Vector3) -> Option<Point3> {
        self.vertices_in_world
            .iter()
            .filter(|p| moe_geom::math::is_finite_point(p))
            .max_by(|a, b| axis.dot(&a.coords).total_cmp(&axis.dot(&b.coords)))
            .copied()
    }
}

/// The largest distance of a vertex from its rest position (vertices in the same frame as the
/// rest positions; non-finite distances skipped).
pub(super) fn largest_displacement(at: &[Point3], rest: &[Point3]) -> Real {
    at.iter()
        .zip(rest)
        .map(|(a, r)| (a - r).norm())
        .filter(|d| d.is_finite())
        .fold(0.0, Real::max)
}

/// Per finger of `hand`, the index of its most distal marker
/// ([`moe_geom::FingerModel::distal_marker_order`]): the marker whose sight says the finger's
/// tip was seen ([`FingerView::tip_seen`]).
pub fn distal_markers(hand: &HandModel) -> Vec<usize> {
    hand.fingers()
        .iter()
        .map(|f| f.model.distal_marker_order().first().copied().unwrap_or(0))
        .collect()
}

/// The fingers of one frame estimate as the plane rule reads them, one per finger of `rest`
/// (the hand's rest shape, hand frame: [`HandShape::rest`]): the estimated shape in the world,
/// its largest displacement from rest, and whether the finger's most distal marker
/// (`distal_markers`, from [`distal_markers`]) was seen. A finger the estimate lacks has no
/// vertices and no displacement.
pub fn finger_views<D>(
    estimate: &FrameEstimate<D>,
    rest: &HandShape,
    distal_markers: &[usize],
) -> Vec<FingerView> {
    let to_world = |p: &Point3| estimate.world_from_hand.transform_point(p);
    rest.fingers
        .iter()
        .enumerate()
        .map(|(finger, at_rest)| {
            // Shape and rest compared in the hand frame (a rigid move keeps distances).
            let at = estimate
                .shape
                .fingers
                .get(finger)
                .map_or(&[][..], Vec::as_slice);
            FingerView {
                vertices_in_world: at.iter().map(to_world).collect(),
                displacement_m: largest_displacement(at, at_rest),
                tip_seen: distal_markers.get(finger).is_some_and(|&distal| {
                    estimate
                        .keypoints
                        .fingers
                        .get(finger)
                        .and_then(|m| m.get(distal))
                        .is_some_and(Option::is_some)
                }),
            }
        })
        .collect()
}

/// The loaded fingers of a hold (a finger is loaded when it is loaded in any hold frame) and the
/// tips of those whose tip was seen while loaded: per such finger, its vertex farthest along
/// `axis` averaged over the hold frames in which it is loaded and its tip seen.
pub(super) fn loaded_fingertips(
    shapes: &[Vec<FingerView>],
    axis: &Vector3,
    options: &GraspOptions,
) -> (Vec<usize>, Vec<Point3>) {
    let fingers = shapes.first().map_or(0, Vec::len);
    let mut loaded = Vec::new();
    let mut tips = Vec::new();
    for finger in 0..fingers {
        let states = shapes
            .iter()
            .filter_map(|s| s.get(finger))
            .filter(|f| f.displacement_m > options.loaded_finger_m);
        let mut any = false;
        let seen: Vec<Point3> = states
            .inspect(|_| any = true)
            .filter(|f| f.tip_seen)
            .filter_map(|f| f.tip(axis))
            .collect();
        if any {
            loaded.push(finger);
        }
        if !seen.is_empty() {
            let mean = seen.iter().map(|p| p.coords).sum::<Vector3>() / seen.len() as Real;
            tips.push(Point3::from(mean));
        }
    }
    (loaded, tips)
}

/// The plane's normal from the loaded fingers (see [`PlaneSource`]), on `prior`'s side:
/// through three or more seen tips by least squares; through two, the plane containing them
/// whose normal is nearest `prior` (the hand's axis); with fewer, `prior`. `None` with fewer
/// than `min_loaded` loaded fingers, or when the tips do not span a plane.
pub(super) fn fingertip_plane(
    loaded: usize,
    min_loaded: usize,
    tips: &[Point3],
    prior: &Vector3,
    ransac: &RansacConfig,
) -> Option<(PlaneSource, Vector3)> {
    if loaded < min_loaded {
        return None;
    }
    match tips {
        [a, b] => {
            let line = (b - a).try_normalize(1e-9)?;
            let n = (prior - line * line.dot(prior)).try_normalize(1e-6)?;
            n.iter()
                .all(|c| c.is_finite())
                .then_some((PlaneSource::TwoFingertipsAndAxis, n))
        }
        [] | [_] => Some((PlaneSource::LoadedFingersAxis, *prior)),
        _ => {
            let everything = RansacConfig {
                distance_threshold_m: Real::MAX.sqrt(),
                ..*ransac
            };
            let fit = fit_plane_ransac(tips, &everything).ok()?;
            let n = if fit.normal.dot(prior) < 0.0 {
                -fit.normal
            } else {
                fit.normal
            };
            Some((PlaneSource::LoadedFingertips, n))
        }
    }
}

/// A fitted grasp plane.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspPlane {
    /// What it was fitted through.
    pub source: PlaneSource,
    /// Its unit normal, world frame, toward the hand: the hand presses squarely along its
    /// negation.
    pub normal: Vector3,
    /// Indices of the RANSAC inliers among the contact points (empty when the plane went
    /// through the fingertips or the hand's axis).
    pub inliers: Vec<usize>,
}

/// What [`fit_grasp_plane`] found in a hold: the loaded fingers, their seen tips and the plane.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspPlaneFit {
    /// Fingers whose estimated shape shows a load in some frame of the hold
    /// ([`GraspOptions::loaded_finger_m`]), ascending.
    pub loaded_fingers: Vec<usize>,
    /// The seen tips of the loaded fingers, world frame, in finger order (what a fingertip
    /// plane goes through).
    pub tips: Vec<Point3>,
    /// The plane, or why none could be fitted (too few contact points, points that span no
    /// plane, an invalid [`GraspOptions::ransac`]).
    pub plane: Result<GraspPlane, GeomError>,
}

/// The plane of the surface a hand presses, from the pipeline's estimates over the hold of a
/// press (the frames at full depth) — the rule of the grasp experiment, for a robot's own
/// frame estimates.
///
/// - `contacts_in_world`: the contact points of every hold frame
///   ([`FrameEstimate::contacts_in_world`], concatenated);
/// - `fingers`: per hold frame, its fingers ([`finger_views`] of the frame's estimate);
/// - `hand_axis`: the hand's axis in the world, a unit vector from the palm toward the
///   fingertips (the direction of the press);
/// - `wrist`: the wrist's position in the world during the hold (a contact-point plane's
///   normal is turned toward it).
///
/// The hand is not actuated during the press, so a finger whose estimated shape has moved more
/// than [`GraspOptions::loaded_finger_m`] from rest is one the surface pushes. With
/// [`GraspOptions::fingertip_plane`] and at least [`GraspOptions::min_loaded_fingers`] loaded
/// fingers, the plane goes through their seen tips ([`PlaneSource::LoadedFingertips`], or with
/// fewer seen tips [`PlaneSource::TwoFingertipsAndAxis`] / [`PlaneSource::LoadedFingersAxis`]);
/// otherwise, or when the tips span no plane, RANSAC ([`GraspOptions::ransac`]) through the
/// contact points gives it ([`PlaneSource::ContactPoints`]). The normal points toward the
/// hand; the hand squares up to the surface by turning its axis onto its negation.
pub fn fit_grasp_plane(
    contacts_in_world: &[ContactPoint],
    fingers: &[Vec<FingerView>],
    hand_axis: &Vector3,
    wrist: &Point3,
    options: &GraspOptions,
) -> GraspPlaneFit {
    let (loaded_fingers, tips) = loaded_fingertips(fingers, hand_axis, options);
    let through_tips = if options.fingertip_plane {
        fingertip_plane(
            loaded_fingers.len(),
            options.min_loaded_fingers,
            &tips,
            &-hand_axis,
            &options.ransac,
        )
    } else {
        None
    };
    let plane = match through_tips {
        Some((source, normal)) => Ok(GraspPlane {
            source,
            normal,
            inliers: Vec::new(),
        }),
        None => {
            let points: Vec<Point3> = contacts_in_world.iter().map(|c| c.point).collect();
            fit_plane_ransac(&points, &options.ransac).map(|fit| {
                let fit = fit.oriented_toward(wrist);
                GraspPlane {
                    source: PlaneSource::ContactPoints,
                    normal: fit.normal,
                    inliers: fit.inliers,
                }
            })
        }
    };
    GraspPlaneFit {
        loaded_fingers,
        tips,
        plane,
    }
}

#[cfg(test)]
mod tests;
