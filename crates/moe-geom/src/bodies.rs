//! Procedural human body parts for contact scenes and surface-reconstruction benchmarks: a
//! family of skull-like heads and of elongated (2:20:1) arms, each member drawn from a seed.
//!
//! Both are star-shaped surfaces on a subdivided icosahedron (see [`crate::shapes`]), so every
//! member is a closed, manifold, outward-oriented mesh at any level.

use serde::{Deserialize, Serialize};

use crate::error::GeomError;
use crate::math::{Point3, Real, Vector3};
use crate::mesh::TriMesh;
use crate::rng::SeededRng;
use crate::shapes::{star_shaped, unit_icosphere};

/// One smooth bump on the unit sphere of directions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bump {
    /// Direction of its centre.
    pub direction: Vector3,
    /// Relative height (fraction of the local radius).
    pub amplitude: Real,
    /// Angular width (radians, Gaussian sigma on the chord).
    pub width: Real,
}

impl Bump {
    fn at(&self, d: &Vector3) -> Real {
        self.amplitude
            * (-(d - self.direction).norm_squared() / (2.0 * self.width * self.width)).exp()
    }
}

/// Depth below the skull centre at which every head of the family is cropped (metres): the flat
/// cut of the neck, common to all members like the crop of a head scan data set.
pub const NECK_CROP_DEPTH: Real = 0.16;

/// Parameters of one procedural head (metres, head frame: x left–right, y towards the face,
/// z up, origin near the centre of the skull).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeadParams {
    /// Half breadth (x).
    pub half_width: Real,
    /// Half length (y).
    pub half_length: Real,
    /// Half height (z).
    pub half_height: Real,
    /// Forehead flattening (relative).
    pub forehead: Real,
    /// Occipital bulge (relative).
    pub occiput: Real,
    /// Taper of the lower head towards the jaw (relative).
    pub jaw: Real,
    /// Radius of the neck cylinder.
    pub neck_radius: Real,
    /// Depth of the neck's flat cut below the origin ([`NECK_CROP_DEPTH`] for the sampled
    /// family).
    pub neck_depth: Real,
    /// Facial features (nose, chin, brow, eye sockets) and individual smooth bumps.
    pub bumps: Vec<Bump>,
}

fn random_direction(rng: &mut SeededRng) -> Vector3 {
    loop {
        let v = Vector3::new(rng.normal(), rng.normal(), rng.normal());
        if v.norm() > 1e-6 {
            return v.normalize();
        }
    }
}

impl HeadParams {
    /// A random member of the family.
    pub fn sample(seed: u64) -> Self {
        let mut rng = SeededRng::new(seed);
        let mut around =
            |mean: Real, rel_sd: Real| mean * (1.0 + rel_sd * rng.normal().clamp(-2.5, 2.5));
        let half_width = around(0.076, 0.06);
        let half_length = around(0.096, 0.06);
        let half_height = around(0.108, 0.06);
        let forehead = around(0.10, 0.3);
        let occiput = around(0.05, 0.3);
        let jaw = around(0.22, 0.2);
        // Heads of a shape data set (and mannequins) are cropped by one rule: the neck is cut at
        // the same level below the skull for everybody; its girth follows the head's breadth.
        let neck_radius = half_width * around(0.72, 0.04);
        let neck_depth = NECK_CROP_DEPTH;
        let mut face = |x: Real, y: Real, z: Real, amplitude: Real, width: Real| Bump {
            direction: Vector3::new(x, y, z).normalize(),
            amplitude: around(amplitude, 0.25),
            width: around(width, 0.1),
        };
        let mut bumps = vec![
            face(0.0, 1.0, -0.12, 0.16, 0.10),  // nose
            face(0.0, 0.85, -0.55, 0.07, 0.15), // chin
            face(0.0, 0.95, 0.22, 0.03, 0.25),  // brow ridge
            face(0.33, 0.9, 0.12, -0.05, 0.10), // eye sockets
            face(-0.33, 0.9, 0.12, -0.05, 0.10),
            face(1.0, -0.05, -0.05, 0.06, 0.10), // ears
            face(-1.0, -0.05, -0.05, 0.06, 0.10),
        ];
        for _ in 0..6 {
            bumps.push(Bump {
                direction: random_direction(&mut rng),
                amplitude: 0.04 * rng.normal().clamp(-2.5, 2.5),
                width: rng.uniform_range(0.35, 0.6),
            });
        }
        Self {
            half_width,
            half_length,
            half_height,
            forehead,
            occiput,
            jaw,
            neck_radius,
            neck_depth,
            bumps,
        }
    }

