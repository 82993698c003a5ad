//! Registration of the prior mesh to the contacts by iterative closest points (ICP), for when the
//! body's pose is only roughly known.
//!
//! Each iteration projects the (currently transformed) contacts onto the fixed prior surface and
//! moves them towards their closest points by a rigid or similarity transform:
//!
//! - **point-to-plane** (the default): one Gauss–Newton step on `Σ (nᵢ·(pᵢ − qᵢ))²`, the squared
//!   distances to the tangent planes at the closest points `qᵢ` (normals `nᵢ`), with the small
//!   transform `x ↦ (1+σ)(I + [ω]×)(x − c) + c + τ` about the pairs' centroid `c` linearised
//!   (a 6×6 or, with scale, 7×7 system with Levenberg–Marquardt damping: a step that does not
//!   reduce the distances of the pairs it was computed from is retried with 10× the damping,
//!   so a rotational symmetry of the prior or an overshoot cannot make the fit worse), applied
//!   as an exact rotation `exp([ω]×)`. Sliding along the surface costs nothing, so it converges
//!   in a few iterations where point-to-point needs hundreds;
//! - **point-to-point**: the best transform between the pairs in closed form (Umeyama: SVD of
//!   the cross-covariance, reflection removed); linear convergence, but the widest basin.
//!
//! **Pose prior.** Contacts from a few patches of a nearly spherical cap (a patted scalp) do not
//! pin the pose: the cap slides along itself, and unregularised ICP happily rotates a head prior
//! by tens of degrees to shave a millimetre off the fit (measured on the head benchmark: a 36°
//! roll, GP + prior UCD 2.0 → 17.9 mm). "The pose is roughly known" is therefore part of the
//! model: with a [`PosePrior`](crate::register::PosePrior) (the default), the point-to-plane step minimises
//! `mean(dᵢ²)/σ_fit² + ‖θ‖²/σ_θ² + ‖g‖²/σ_t² + (s − 1)²/σ_s²`, where `θ` is the rotation vector
//! of the accumulated transform, `g` the displacement of the contacts' centroid and `s` the
//! scale — a maximum a posteriori registration in which the contacts count as *one*
//! observation of the fit: their distances to a different person's prior are dominated by the
//! shape mismatch, which is the same for neighbouring contacts, so they are far from
//! independent (counted independently, 300 contacts outweigh any pose prior). Point-to-point
//! steps ignore it.
//!
//! The prior's BVH is built once; the accumulated contacts→prior transform is inverted at the
//! end and applied to the prior mesh. Pairs farther than [`IcpConfig::reject_factor`] × the
//! median pair distance are ignored in an iteration (robust to outlier contacts).

use moe_geom::nalgebra::{Rotation3, SMatrix, SVector};
use moe_geom::{Matrix3, Point3, Real, TriMesh, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::mean::MeshSdfMean;

/// Which transforms registration may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegistrationKind {
    /// Rotation and translation.
    #[default]
    Rigid,
    /// Rotation, translation and a uniform scale.
    Similarity,
}

/// The distance ICP minimises in each iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IcpMetric {
    /// Distance to the tangent plane at the closest point (Gauss–Newton step).
    #[default]
    PointToPlane,
    /// Distance to the closest point (closed-form step).
    PointToPoint,
}

/// A Gaussian prior on the registration transform (module docs): how far the body may be from
/// the prior's pose, against how closely the contacts should fit the prior's shape.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PosePrior {
    /// Standard deviation of the rotation angle, radians (default 0.1 ≈ 6°).
    pub rotation_sd_rad: Real,
    /// Standard deviation of the contacts' centroid displacement, metres (default 0.02).
    pub translation_sd_m: Real,
    /// Standard deviation of the scale (default 0.05).
    pub scale_sd: Real,
    /// Standard deviation of a contact's distance to the prior surface once registered: the
    /// shape mismatch between the prior and the body plus contact noise, metres (default 0.004).
    pub fit_sd_m: Real,
}

