//! The non-probabilistic baseline (paper §6.1 and App. E.0.1): move the prior vertices nearest
//! to the contacts onto them, then smooth with a Laplacian filter.
//!
//! Each contact pulls its nearest prior vertex; a vertex pulled by several contacts moves to
//! their mean. The smoothing is the explicit normalised cotangent filter
//! `v_i ← v_i + λ (Σ_j w_ij v_j / Σ_j w_ij − v_i)` applied to every vertex for a number of
//! iterations (as mesh-processing libraries' Laplacian filters do), with the cotangent weights
//! of the prior mesh (clamped at 0, docs/design.md's convention; uniform weights for a vertex whose
//! weights all vanish).

use moe_geom::{CotanLaplacian, Point3, PointIndex, Real, Topology, TriMesh, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;

/// Options of [`nonprobabilistic`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NonProbConfig {
    /// Smoothing iterations (default 10).
    pub iterations: usize,
    /// Step `λ ∈ (0, 1]` of each iteration (default 0.5).
    pub lambda: Real,
}

impl Default for NonProbConfig {
    fn default() -> Self {
        Self {
            iterations: 10,
            lambda: 0.5,
        }
    }
}

/// The baseline reconstruction: the prior deformed towards the contacts and smoothed.
///
/// # Errors
/// No contacts, non-finite contacts, or `λ` outside `(0, 1]`.
pub fn nonprobabilistic(
    prior: &TriMesh,
    contacts: &[Point3],
    config: &NonProbConfig,
) -> Result<TriMesh, GpisError> {
    if contacts.is_empty() {
        return Err(GpisError::TooFewObservations {
            method: "nonprob",
            what: "contacts",
            needed: 1,
            got: 0,
        });
    }
    crate::observations::check_finite(contacts, "contact")?;
    crate::error::check_iterations("nonprob_iterations", config.iterations)?;
    if !(config.lambda > 0.0 && config.lambda <= 1.0) {
        return Err(GpisError::InvalidParameter {
            name: "lambda",
            value: config.lambda,
            reason: "must be in (0, 1]",
        });
    }
    let index = PointIndex::new(prior.vertices(), "prior vertices")?;
    let n = prior.num_vertices();
    let mut sum = vec![Vector3::zeros(); n];
    let mut count = vec![0usize; n];
    for c in contacts {
        let nb = index.nearest(c);
        sum[nb.index] += c.coords;
        count[nb.index] += 1;
    }
    let mut v: Vec<Point3> = prior
        .vertices()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if count[i] > 0 {
                Point3::from(sum[i] / count[i] as Real)
            } else {
                *p
            }
        })
        .collect();
    let topo = Topology::new(prior);
    let lap = CotanLaplacian::new(prior, &topo);
    for _ in 0..config.iterations {
        let mut acc = vec![Vector3::zeros(); n];
        let mut wsum = vec![0.0; n];
        for (&[a, b], &w) in topo.edges().iter().zip(lap.weights()) {
            let (a, b) = (a as usize, b as usize);
            acc[a] += v[b].coords * w;
            acc[b] += v[a].coords * w;
            wsum[a] += w;
            wsum[b] += w;
        }
        v = (0..n)
            .map(|i| {
                let target = if wsum[i] > 0.0 {
                    acc[i] / wsum[i]
                } else {
                    let nb = topo.neighbors(i);
                    nb.iter().map(|&j| v[j as usize].coords).sum::<Vector3>()
                        / nb.len().max(1) as Real
                };
                Point3::from(v[i].coords + (target - v[i].coords) * config.lambda)
            })
            .collect();
    }
    Ok(prior.with_vertices(v)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::shapes::icosphere;

    #[test]
    fn contacts_pull_the_prior_and_smoothing_keeps_it_closed() {
        let prior = icosphere(3, 0.1);
        // Contacts on a 5 mm larger sphere around the top.
        let contacts: Vec<Point3> = prior
            .vertices()
            .iter()
            .filter(|p| p.z > 0.05)
            .map(|p| Point3::from(p.coords * 1.05))
            .collect();
        // Without smoothing, each contact's nearest vertex sits on it.
        let raw = nonprobabilistic(
            &prior,
            &contacts,
            &NonProbConfig {
                iterations: 0,
                lambda: 0.5,
            },
        )
        .unwrap();
        let index = PointIndex::new(raw.vertices(), "raw").unwrap();
        for c in &contacts {
            assert!(index.nearest(c).distance < 1e-12);
        }
        // Smoothed: closed, and the top sits outside where smoothing alone would put it.
        let out = nonprobabilistic(&prior, &contacts, &NonProbConfig::default()).unwrap();
        out.require_closed().unwrap();
        let own: Vec<Point3> = prior
            .vertices()
            .iter()
            .filter(|p| p.z > 0.05)
            .copied()
            .collect();
        let smooth_only = nonprobabilistic(&prior, &own, &NonProbConfig::default()).unwrap();
        let top = |m: &TriMesh| {
            let r: Vec<Real> = m
                .vertices()
                .iter()
                .filter(|p| p.z > 0.08)
                .map(|p| p.coords.norm())
                .collect();
            r.iter().sum::<Real>() / r.len() as Real
        };
        assert!(
            top(&out) > top(&smooth_only) + 2e-3,
            "{} vs {}",
            top(&out),
            top(&smooth_only)
        );
        moe_geom::assert_err!(
            nonprobabilistic(&prior, &[], &NonProbConfig::default()),
            GpisError::TooFewObservations {
                method: "nonprob",
                what: "contacts",
                needed: 1,
                got: 0
            }
        );
    }
}
