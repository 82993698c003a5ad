//! Bad input through the public API: every case is a typed error naming the problem, never a
//! panic.

use moe_geom::shapes::icosphere;
use moe_geom::{Point3, Real, TriMesh};
use moe_gpis::parts::nonprobabilistic;
use moe_gpis::{
    FitConfig, GpisConfig, GpisError, Hyper, Jitter, MeshSdfMean, NonProbConfig, Observations,
    ReconstructOptions, SphereMean, bounds_of, condition, reconstruct,
};

fn contacts(n: usize) -> Vec<Point3> {
    icosphere(2, 0.05)
        .vertices()
        .iter()
        .take(n)
        .copied()
        .collect()
}

#[test]
fn too_few_contacts_for_each_method() {
    assert!(matches!(
        SphereMean::fit(&contacts(3)),
        Err(GpisError::TooFewObservations {
            method: "sphere",
            needed: 4,
            got: 3,
            ..
        })
    ));
    let prior = MeshSdfMean::new(&icosphere(2, 0.05)).unwrap();
    assert!(matches!(
        condition(&prior, &Observations::new(), &GpisConfig::default()),
        Err(GpisError::TooFewObservations {
            needed: 1,
            got: 0,
            ..
        })
    ));
    // Fitting needs at least three observations; fixed hyper-parameters work with one.
    let two = Observations::from_contacts(&contacts(2)).unwrap();
    assert!(matches!(
        condition(&prior, &two, &GpisConfig::default()),
        Err(GpisError::TooFewObservations {
            needed: 3,
            got: 2,
            ..
        })
    ));
    let fixed = GpisConfig {
        fixed: Some(Hyper {
            signal_variance: 1e-4,
            lengthscale: 0.03,
            noise_variance: 1e-8,
        }),
        ..GpisConfig::default()
    };
    assert!(condition(&prior, &two, &fixed).is_ok());
    assert!(matches!(
        nonprobabilistic(&icosphere(2, 0.05), &[], &NonProbConfig::default()),
        Err(GpisError::TooFewObservations {
            method: "nonprob",
            ..
        })
    ));
}

#[test]
fn nan_points_are_named() {
    let mut c = contacts(10);
    c[7].z = Real::NAN;
    assert_eq!(
        Observations::from_contacts(&c),
        Err(GpisError::NonFiniteObservation {
            what: "contact",
            index: 7
        })
    );
    assert!(matches!(
        SphereMean::fit(&c),
        Err(GpisError::NonFiniteObservation { index: 7, .. })
    ));
    let prior = MeshSdfMean::new(&icosphere(2, 0.05)).unwrap();
    let obs = Observations::from_contacts(&contacts(10)).unwrap();
    let (gpis, _) = condition(&prior, &obs, &GpisConfig::default()).unwrap();
    assert!(matches!(
        gpis.query(&[Point3::origin(), Point3::new(0.0, Real::INFINITY, 0.0)]),
        Err(GpisError::NonFiniteObservation {
            what: "query point",
            index: 1
        })
    ));
}

#[test]
fn a_non_watertight_prior_is_rejected() {
    let (v, mut f) = icosphere(2, 0.05).into_parts();
    f.truncate(f.len() - 3);
    // Dropping faces can orphan nothing here (every vertex keeps other faces).
    let open = TriMesh::new(v, f).unwrap();
    assert!(matches!(
        MeshSdfMean::new(&open),
        Err(GpisError::NonWatertightPrior { .. })
    ));
}

#[test]
fn a_singular_kernel_matrix_is_a_typed_error_after_the_jitter_budget() {
    // The same contact three times with zero noise: K is rank one.
    let p = Point3::new(0.0, 0.0, 0.05);
    let obs = Observations::from_contacts(&[p, p, p]).unwrap();
    let hyper = Hyper {
        signal_variance: 1e-4,
        lengthscale: 0.03,
        noise_variance: 0.0,
    };
    let prior = MeshSdfMean::new(&icosphere(2, 0.05)).unwrap();
    let no_jitter = GpisConfig {
        fixed: Some(hyper),
        fit: FitConfig {
            jitter: Jitter {
                max_relative: 0.0,
                ..Jitter::default()
            },
            ..FitConfig::default()
        },
        ..GpisConfig::default()
    };
    assert!(matches!(
        condition(&prior, &obs, &no_jitter),
        Err(GpisError::SingularKernel { n: 3, .. })
    ));
    // With the default jitter budget the same data conditions, and the jitter is reported.
    let (_, report) = condition(
        &prior,
        &obs,
        &GpisConfig {
            fixed: Some(hyper),
            ..GpisConfig::default()
        },
    )
    .unwrap();
    assert!(report.jitter > 0.0);
}

#[test]
fn invalid_hyper_parameters_and_grids_are_named() {
    let obs = Observations::from_contacts(&contacts(20)).unwrap();
    let prior = MeshSdfMean::new(&icosphere(2, 0.05)).unwrap();
    let bad = GpisConfig {
        fixed: Some(Hyper {
            signal_variance: -1.0,
            lengthscale: 0.03,
            noise_variance: 0.0,
        }),
        ..GpisConfig::default()
    };
    assert!(matches!(
        condition(&prior, &obs, &bad),
        Err(GpisError::InvalidParameter {
            name: "signal_variance_m2",
            ..
        })
    ));
    let b = bounds_of(&contacts(20), None).unwrap();
    let tiny = ReconstructOptions {
        max_grid_nodes: 4,
        ..ReconstructOptions::default()
    };
    assert!(matches!(
        reconstruct(&prior, &obs, &b, &tiny),
        Err(GpisError::InvalidParameter {
            name: "grid_max_nodes",
            ..
        })
    ));
}