impl Default for PosePrior {
    fn default() -> Self {
        Self {
            rotation_sd_rad: 0.1,
            translation_sd_m: 0.02,
            scale_sd: 0.05,
            fit_sd_m: 0.004,
        }
    }
}

impl PosePrior {
    fn validate(&self) -> Result<(), GpisError> {
        for (name, v) in [
            ("rotation_sd_rad", self.rotation_sd_rad),
            ("translation_sd_m", self.translation_sd_m),
            ("scale_sd", self.scale_sd),
            ("fit_sd_m", self.fit_sd_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GpisError::InvalidParameter {
                    name,
                    value: v,
                    reason: "pose prior standard deviations must be finite and positive",
                });
            }
        }
        Ok(())
    }

    /// `‖θ‖²/σ_θ² + ‖g‖²/σ_t² + (s − 1)²/σ_s²` of the contacts→prior transform `acc`, with `g`
    /// the displacement of the contacts' centroid `c0`, in units of `σ_fit²` (so that it adds
    /// to a sum of squared distances).
    fn energy(&self, acc: &Similarity, c0: &Point3, kind: RegistrationKind) -> Real {
        let theta = Rotation3::from_matrix(&acc.rotation).scaled_axis();
        let g = acc.apply(c0) - c0;
        let w = self.fit_sd_m * self.fit_sd_m;
        let mut e = w
            * (theta.norm_squared() / self.rotation_sd_rad.powi(2)
                + g.norm_squared() / self.translation_sd_m.powi(2));
        if kind == RegistrationKind::Similarity {
            e += w * ((acc.scale - 1.0) / self.scale_sd).powi(2);
        }
        e
    }
}

/// ICP options.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IcpConfig {
    /// Transform family.
    pub kind: RegistrationKind,
    /// Point-to-plane (default) or point-to-point.
    #[serde(default)]
    pub metric: IcpMetric,
    /// Prior on the transform (default [`PosePrior::default`]); `None` for plain ICP.
    #[serde(default)]
    pub pose_prior: Option<PosePrior>,
    /// Iteration limit (default 100).
    pub max_iterations: usize,
    /// Stop when the RMS pair distance changes by less than this, metres (default 1e-7).
    pub tolerance_m: Real,
    /// Reject pairs farther than this multiple of the median distance (default 3).
    pub reject_factor: Real,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            kind: RegistrationKind::Rigid,
            metric: IcpMetric::PointToPlane,
            pose_prior: Some(PosePrior::default()),
            max_iterations: 100,
            tolerance_m: 1e-7,
            reject_factor: 3.0,
        }
    }
}

/// A similarity transform `x ↦ s·R·x + t`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Similarity {
    /// Rotation `R`.
    pub rotation: Matrix3,
    /// Translation `t`, metres.
    pub translation: Vector3,
    /// Scale `s` (1 for rigid).
    pub scale: Real,
}

impl Similarity {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }

    /// Applies the transform to a point.
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.rotation * p.coords * self.scale + self.translation)
    }

    /// `self ∘ other`.
    pub fn compose(&self, other: &Self) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation * self.scale + self.translation,
            scale: self.scale * other.scale,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation) / self.scale,
            scale: 1.0 / self.scale,
        }
    }
}

/// The outcome of [`register_prior`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IcpReport {
    /// Transform applied to the prior (prior frame → contact frame).
    pub prior_to_contacts: Similarity,
    /// RMS contact-to-prior distance before registration, metres.
    pub rms_before_m: Real,
    /// RMS contact-to-prior distance after registration, metres.
    pub rms_after_m: Real,
    /// Iterations taken.
    pub iterations: usize,
}

