//! Scalar and linear-algebra aliases used across the workspace, and the one seam to parry's glam
//! types.
//!
//! Geometry, ARAP, GPIS and FEM all compute in `f64` ([`Real`]). parry3d-f64 0.31 speaks glam
//! (`DVec3`, `DPose3`); the conversions below are the only place where the two meet, so the rest of
//! the workspace sees nalgebra only.

/// The scalar type of geometry, ARAP, GPIS and FEM.
pub type Real = f64;
/// A point in some frame (the frame is carried by the variable name: `p_in_hand`).
pub type Point3 = nalgebra::Point3<Real>;
/// A free vector.
pub type Vector3 = nalgebra::Vector3<Real>;
/// A 3 × 3 matrix (rotations, covariance, stiffness blocks).
pub type Matrix3 = nalgebra::Matrix3<Real>;
/// A rigid transform (rotation then translation).
pub type Iso3 = nalgebra::Isometry3<Real>;
/// A unit quaternion.
pub type UnitQuat = nalgebra::UnitQuaternion<Real>;
/// A 3-D translation.
pub type Translation3 = nalgebra::Translation3<Real>;

/// parry3d-f64's vector type (glam `DVec3`).
pub type ParryVector = parry3d_f64::math::Vector;
/// parry3d-f64's rigid pose type.
pub type ParryPose = parry3d_f64::math::Pose;

/// Converts a point to parry's vector type.
#[inline]
pub fn to_parry(p: &Point3) -> ParryVector {
    ParryVector::new(p.x, p.y, p.z)
}

/// Converts a vector to parry's vector type.
#[inline]
pub fn vec_to_parry(v: &Vector3) -> ParryVector {
    ParryVector::new(v.x, v.y, v.z)
}

/// Converts parry's vector type to a point.
#[inline]
pub fn from_parry(v: ParryVector) -> Point3 {
    Point3::new(v.x, v.y, v.z)
}

/// Converts parry's vector type to a free vector.
#[inline]
pub fn vec_from_parry(v: ParryVector) -> Vector3 {
    Vector3::new(v.x, v.y, v.z)
}

/// Converts a rigid transform to parry's pose type.
pub fn iso_to_parry(iso: &Iso3) -> ParryPose {
    let q = iso.rotation.quaternion();
    let t = iso.translation.vector;
    ParryPose::from_parts(
        ParryVector::new(t.x, t.y, t.z),
        parry3d_f64::glamx::DQuat::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

/// True when every coordinate is finite.
#[inline]
pub fn is_finite_point(p: &Point3) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parry_round_trip_is_exact() {
        let p = Point3::new(0.1, -2.5, 3.25e-3);
        assert_eq!(from_parry(to_parry(&p)), p);
    }

    #[test]
    fn iso_conversion_moves_points_the_same_way() {
        let iso = Iso3::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(0.3, -0.2, 0.9));
        let pose = iso_to_parry(&iso);
        let p = Point3::new(0.5, -0.25, 2.0);
        let a = iso * p;
        let b = from_parry(pose * to_parry(&p));
        assert!((a - b).norm() < 1e-12, "{a} vs {b}");
    }
}
