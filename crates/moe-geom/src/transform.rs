//! Rigid transforms that carry their frames in the type.
//!
//! `Transform<To, From>` maps coordinates expressed in frame `From` to frame `To`, so
//! `world_from_hand * hand_from_finger` is a `Transform<World, Finger>` and composing in the
//! wrong order does not compile. Frames (docs/design.md): `world`; `hand` (palm, z from the palm toward
//! the fingertips); `finger` (base at the origin, z along the finger); `camera` (OpenCV: x right,
//! y down, z forward).

use std::marker::PhantomData;
use std::ops::Mul;

use serde::{Deserialize, Serialize};

use crate::math::{Iso3, Point3, Vector3};

/// Frame markers.
pub mod frame {
    /// The world (robot base) frame.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct World;
    /// The hand (palm) frame: z from the palm toward the fingertips.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Hand;
    /// A finger's frame: base centre at the origin, z along the finger.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Finger;
    /// The wrist camera's optical frame (OpenCV: x right, y down, z forward).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Camera;
}

/// A rigid transform from frame `From` to frame `To`.
#[derive(Serialize, Deserialize)]
#[serde(transparent, bound = "")]
pub struct Transform<To, From> {
    iso: Iso3,
    #[serde(skip)]
    frames: PhantomData<fn(From) -> To>,
}

/// `world_from_hand`: where the hand is, from robot kinematics.
pub type WorldFromHand = Transform<frame::World, frame::Hand>;
/// `hand_from_finger`: where a finger's base sits on the palm.
pub type HandFromFinger = Transform<frame::Hand, frame::Finger>;
/// `camera_from_hand`: the wrist camera's mounting, inverted.
pub type CameraFromHand = Transform<frame::Camera, frame::Hand>;
/// `hand_from_camera`: the wrist camera's mounting (a calibration: the camera rides on the wrist).
pub type HandFromCamera = Transform<frame::Hand, frame::Camera>;

impl<To, From> Transform<To, From> {
    /// Wraps an isometry that maps `From` coordinates to `To` coordinates.
    pub fn new(iso: Iso3) -> Self {
        Self {
            iso,
            frames: PhantomData,
        }
    }

    /// The identity (the two frames coincide).
    pub fn identity() -> Self {
        Self::new(Iso3::identity())
    }

    /// The underlying isometry.
    pub fn iso(&self) -> &Iso3 {
        &self.iso
    }

    /// Maps a point given in `From` to `To`.
    pub fn transform_point(&self, p_in_from: &Point3) -> Point3 {
        self.iso.transform_point(p_in_from)
    }

    /// Maps a free vector given in `From` to `To` (rotation only).
    pub fn transform_vector(&self, v_in_from: &Vector3) -> Vector3 {
        self.iso.transform_vector(v_in_from)
    }

    /// Maps many points.
    pub fn transform_points(&self, points_in_from: &[Point3]) -> Vec<Point3> {
        points_in_from
            .iter()
            .map(|p| self.iso.transform_point(p))
            .collect()
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Transform<From, To> {
        Transform::new(self.iso.inverse())
    }
}

impl<To, From> Clone for Transform<To, From> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<To, From> Copy for Transform<To, From> {}

impl<To, From> PartialEq for Transform<To, From> {
    fn eq(&self, other: &Self) -> bool {
        self.iso == other.iso
    }
}

impl<To, From> std::fmt::Debug for Transform<To, From> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let short = |s: &'static str| s.rsplit("::").next().unwrap_or(s);
        write!(
            f,
            "Transform<{}, {}>({:?})",
            short(std::any::type_name::<To>()),
            short(std::any::type_name::<From>()),
            self.iso
        )
    }
}

impl<A, B, C> Mul<Transform<B, C>> for Transform<A, B> {
    type Output = Transform<A, C>;
    fn mul(self, rhs: Transform<B, C>) -> Transform<A, C> {
        Transform::new(self.iso * rhs.iso)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frame::{Finger, Hand, World};

    #[test]
    fn composition_is_right_to_left_and_inverse_undoes() {
        let world_from_hand: Transform<World, Hand> = Transform::new(Iso3::new(
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 0.5),
        ));
        let hand_from_finger: Transform<Hand, Finger> = Transform::new(Iso3::new(
            Vector3::new(0.0, 0.03, 0.0),
            Vector3::new(0.2, 0.0, 0.0),
        ));
        let world_from_finger = world_from_hand * hand_from_finger;
        let p_in_finger = Point3::new(0.0, 0.0, 0.08);
        let direct = world_from_finger.transform_point(&p_in_finger);
        let stepwise =
            world_from_hand.transform_point(&hand_from_finger.transform_point(&p_in_finger));
        assert!((direct - stepwise).norm() < 1e-15);
        let back = world_from_finger.inverse().transform_point(&direct);
        assert!((back - p_in_finger).norm() < 1e-15);
    }
}
