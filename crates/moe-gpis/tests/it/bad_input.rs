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

/// Iteration counts and problem sizes are bounded, each side of the bound.
#[test]
fn iteration_counts_and_sizes_are_bounded() {
    use moe_gpis::parts::{fit_hyper, register_prior};
    use moe_gpis::{IcpConfig, MAX_ITERATIONS};
    let name_of = |r: Result<(), GpisError>| match r {
        Err(GpisError::InvalidParameter { name, .. }) => name,
        other => panic!("{other:?}"),
    };
    let prior = icosphere(2, 0.05);
    let pts = contacts(20);
    let too_many = MAX_ITERATIONS + 1;
    let icp = |max_iterations| IcpConfig {
        max_iterations,
        ..IcpConfig::default()
    };
    assert_eq!(
        name_of(register_prior(&prior, &pts, &icp(too_many)).map(|_| ())),
        "icp_max_iterations"
    );
    assert!(register_prior(&prior, &pts, &icp(MAX_ITERATIONS)).is_ok());
    let nonprob = |iterations| NonProbConfig {
        iterations,
        ..NonProbConfig::default()
    };
    assert_eq!(
        name_of(nonprobabilistic(&prior, &pts, &nonprob(too_many)).map(|_| ())),
        "nonprob_iterations"
    );
    let residuals = vec![0.0; pts.len()];
    let fit = FitConfig {
        max_iterations: too_many,
        ..FitConfig::default()
    };
    assert_eq!(
        name_of(fit_hyper(&pts, &residuals, &fit).map(|_| ())),
        "fit_max_iterations"
    );
    let fit = FitConfig {
        max_fit_points: moe_gpis::MAX_EXACT_OBSERVATIONS + 1,
        ..FitConfig::default()
    };
    assert_eq!(
        name_of(fit_hyper(&pts, &residuals, &fit).map(|_| ())),
        "max_fit_points"
    );
    // At each limit the call goes through.
    assert!(nonprobabilistic(&prior, &pts, &nonprob(MAX_ITERATIONS)).is_ok());
    let at_limit = FitConfig {
        max_iterations: MAX_ITERATIONS,
        max_fit_points: moe_gpis::MAX_EXACT_OBSERVATIONS,
        ..FitConfig::default()
    };
    assert!(fit_hyper(&pts, &residuals, &at_limit).is_ok());
    let gpis = GpisConfig {
        exact_limit: moe_gpis::MAX_EXACT_OBSERVATIONS,
        inducing_points: moe_gpis::MAX_EXACT_OBSERVATIONS,
        ..GpisConfig::default()
    };
    let sphere = SphereMean {
        center: Point3::origin(),
        radius: 0.05,
    };
    let obs = Observations::from_contacts(&pts).unwrap();
    assert!(condition(sphere, &obs, &gpis).is_ok());
}
