//! The benchmark scenes: seeded ground truth and prior shapes and the patted contacts.

use moe_geom::bodies::{ArmParams, HeadParams};
use moe_geom::{Point3, Real, SeededRng, TriMesh, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;

/// Which scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// A head patted on top, back and sides.
    Head,
    /// An elongated 2:20:1 arm patted along its top and outer side.
    Arm,
}

/// How to build a scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BenchSceneConfig {
    /// Head or arm.
    pub kind: SceneKind,
    /// Seed of the ground-truth shape.
    pub truth_seed: u64,
    /// Seed of the prior shape (a different member of the family).
    pub prior_seed: u64,
    /// Seed of the contact sampling and noise.
    pub contact_seed: u64,
    /// Contacts per patch.
    pub contacts_per_patch: usize,
    /// Standard deviation of the isotropic contact noise, metres (default 1 mm).
    pub noise_m: Real,
    /// Icosphere level of the ground-truth and prior meshes.
    pub mesh_level: u32,
}

impl BenchSceneConfig {
    /// The default head scene (6 patches × 50 contacts).
    pub fn head() -> Self {
        Self {
            kind: SceneKind::Head,
            truth_seed: 1,
            prior_seed: 2,
            contact_seed: 3,
            contacts_per_patch: 50,
            noise_m: 1e-3,
            mesh_level: 5,
        }
    }

    /// The default arm scene (8 patches × 35 contacts).
    pub fn arm() -> Self {
        Self {
            kind: SceneKind::Arm,
            contacts_per_patch: 35,
            ..Self::head()
        }
    }
}

/// A ground truth, a prior and contacts.
#[derive(Debug, Clone)]
pub struct BenchScene {
    /// The hidden surface.
    pub truth: TriMesh,
    /// The task prior (another member of the family).
    pub prior: TriMesh,
    /// Noisy contact points on the truth.
    pub contacts: Vec<Point3>,
}

/// Uniform direction in the cap of angular radius `alpha` around `axis`.
fn direction_in_cap(rng: &mut SeededRng, axis: &Vector3, alpha: Real) -> Vector3 {
    let cos_t = 1.0 - rng.uniform() * (1.0 - alpha.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.uniform();
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    (axis * cos_t + (u * phi.cos() + v * phi.sin()) * sin_t).normalize()
}

/// Builds a scene.
///
/// # Errors
/// Mesh validation (never for the built-in families).
pub fn build_scene(config: &BenchSceneConfig) -> Result<BenchScene, GpisError> {
    let mut rng = SeededRng::new(config.contact_seed);
    let noise = |rng: &mut SeededRng| {
        Vector3::new(rng.normal(), rng.normal(), rng.normal()) * config.noise_m
    };
    match config.kind {
        SceneKind::Head => {
            let truth = HeadParams::sample(config.truth_seed);
            let prior = HeadParams::sample(config.prior_seed);
            // Top, crown, back, two sides, front of the scalp above the forehead.
            let patches = [
                Vector3::new(0.0, 0.0, 1.0),
                Vector3::new(0.0, -0.7, 0.7),
                Vector3::new(0.0, -1.0, 0.15),
                Vector3::new(1.0, -0.1, 0.35),
                Vector3::new(-1.0, -0.1, 0.35),
                Vector3::new(0.0, 0.55, 0.85),
            ];
            let mut contacts = Vec::new();
            for axis in patches {
                let axis = axis.normalize();
                for _ in 0..config.contacts_per_patch {
                    let d = direction_in_cap(&mut rng, &axis, 0.38);
                    let p = Point3::from(d * truth.radius(&d));
                    contacts.push(p + noise(&mut rng));
                }
            }
            Ok(BenchScene {
                truth: truth.mesh(config.mesh_level)?,
                prior: prior.mesh(config.mesh_level)?,
                contacts,
            })
        }
        SceneKind::Arm => {
            let truth = ArmParams::sample(config.truth_seed);
            let prior = ArmParams::sample(config.prior_seed);
            let mut contacts = Vec::new();
            // Four stations along the arm, top (z) and outer side (x).
            for s0 in [-0.6, -0.2, 0.2, 0.6] {
                for phi0 in [std::f64::consts::FRAC_PI_2, 0.0] {
                    for _ in 0..config.contacts_per_patch {
                        let s: Real = s0 + rng.uniform_range(-0.12, 0.12);
                        let phi: Real = phi0 + rng.uniform_range(-0.6, 0.6);
                        let q = (1.0 - s * s).sqrt();
                        let d = Vector3::new(q * phi.cos(), s, q * phi.sin());
                        contacts.push(truth.point(&d) + noise(&mut rng));
                    }
                }
            }
            Ok(BenchScene {
                truth: truth.mesh(config.mesh_level)?,
                prior: prior.mesh(config.mesh_level)?,
                contacts,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_are_reproducible_closed_and_plausible() {
        let cfg = BenchSceneConfig {
            mesh_level: 3,
            ..BenchSceneConfig::head()
        };
        let a = build_scene(&cfg).unwrap();
        let b = build_scene(&cfg).unwrap();
        assert_eq!(a.contacts, b.contacts);
        assert_eq!(a.truth, b.truth);
        a.truth.require_closed().unwrap();
        a.prior.require_closed().unwrap();
        assert_ne!(a.truth, a.prior);
        assert_eq!(a.contacts.len(), 300);
        let ext = a.truth.aabb().extents();
        assert!(
            ext.x > 0.12 && ext.x < 0.2 && ext.y > 0.16 && ext.y < 0.25,
            "{ext}"
        );
        assert!(ext.z > 0.22 && ext.z < 0.32, "{ext}");
        let arm = build_scene(&BenchSceneConfig {
            mesh_level: 3,
            ..BenchSceneConfig::arm()
        })
        .unwrap();
        let e = arm.truth.aabb().extents();
        assert!(e.y > 8.0 * e.x && e.x > 1.5 * e.z, "2:20:1 ({e})");
        arm.truth.require_closed().unwrap();
    }
}