    /// Distance from the origin to the surface along the unit direction `d`.
    pub fn radius(&self, d: &Vector3) -> Real {
        let e = (d.x / self.half_width).powi(2)
            + (d.y / self.half_length).powi(2)
            + (d.z / self.half_height).powi(2);
        let mut s = 1.0;
        s -= self.forehead * d.y.max(0.0).powi(3) * (0.5 + 0.5 * d.z).max(0.0);
        let occ = Vector3::new(0.0, -1.0, 0.25).normalize();
        s += self.occiput * (-(d - occ).norm_squared() / 0.3).exp();
        if d.z < 0.0 {
            s -= self.jaw * d.z * d.z * (1.0 - 0.4 * d.y.max(0.0));
        }
        s += self.bumps.iter().map(|b| b.at(d)).sum::<Real>();
        let head = s / e.sqrt();
        // Neck: a vertical cylinder (centred slightly behind the origin) cut flat at
        // `z = −neck_depth`, joined to the head by a smooth maximum.
        if d.z >= -0.05 {
            return head;
        }
        let horizontal = (d.x * d.x + (d.y + 0.15 * d.z).powi(2)).sqrt().max(1e-9);
        let neck = (self.neck_radius / horizontal).min(self.neck_depth / -d.z);
        let k = 0.008; // blend width, metres
        let (a, b) = (head, neck);
        let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
        b * h + a * (1.0 - h) + k * h * (1.0 - h)
    }

    /// The closed head mesh on a subdivided icosahedron of the given level.
    ///
    /// # Errors
    /// A `level` above [`crate::shapes::MAX_SUBDIVISION_LEVEL`]; mesh validation (never for the
    /// sampled family).
    pub fn mesh(&self, level: u32) -> Result<TriMesh, GeomError> {
        star_shaped(level, Point3::origin(), |d| self.radius(d))
    }
}

/// Parameters of one procedural arm (metres; y along the arm, x outward, z up).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArmParams {
    /// Half-axes of the base ellipsoid (2:20:1).
    pub half_axes: Vector3,
    /// `(position along the arm in [-1, 1], relative amplitude, width)` of cross-section changes.
    pub profile: Vec<(Real, Real, Real)>,
}

impl ArmParams {
    /// A random member of the family.
    pub fn sample(seed: u64) -> Self {
        let mut rng = SeededRng::new(seed);
        let mut j = |sd: Real| 1.0 + sd * rng.normal().clamp(-2.5, 2.5);
        let half_axes = Vector3::new(0.030 * j(0.1), 0.300 * j(0.04), 0.015 * j(0.1));
        // Wrist (narrow), forearm bulge, elbow, biceps.
        let profile = vec![
            (-0.75, -0.18 * j(0.5), 0.15),
            (-0.35, 0.12 * j(0.6), 0.2),
            (0.05, -0.08 * j(0.6), 0.12),
            (0.45, 0.15 * j(0.6), 0.2),
        ];
        Self { half_axes, profile }
    }

    fn width(&self, s: Real) -> Real {
        1.0 + self
            .profile
            .iter()
            .map(|(c, a, w)| a * (-(s - c) * (s - c) / (2.0 * w * w)).exp())
            .sum::<Real>()
    }

    /// The surface point of the unit direction `d` (ellipsoid map with the width profile).
    pub fn point(&self, d: &Vector3) -> Point3 {
        let w = self.width(d.y);
        Point3::new(
            self.half_axes.x * d.x * w,
            self.half_axes.y * d.y,
            self.half_axes.z * d.z * w,
        )
    }

    /// The closed arm mesh.
    ///
    /// # Errors
    /// A `level` above [`crate::shapes::MAX_SUBDIVISION_LEVEL`]; mesh validation (never for the
    /// sampled family).
    pub fn mesh(&self, level: u32) -> Result<TriMesh, GeomError> {
        crate::shapes::check_subdivision_level(level)?;
        let (dirs, faces) = unit_icosphere(level);
        TriMesh::new(dirs.iter().map(|d| self.point(d)).collect(), faces)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Topology;

    #[test]
    fn heads_are_closed_head_sized_and_differ_by_seed() {
        let a = HeadParams::sample(1).mesh(3).unwrap();
        let b = HeadParams::sample(2).mesh(3).unwrap();
        for m in [&a, &b] {
            m.require_closed().unwrap();
            assert_eq!(Topology::new(m).euler_characteristic(), 2);
            let e = m.aabb().extents();
            assert!(
                (0.12..0.2).contains(&e.x) && (0.15..0.25).contains(&e.y),
                "{e}"
            );
        }
        assert_ne!(a.vertices(), b.vertices());
        assert_eq!(HeadParams::sample(1), HeadParams::sample(1));
    }

    #[test]
    fn every_head_is_cropped_at_the_same_level() {
        for seed in [1, 2, 3, 40] {
            let p = HeadParams::sample(seed);
            let m = p.mesh(3).unwrap();
            let lowest = m
                .vertices()
                .iter()
                .map(|v| v.z)
                .fold(Real::INFINITY, Real::min);
            assert!(
                (lowest + NECK_CROP_DEPTH).abs() < 1e-9,
                "seed {seed}: {lowest}"
            );
            let girth = p.neck_radius / p.half_width;
            assert!((0.6..0.85).contains(&girth), "seed {seed}: {girth}");
        }
    }

    #[test]
    fn arms_are_elongated() {
        let m = ArmParams::sample(3).mesh(3).unwrap();
        m.require_closed().unwrap();
        let e = m.aabb().extents();
        assert!(e.y > 8.0 * e.x && e.x > e.z, "{e}");
    }
}