/// The best transform mapping `a[i]` onto `b[i]` (Umeyama), with or without scale.
pub fn best_transform(a: &[Point3], b: &[Point3], kind: RegistrationKind) -> Similarity {
    let n = a.len().max(1) as Real;
    let ma = a.iter().map(|p| p.coords).sum::<Vector3>() / n;
    let mb = b.iter().map(|p| p.coords).sum::<Vector3>() / n;
    let mut cov = Matrix3::zeros();
    let mut var_a = 0.0;
    for (p, q) in a.iter().zip(b) {
        let (da, db) = (p.coords - ma, q.coords - mb);
        cov += db * da.transpose();
        var_a += da.norm_squared();
    }
    let svd = cov.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Similarity::identity();
    };
    let mut s = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        s[(2, 2)] = -1.0;
    }
    let rotation = u * s * vt;
    let scale = match kind {
        RegistrationKind::Rigid => 1.0,
        RegistrationKind::Similarity if var_a > 0.0 => {
            (svd.singular_values.component_mul(&s.diagonal())).sum() / var_a
        }
        RegistrationKind::Similarity => 1.0,
    };
    Similarity {
        rotation,
        translation: mb - rotation * ma * scale,
        scale,
    }
}

/// The pose prior's share of a point-to-plane step: the prior, the transform accumulated so far
/// and the contacts' centroid.
struct PriorTerm<'a> {
    prior: &'a PosePrior,
    acc: &'a Similarity,
    c0: Point3,
}

/// `skew(v) w = v × w`.
fn skew(v: &Vector3) -> Matrix3 {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// One damped Gauss–Newton step of point-to-plane ICP (module docs): the transform moving the
/// points `p` towards the tangent planes `(q, n)`, pulled towards the identity pose by `prior`.
fn point_to_plane_step(
    p: &[Point3],
    q: &[Point3],
    n: &[Vector3],
    kind: RegistrationKind,
    lambda: Real,
    prior: Option<&PriorTerm<'_>>,
) -> Similarity {
    let count = p.len().max(1) as Real;
    let c = Point3::from(p.iter().map(|x| x.coords).sum::<Vector3>() / count);
    let mut a = SMatrix::<Real, 7, 7>::zeros();
    let mut b = SVector::<Real, 7>::zeros();
    for ((pi, qi), ni) in p.iter().zip(q).zip(n) {
        let d = pi - c;
        let dn = d.cross(ni);
        let row = SVector::<Real, 7>::from_column_slice(&[
            dn.x,
            dn.y,
            dn.z,
            ni.x,
            ni.y,
            ni.z,
            ni.dot(&d),
        ]);
        let r = ni.dot(&(pi - qi));
        a += row * row.transpose();
        b -= row * r;
    }
    if let Some(term) = prior {
        // Residuals in units of σ_fit, linearised in the step (ω, τ, σ) about `c`.
        let pp = term.prior;
        // The data term above is a sum over the pairs; the prior weighs against their mean.
        let k = count.sqrt();
        let (wr, wt, ws) = (
            k * pp.fit_sd_m / pp.rotation_sd_rad,
            k * pp.fit_sd_m / pp.translation_sd_m,
            k * pp.fit_sd_m / pp.scale_sd,
        );
        // Rotation: θ_acc + ω.
        let theta = Rotation3::from_matrix(&term.acc.rotation).scaled_axis();
        for i in 0..3 {
            a[(i, i)] += wr * wr;
            b[i] -= wr * wr * theta[i];
        }
        // Centroid displacement: g + ω × v + τ + σ v, with v = acc(c0) − c.
        let m = term.acc.apply(&term.c0);
        let g = m - term.c0;
        let v = m - c;
        let mut jg = SMatrix::<Real, 3, 7>::zeros();
        jg.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-skew(&v)));
        jg.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        jg.fixed_view_mut::<3, 1>(0, 6).copy_from(&v);
        a += jg.transpose() * jg * (wt * wt);
        b -= jg.transpose() * g * (wt * wt);
        // Scale: s_acc − 1 + σ.
        if kind == RegistrationKind::Similarity {
            a[(6, 6)] += ws * ws;
            b[6] -= ws * ws * (term.acc.scale - 1.0);
        }
    }
    let unknowns = match kind {
        RegistrationKind::Rigid => 6,
        RegistrationKind::Similarity => 7,
    };
    // Levenberg damping relative to the system's own scale: a direction the data cannot see
    // (a symmetry of the prior) gets a zero step instead of an arbitrary one.
    let damping = 1e-9 * (0..unknowns).map(|i| a[(i, i)]).sum::<Real>() / unknowns as Real;
    for i in 0..7 {
        if i < unknowns {
            a[(i, i)] += lambda * a[(i, i)] + damping + Real::MIN_POSITIVE;
        } else {
            a.row_mut(i).fill(0.0);
            a.column_mut(i).fill(0.0);
            a[(i, i)] = 1.0;
            b[i] = 0.0;
        }
    }
    let Some(x) = a.cholesky().map(|ch| ch.solve(&b)) else {
        return Similarity::identity();
    };
    if x.iter().any(|v| !v.is_finite()) {
        return Similarity::identity();
    }
    let rotation = Rotation3::new(Vector3::new(x[0], x[1], x[2])).into_inner();
    let scale = 1.0 + x[6];
    Similarity {
        rotation,
        translation: c.coords + Vector3::new(x[3], x[4], x[5]) - rotation * c.coords * scale,
        scale,
    }
}

