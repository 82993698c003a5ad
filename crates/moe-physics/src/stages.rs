//! The physics estimator behind the pipeline's seams: `ShapeEstimator` (the dented surface)
//! and `ContactEstimator` (per-vertex probability and force), alone or as two stages that share
//! one estimate per observation.

use std::sync::{Arc, Mutex, PoisonError};

use moe_geom::{
    ContactEstimate, ContactEstimator, ContactInput, HandKeypoints, HandShape, Real,
    ShapeEstimator, ShapeInput, WorldFromHand,
};

use crate::error::PhysicsError;
use crate::estimator::{PhysicsEstimate, PhysicsEstimator, PhysicsObservation};

/// What an observation must carry for the physics estimator.
fn observation<'a>(
    keypoints: Option<&'a HandKeypoints>,
    tendon_pull_m: Option<&'a [Vec<Real>]>,
    world_from_hand: Option<&'a WorldFromHand>,
    time_secs: Option<Real>,
) -> Result<PhysicsObservation<'a>, PhysicsError> {
    Ok(PhysicsObservation {
        keypoints: keypoints.ok_or(PhysicsError::Missing {
            what: "the observed markers (keypoints)",
        })?,
        tendon_pull_m: tendon_pull_m.ok_or(PhysicsError::Missing {
            what: "the tendon pulls",
        })?,
        world_from_hand: world_from_hand.ok_or(PhysicsError::Missing {
            what: "the hand's pose (world_from_hand), for the direction of gravity",
        })?,
        time_secs,
    })
}

impl PhysicsEstimate {
    /// The estimate as the contact seam reports it: per-vertex probability and force.
    pub fn contact_estimate(&self) -> ContactEstimate {
        ContactEstimate {
            map: self.contact.clone(),
            vertex_force_n: Some(self.vertex_force_n.clone()),
        }
    }
}

impl ShapeEstimator for PhysicsEstimator {
    type Error = PhysicsError;

    /// Refused: the physics estimator needs the tendon pulls and the hand's pose
    /// ([`ShapeEstimator::estimate_shape_with`]).
    fn estimate_shape(&mut self, _keypoints: &HandKeypoints) -> Result<HandShape, PhysicsError> {
        Err(PhysicsError::Missing {
            what: "the tendon pulls and the hand's pose (use estimate_shape_with)",
        })
    }

    fn estimate_shape_with(&mut self, input: &ShapeInput<'_>) -> Result<HandShape, PhysicsError> {
        let obs = observation(
            Some(input.keypoints),
            input.tendon_pull_m,
            input.world_from_hand,
            input.time_secs,
        )?;
        Ok(self.estimate(&obs)?.shape)
    }

    fn reset(&mut self) {
        PhysicsEstimator::reset(self);
    }
}

impl ContactEstimator for PhysicsEstimator {
    type Error = PhysicsError;

    /// The loads from the input's markers, pulls and pose; the input's shape is not used (the
    /// estimate makes its own).
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, PhysicsError> {
        let obs = observation(
            input.keypoints,
            input.tendon_pull_m,
            input.world_from_hand,
            input.time_secs,
        )?;
        Ok(PhysicsEstimator::estimate(self, &obs)?.contact_estimate())
    }

    fn reset(&mut self) {
        PhysicsEstimator::reset(self);
    }
}

/// The last estimate and the observation it was made from.
#[derive(Debug)]
struct Shared {
    estimator: PhysicsEstimator,
    last: Option<(ObservationKey, PhysicsEstimate)>,
}

/// What identifies an observation: its markers, pulls, pose and time.
#[derive(Debug, Clone, PartialEq)]
struct ObservationKey {
    keypoints: HandKeypoints,
    pulls: Vec<Vec<Real>>,
    world_from_hand: moe_geom::Iso3,
    time_secs: Option<Real>,
}

impl Shared {
    /// The estimate of `obs`: the last one when it was made from the same observation.
    fn estimate(&mut self, obs: &PhysicsObservation<'_>) -> Result<PhysicsEstimate, PhysicsError> {
        let key = ObservationKey {
            keypoints: obs.keypoints.clone(),
            pulls: obs.tendon_pull_m.to_vec(),
            world_from_hand: *obs.world_from_hand.iso(),
            time_secs: obs.time_secs,
        };
        if let Some((k, e)) = &self.last
            && *k == key
        {
            return Ok(e.clone());
        }
        let e = self.estimator.estimate(obs)?;
        self.last = Some((key, e.clone()));
        Ok(e)
    }
}

/// The shape stage of a pipeline run by the physics estimator (see [`PhysicsEstimator::stages`]).
#[derive(Debug, Clone)]
pub struct PhysicsShapeStage(Arc<Mutex<Shared>>);

/// The contact stage of a pipeline run by the physics estimator: it reuses the estimate its
/// shape stage made of the same observation (see [`PhysicsEstimator::stages`]).
#[derive(Debug, Clone)]
pub struct PhysicsContactStage(Arc<Mutex<Shared>>);

impl PhysicsEstimator {
    /// The estimator as a pipeline's shape and contact stages sharing one estimate per
    /// observation: the shape stage estimates, the contact stage reads the same estimate
    /// (the observation is estimated once).
    pub fn stages(self) -> (PhysicsShapeStage, PhysicsContactStage) {
        let shared = Arc::new(Mutex::new(Shared {
            estimator: self,
            last: None,
        }));
        (
            PhysicsShapeStage(Arc::clone(&shared)),
            PhysicsContactStage(shared),
        )
    }
}

fn lock(shared: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    // A panic while estimating leaves nothing half-written that the next call depends on: the
    // cache is replaced only after a successful estimate.
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

impl PhysicsShapeStage {
    /// The latest estimate (loads, forces and the finger reports), when there is one.
    pub fn last_estimate(&self) -> Option<PhysicsEstimate> {
        lock(&self.0).last.as_ref().map(|(_, e)| e.clone())
    }
}

impl PhysicsContactStage {
    /// The latest estimate (loads, forces and the finger reports), when there is one.
    pub fn last_estimate(&self) -> Option<PhysicsEstimate> {
        lock(&self.0).last.as_ref().map(|(_, e)| e.clone())
    }
}

impl ShapeEstimator for PhysicsShapeStage {
    type Error = PhysicsError;

    fn estimate_shape(&mut self, keypoints: &HandKeypoints) -> Result<HandShape, PhysicsError> {
        lock(&self.0).estimator.estimate_shape(keypoints)
    }

    fn estimate_shape_with(&mut self, input: &ShapeInput<'_>) -> Result<HandShape, PhysicsError> {
        let obs = observation(
            Some(input.keypoints),
            input.tendon_pull_m,
            input.world_from_hand,
            input.time_secs,
        )?;
        Ok(lock(&self.0).estimate(&obs)?.shape)
    }

    fn reset(&mut self) {
        let mut s = lock(&self.0);
        s.estimator.reset();
        s.last = None;
    }
}

impl ContactEstimator for PhysicsContactStage {
    type Error = PhysicsError;

    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, PhysicsError> {
        let obs = observation(
            input.keypoints,
            input.tendon_pull_m,
            input.world_from_hand,
            input.time_secs,
        )?;
        Ok(lock(&self.0).estimate(&obs)?.contact_estimate())
    }

    fn reset(&mut self) {
        let mut s = lock(&self.0);
        s.estimator.reset();
        s.last = None;
    }
}
