//! Scale: exact inference at the documented limit of 5000 observations, and the switch to the
//! sparse approximation one observation beyond it.

use moe_geom::{Point3, Real, SeededRng, Vector3};
use moe_gpis::{Gpis, GpisConfig, Hyper, Observations, SphereMean, condition};

const SEMI_AXES: [Real; 3] = [0.09, 0.08, 0.07];

/// Random points on an ellipsoid (radial projection of Gaussian directions).
fn on_ellipsoid(n: usize, seed: u64) -> Vec<Point3> {
    let mut rng = SeededRng::new(seed);
    (0..n)
        .map(|_| {
            let d = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            let s = (0..3)
                .map(|i| (d[i] / SEMI_AXES[i]).powi(2))
                .sum::<Real>()
                .sqrt();
            Point3::from(d / s)
        })
        .collect()
}

/// The largest |posterior mean| (metres from the zero level set, to first order) at `points`.
fn worst_abs_mean(gpis: &Gpis<SphereMean>, points: &[Point3]) -> Real {
    points
        .iter()
        .map(|p| gpis.mean_at(p).abs())
        .fold(0.0, Real::max)
}

fn config() -> GpisConfig {
    GpisConfig {
        fixed: Some(Hyper {
            signal_variance: 1e-4,
            lengthscale: 0.03,
            noise_variance: 1e-10,
        }),
        ..GpisConfig::default()
    }
}

fn sphere() -> SphereMean {
    SphereMean {
        center: Point3::origin(),
        radius: 0.08,
    }
}

#[test]
fn five_thousand_observations_are_conditioned_exactly() {
    let contacts = on_ellipsoid(5000, 1);
    let obs = Observations::from_contacts(&contacts).unwrap();
    let (gpis, report) = condition(sphere(), &obs, &config()).unwrap();
    assert!(!report.sparse);
    assert!(report.log_marginal_likelihood.unwrap().is_finite());
    // The posterior mean interpolates the (nearly noise-free) observations: the sphere mean is
    // off by up to 10 mm on this ellipsoid, the posterior by less than a micrometre.
    let every_25th: Vec<Point3> = contacts.iter().step_by(25).copied().collect();
    let worst_obs = worst_abs_mean(&gpis, &every_25th);
    assert!(worst_obs < 1e-6, "{worst_obs} m at an observation");
    // And it lies on the ellipsoid between them.
    let worst = worst_abs_mean(&gpis, &on_ellipsoid(200, 2));
    assert!(worst < 1e-5, "{worst} m at a held-out surface point");
}

#[test]
fn one_more_observation_switches_to_the_sparse_approximation() {
    let contacts = on_ellipsoid(5001, 1);
    let obs = Observations::from_contacts(&contacts).unwrap();
    let (gpis, report) = condition(sphere(), &obs, &config()).unwrap();
    assert!(report.sparse);
    assert!(report.log_marginal_likelihood.is_none());
    let worst = worst_abs_mean(&gpis, &on_ellipsoid(200, 2));
    assert!(worst < 1e-4, "{worst} m at a held-out surface point");
}