/// Registers `prior` to `contacts` and returns the transformed prior.
///
/// # Errors
/// Fewer than 3 contacts, non-finite contacts, or a prior that is not watertight.
pub fn register_prior(
    prior: &TriMesh,
    contacts: &[Point3],
    config: &IcpConfig,
) -> Result<(TriMesh, IcpReport), GpisError> {
    if contacts.len() < 3 {
        return Err(GpisError::TooFewObservations {
            method: "registration",
            what: "contacts",
            needed: 3,
            got: contacts.len(),
        });
    }
    crate::observations::check_finite(contacts, "contact")?;
    crate::error::check_iterations("icp_max_iterations", config.max_iterations)?;
    if let Some(pp) = &config.pose_prior {
        pp.validate()?;
    }
    let sdf = MeshSdfMean::new(prior)?;
    let rms = |pts: &[Point3], closest: &[Point3]| {
        (pts.iter()
            .zip(closest)
            .map(|(p, q)| (p - q).norm_squared())
            .sum::<Real>()
            / pts.len() as Real)
            .sqrt()
    };
    // `acc` maps contacts into the prior's frame.
    let mut acc = Similarity::identity();
    let project = |pts: &[Point3]| -> (Vec<Point3>, Vec<Vector3>) {
        pts.iter().map(|p| sdf.closest_point_and_normal(p)).unzip()
    };
    let mut moved: Vec<Point3> = contacts.to_vec();
    let (mut closest, mut normals) = project(&moved);
    let rms_before = rms(&moved, &closest);
    let mut last = rms_before;
    let mut iterations = 0;
    let mut lambda = 1e-6;
    let c0 =
        Point3::from(contacts.iter().map(|p| p.coords).sum::<Vector3>() / contacts.len() as Real);
    let prior_energy = |t: &Similarity| match (config.metric, &config.pose_prior) {
        (IcpMetric::PointToPlane, Some(pp)) => pp.energy(t, &c0, config.kind),
        _ => 0.0,
    };
    for it in 0..config.max_iterations {
        iterations = it + 1;
        let d: Vec<Real> = moved
            .iter()
            .zip(&closest)
            .map(|(p, q)| (p - q).norm())
            .collect();
        let mut sorted = d.clone();
        sorted.sort_by(Real::total_cmp);
        let limit = config.reject_factor * sorted[sorted.len() / 2].max(1e-9);
        let keep: Vec<usize> = (0..moved.len()).filter(|&i| d[i] <= limit).collect();
        if keep.len() < 3 {
            break;
        }
        let a: Vec<Point3> = keep.iter().map(|&i| moved[i]).collect();
        let b: Vec<Point3> = keep.iter().map(|&i| closest[i]).collect();
        let n: Vec<Vector3> = keep.iter().map(|&i| normals[i]).collect();
        let kept_ms = |dist: &dyn Fn(usize) -> Real| {
            keep.iter().map(|&i| dist(i).powi(2)).sum::<Real>() / keep.len() as Real
        };
        let before = kept_ms(&|i| d[i]) + prior_energy(&acc);
        // Damped steps until one reduces the kept pairs' distances (module docs).
        let mut accepted = None;
        for _ in 0..8 {
            let step = match config.metric {
                IcpMetric::PointToPoint => best_transform(&a, &b, config.kind),
                IcpMetric::PointToPlane => {
                    let term = config.pose_prior.as_ref().map(|prior| PriorTerm {
                        prior,
                        acc: &acc,
                        c0,
                    });
                    point_to_plane_step(&a, &b, &n, config.kind, lambda, term.as_ref())
                }
            };
            let trial = step.compose(&acc);
            let trial_moved: Vec<Point3> = contacts.iter().map(|p| trial.apply(p)).collect();
            // The trial's closest points serve the next iteration when it is accepted.
            let (trial_closest, trial_normals) = project(&trial_moved);
            let after =
                kept_ms(&|i| (trial_moved[i] - trial_closest[i]).norm()) + prior_energy(&trial);
            if after < before {
                lambda = (lambda * 0.1).max(1e-9);
                accepted = Some((trial, trial_moved, trial_closest, trial_normals));
                break;
            }
            if config.metric == IcpMetric::PointToPoint {
                break;
            }
            lambda *= 10.0;
        }
        let Some((trial, trial_moved, trial_closest, trial_normals)) = accepted else {
            break;
        };
        acc = trial;
        moved = trial_moved;
        closest = trial_closest;
        normals = trial_normals;
        let now = rms(&moved, &closest);
        if (last - now).abs() < config.tolerance_m {
            last = now;
            break;
        }
        last = now;
    }
    let prior_to_contacts = acc.inverse();
    let vertices = prior
        .vertices()
        .iter()
        .map(|p| prior_to_contacts.apply(p))
        .collect();
    let registered = prior.with_vertices(vertices)?;
    Ok((
        registered,
        IcpReport {
            prior_to_contacts,
            rms_before_m: rms_before,
            rms_after_m: last * prior_to_contacts.scale,
            iterations,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::shapes::star_shaped;

    /// An egg-like shape: no rotational symmetry about most axes.
    fn egg() -> TriMesh {
        star_shaped(3, Point3::origin(), |d| {
            0.08 + 0.02 * d.x + 0.015 * d.y * d.y - 0.01 * d.z * d.x
        })
        .unwrap()
    }

    /// The similarity with the given Euler angles, translation and scale.
    fn pose(angles: [Real; 3], translation: Vector3, scale: Real) -> Similarity {
        Similarity {
            rotation: nalgebra_rotation(angles[0], angles[1], angles[2])
                .to_rotation_matrix()
                .into_inner(),
            translation,
            scale,
        }
    }

    #[test]
    fn icp_recovers_a_known_pose_and_scale() {
        let prior = egg();
        let truth = pose([0.08, -0.05, 0.1], Vector3::new(0.006, -0.004, 0.003), 1.04);
        let contacts: Vec<Point3> = prior
            .vertices()
            .iter()
            .step_by(3)
            .filter(|p| p.z > -0.02)
            .map(|p| truth.apply(p))
            .collect();
        for kind in [RegistrationKind::Similarity, RegistrationKind::Rigid] {
            let cfg = IcpConfig {
                kind,
                max_iterations: 300,
                metric: IcpMetric::PointToPoint,
                pose_prior: None,
                ..IcpConfig::default()
            };
            let (_, report) = register_prior(&prior, &contacts, &cfg).unwrap();
            if kind == RegistrationKind::Similarity {
                // Point-to-point ICP converges linearly: 300 iterations bring 6.6 mm to ~0.25 mm.
                assert!(
                    report.rms_after_m < 0.05 * report.rms_before_m,
                    "{report:?}"
                );
                assert!(
                    (report.prior_to_contacts.scale - 1.04).abs() < 6e-3,
                    "{report:?}"
                );
            }
            assert!(report.rms_after_m < 0.5 * report.rms_before_m, "{report:?}");
        }
        // Point-to-plane recovers the transform itself, in tens of iterations.
        let cfg = IcpConfig {
            kind: RegistrationKind::Similarity,
            pose_prior: None,
            ..IcpConfig::default()
        };
        let (registered, report) = register_prior(&prior, &contacts, &cfg).unwrap();
        assert!(report.iterations <= 40, "{report:?}");
        assert!(report.rms_after_m < 1e-6, "{report:?}");
        let found = report.prior_to_contacts;
        assert!((found.scale - truth.scale).abs() < 1e-5, "{found:?}");
        assert!((found.rotation - truth.rotation).norm() < 1e-5, "{found:?}");
        assert!(
            (found.translation - truth.translation).norm() < 1e-6,
            "{found:?}"
        );
        let moved_prior = prior.vertices().iter().map(|p| truth.apply(p));
        let worst = registered
            .vertices()
            .iter()
            .zip(moved_prior)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(worst < 1e-5, "{worst} m");
    }

    #[test]
    fn point_to_plane_rigid_registration_ignores_an_outlier() {
        let prior = egg();
        let truth = pose([-0.06, 0.04, 0.05], Vector3::new(-0.004, 0.005, 0.002), 1.0);
        let mut contacts: Vec<Point3> = prior
            .vertices()
            .iter()
            .step_by(4)
            .filter(|p| p.z > 0.0)
            .map(|p| truth.apply(p))
            .collect();
        contacts.push(Point3::new(0.0, 0.0, 0.3));
        let cfg = IcpConfig {
            pose_prior: None,
            ..IcpConfig::default()
        };
        let (_, report) = register_prior(&prior, &contacts, &cfg).unwrap();
        let found = report.prior_to_contacts;
        assert!((found.rotation - truth.rotation).norm() < 1e-4, "{found:?}");
        assert!(
            (found.translation - truth.translation).norm() < 1e-4,
            "{found:?}"
        );
        assert_eq!(found.scale, 1.0);
    }

    #[test]
    fn the_pose_prior_keeps_a_patted_head_from_rolling() {
        use crate::bench_scene::{BenchSceneConfig, build_scene};
        // Another person's head, patted on top, back and sides: plain ICP trades the pose
        // for the shape mismatch and rolls the prior far from the (correct) initial pose.
        let scene = build_scene(&BenchSceneConfig {
            truth_seed: 11,
            prior_seed: 12,
            contact_seed: 13,
            contacts_per_patch: 20,
            mesh_level: 3,
            ..BenchSceneConfig::head()
        })
        .unwrap();
        let angle = |pose_prior| {
            let cfg = IcpConfig {
                pose_prior,
                ..IcpConfig::default()
            };
            let (_, report) = register_prior(&scene.prior, &scene.contacts, &cfg).unwrap();
            Rotation3::from_matrix(&report.prior_to_contacts.rotation)
                .angle()
                .to_degrees()
        };
        let plain = angle(None);
        let map = angle(Some(PosePrior::default()));
        assert!(plain > 15.0, "plain ICP rolled only {plain}°");
        assert!(map < 3.0, "with the pose prior: {map}°");
    }

    #[test]
    fn invalid_pose_priors_are_named() {
        let prior = star_shaped(2, Point3::origin(), |_| 0.05).unwrap();
        let contacts: Vec<Point3> = prior.vertices().to_vec();
        let cfg = IcpConfig {
            pose_prior: Some(PosePrior {
                translation_sd_m: Real::NAN,
                ..PosePrior::default()
            }),
            ..IcpConfig::default()
        };
        let err = register_prior(&prior, &contacts, &cfg).unwrap_err();
        assert!(err.to_string().contains("translation_sd_m"), "{err}");
    }

    fn nalgebra_rotation(rx: Real, ry: Real, rz: Real) -> moe_geom::math::UnitQuat {
        moe_geom::math::UnitQuat::from_euler_angles(rx, ry, rz)
    }
}
