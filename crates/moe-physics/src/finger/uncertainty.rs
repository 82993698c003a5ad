//! How sure the estimate is: the loads found described with the spread of their force and place
//! (the posterior over the candidates), and the Cramér–Rao bound of a press's place.

use moe_geom::{Point3, Real, Vector3};
use nalgebra::{DMatrix, DVector};

use super::compliance::{Linear, dot};
use super::gauss_newton::Solved;
use super::search::Fit;
use super::{FingerInverse, FingerLoad, FingerObservation, to_physics};
use crate::error::PhysicsError;
use crate::mechanics::Axis;
use crate::observability::BoundOptions;

/// The loads of a press, described for the estimate.
pub(super) struct PressedLoads {
    pub(super) loads: Vec<FingerLoad>,
    /// Per surface vertex: the probability that it is in contact.
    pub(super) probability: Vec<Real>,
    /// Per surface vertex: the force the loads put on it.
    pub(super) vertex_force: Vec<Vector3>,
    /// Per load: the normalised posterior over the candidates (empty when undefined).
    pub(super) posteriors: Vec<Vec<Real>>,
}

impl FingerInverse {
    /// The found loads as outputs, with the contact region, vertex forces and place posteriors.
    pub(super) fn describe_loads(
        &self,
        lin: &Linear,
        state: &Solved,
        pressed_probability: Real,
    ) -> PressedLoads {
        let nv = self.rest_surface.len();
        let mut probability = vec![0.0; nv];
        let mut vertex_force = vec![Vector3::zeros(); nv];
        let fit = Fit {
            candidates: state.loads.iter().map(|l| l.0).collect(),
            forces: state.loads.iter().map(|l| l.1).collect(),
            residual_sq: state.chi,
        };
        let force_sd = self.force_spread(lin, &fit);
        let mut loads = Vec::with_capacity(state.loads.len());
        let mut posteriors = Vec::with_capacity(state.loads.len());
        for (k, &(c, f)) in state.loads.iter().enumerate() {
            let (location_sd_m, place, posterior) = self.location_spread(lin, &fit, k);
            posteriors.push(posterior);
            for &(u, s) in &self.patches[c] {
                vertex_force[u as usize] += f * s;
            }
            let centre: Point3 = place
                .iter()
                .map(|&(u, w)| self.rest_surface[u as usize].coords * w)
                .sum::<Vector3>()
                .into();
            let normal = -lin.inward[c];
            let r = self.config.contact_radius_m;
            for (u, p) in self.rest_surface.iter().enumerate() {
                // The contact region: the rest surface within the radius, on the patch's side.
                if (p - centre).norm() <= r && self.rest_normals[u].dot(&normal) > 0.0 {
                    probability[u] = pressed_probability;
                }
            }
            loads.push(FingerLoad {
                vertex: self.candidates[c],
                place,
                patch: self.patches[c].clone(),
                force: f,
                force_sd_n: force_sd[k],
                location_sd_m,
            });
        }
        PressedLoads {
            loads,
            probability,
            vertex_force,
            posteriors,
        }
    }

    /// Standard deviation of each load's magnitude at fixed places and directions: `σ` times
    /// the square root of the diagonal of the inverse Gram matrix of their response columns.
    fn force_spread(&self, lin: &Linear, fit: &Fit) -> Vec<Real> {
        let cols: Vec<Vec<Real>> = fit
            .candidates
            .iter()
            .zip(&fit.forces)
            .map(|(&c, f)| lin.response(c, &f.try_normalize(0.0).unwrap_or(lin.inward[c])))
            .collect();
        let n = cols.len();
        let g = DMatrix::from_fn(n, n, |i, j| dot(&cols[i], &cols[j]));
        let sigma = self.config.marker_sigma_m;
        match g.try_inverse() {
            Some(inv) => (0..n)
                .map(|k| sigma * inv[(k, k)].max(0.0).sqrt())
                .collect(),
            None => vec![Real::INFINITY; n],
        }
    }

    /// Posterior standard deviations of load `k`'s place along the finger's axis and around
    /// it: every candidate weighted by its prior (its area, or the remembered place's
    /// [`Self::propagate`]) and the likelihood of its best single load for the residual the
    /// other loads leave; also the place ([`Self::local_place`]) and the normalised posterior.
    fn location_spread(
        &self,
        lin: &Linear,
        fit: &Fit,
        k: usize,
    ) -> ([Real; 2], Vec<(u32, Real)>, Vec<Real>) {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let mut r = lin.r.clone();
        let mut buf = vec![0.0; lin.n_obs];
        for (j, (&c, f)) in fit.candidates.iter().zip(&fit.forces).enumerate() {
            if j != k {
                lin.response_into(c, f, &mut buf);
                r.iter_mut().zip(&buf).for_each(|(r, b)| *r -= b);
            }
        }
        let singles = self.single_fits(lin, &r);
        let best = singles.iter().map(|f| f.1).fold(Real::INFINITY, Real::min);
        let weights: Vec<Real> = singles
            .iter()
            .enumerate()
            .map(|(c, f)| {
                let prior = match &self.place_prior {
                    Some(prior) => prior[c],
                    None => self.area[self.candidates[c] as usize],
                };
                prior * (-(f.1 - best) / (2.0 * sigma2)).exp()
            })
            .collect();
        let centre = fit.candidates[k];
        let place = self.local_place(centre, &weights);
        let wsum: Real = weights.iter().sum();
        if wsum.is_nan() || wsum <= 0.0 {
            return ([Real::NAN; 2], place, Vec::new());
        }
        let posterior: Vec<Real> = weights.iter().map(|w| w / wsum).collect();
        let position = |c: usize| self.rest_surface[self.candidates[c] as usize];
        let mut mean = Vector3::zeros();
        for (c, w) in weights.iter().enumerate() {
            mean += position(c).coords * (w / wsum);
        }
        let mean_angle = mean.y.atan2(mean.x);
        let radius = (mean.x * mean.x + mean.y * mean.y).sqrt().max(1e-4);
        let (mut along, mut around) = (0.0, 0.0);
        for (c, w) in weights.iter().enumerate() {
            let p = position(c);
            along += w / wsum * (p.z - mean.z).powi(2);
            let da = (p.y.atan2(p.x) - mean_angle + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            around += w / wsum * (da * radius).powi(2);
        }
        ([along.sqrt(), around.sqrt()], place, posterior)
    }

    /// The place of a load whose best patch is candidate `centre`, from the posterior
    /// `weights` over every candidate: the centre vertex alone, or with `place_radius_m > 0`
    /// the normalised weights of the candidates within that radius on the centre's side.
    fn local_place(&self, centre: usize, weights: &[Real]) -> Vec<(u32, Real)> {
        let v0 = self.candidates[centre];
        let r = self.config.place_radius_m;
        if r <= 0.0 {
            return vec![(v0, 1.0)];
        }
        let (p0, n0) = (
            self.rest_surface[v0 as usize],
            self.rest_normals[v0 as usize],
        );
        let mut place: Vec<(u32, Real)> = self
            .candidates
            .iter()
            .zip(weights)
            .filter(|&(&v, &w)| {
                w > 0.0
                    && (self.rest_surface[v as usize] - p0).norm() <= r
                    && self.rest_normals[v as usize].dot(&n0) > 0.0
            })
            .map(|(&v, &w)| (v, w))
            .collect();
        let total: Real = place.iter().map(|p| p.1).sum();
        if !(total.is_finite() && total > 0.0) {
            return vec![(v0, 1.0)];
        }
        place.iter_mut().for_each(|p| p.1 /= total);
        place
    }

    /// The Cramér–Rao bound of a press at every candidate place, linearised at the static free
    /// shape under `obs`'s pulls and gravity: the Fisher information of what `options` observes
    /// (every marker's coordinates with independent Gaussian noise; the depth image's view of
    /// the surface, each visible vertex's normal displacement with the depth noise of its
    /// pixels), over `options.frames` independent frames of a held press, about the press's
    /// place on the surface (along the finger's axis and around it) and its force vector, at a
    /// force of `options.force_n` along the inward normal. Per candidate: its vertex, the
    /// bound's standard deviations along and around (metres) and of the force's magnitude
    /// (newtons).
    pub(crate) fn location_bounds(
        &mut self,
        obs: &FingerObservation<'_>,
        options: &BoundOptions,
    ) -> Result<Vec<(u32, [Real; 3])>, PhysicsError> {
        let mut solves = 0;
        let x = self.static_free(obs, &mut solves)?;
        let (axes, weights) = self.bound_axes(&x, obs, options);
        let n_obs = axes.len();
        let fields = self
            .mech
            .reciprocal_fields(&x, &obs.commands(), &obs.gravity, &[], &axes, self.ctx())
            .map_err(|e| to_physics(self.index, "(tangent)", e))?;
        let responses = self.candidate_responses(&fields);
        let inward_normals = self.inward_normals(&x);
        let frames = options.frames.max(1) as Real;
        let whiten: Vec<Real> = weights.iter().map(|w| (w * frames).sqrt()).collect();
        let mut out = Vec::with_capacity(self.candidates.len());
        for (c, patch) in self.patches.iter().enumerate() {
            let inward = inward_normals[c];
            let force = inward * options.force_n;
            // Tangent directions at the patch: around the axis and along it.
            let n = -inward;
            let around = Vector3::z()
                .cross(&n)
                .try_normalize(1e-6)
                .unwrap_or_else(Vector3::y);
            let along = n.cross(&around).normalize();
            // Jacobian columns: place along, place around, force x, y, z.
            let mut j = DMatrix::<Real>::zeros(n_obs, 5);
            for &(u, share) in patch {
                for (i, grad) in self.mech.load_weight_gradients(u) {
                    let dw = [grad.dot(&along) * share, grad.dot(&around) * share];
                    for k in 0..n_obs {
                        let mut s = 0.0;
                        for a in 0..3 {
                            s += fields[(3 * i as usize + a, k)] * force[a];
                        }
                        j[(k, 0)] += dw[0] * s;
                        j[(k, 1)] += dw[1] * s;
                    }
                }
            }
            let base = 3 * c * n_obs;
            for d in 0..3 {
                for k in 0..n_obs {
                    j[(k, 2 + d)] = responses[base + d * n_obs + k];
                }
            }
            // Whitened rows: the information is Jᵀ W J with W the weights over the frames.
            for (k, w) in whiten.iter().enumerate() {
                j.row_mut(k).scale_mut(*w);
            }
            let info = j.transpose() * &j;
            let bound = match info.try_inverse() {
                Some(cov) => {
                    let f = DVector::from_column_slice(inward.as_slice());
                    let cov_f = cov.view((2, 2), (3, 3)).into_owned();
                    [
                        cov[(0, 0)].max(0.0).sqrt(),
                        cov[(1, 1)].max(0.0).sqrt(),
                        (f.transpose() * cov_f * &f)[(0, 0)].max(0.0).sqrt(),
                    ]
                }
                None => [Real::INFINITY; 3],
            };
            out.push((self.candidates[c], bound));
        }
        Ok(out)
    }

    /// The surface vertices the camera of `depth` sees on the static free shape under `obs`'s
    /// pulls and gravity: per vertex, its depth (metres) and the pixels that fall on its share
    /// of the surface.
    pub(crate) fn depth_view(
        &mut self,
        obs: &FingerObservation<'_>,
        depth: &crate::observability::DepthBoundModel,
    ) -> Result<Vec<(Real, Real)>, PhysicsError> {
        let mut solves = 0;
        let x = self.static_free(obs, &mut solves)?;
        Ok(self
            .seen_by(&x, obs, depth)
            .1
            .into_iter()
            .map(|(_, depth_m, pixels)| (depth_m, pixels))
            .collect())
    }

    /// The unit normals of the surface at nodes `x`, and the vertices the camera of `depth`
    /// sees there: `(vertex, depth, pixels on its share of the surface)`.
    fn seen_by(
        &self,
        x: &[Point3],
        obs: &FingerObservation<'_>,
        depth: &crate::observability::DepthBoundModel,
    ) -> (Vec<Vector3>, Vec<(u32, Real, Real)>) {
        let surface = self.surface_of(x);
        let normals = self.normals_of(&surface);
        let camera_from_finger = depth.hand_from_camera.inverse() * obs.world_from_finger;
        let seen = depth
            .visible_vertices(&camera_from_finger, &surface, &normals, &self.faces)
            .into_iter()
            .map(|v| {
                let pixels = self.area[v.vertex as usize] * v.pixels_per_m2;
                (v.vertex, v.depth_m, pixels)
            })
            .collect();
        (normals, seen)
    }

    /// What the bound observes at nodes `x`, as observation axes (a surface vertex and the
    /// direction its displacement is seen along) with their information per frame (one over
    /// the variance): each marker's three coordinates, and with a depth model every surface
    /// vertex the camera sees, along its normal.
    fn bound_axes(
        &self,
        x: &[Point3],
        obs: &FingerObservation<'_>,
        options: &BoundOptions,
    ) -> (Vec<Axis>, Vec<Real>) {
        let mut axes = Vec::new();
        let mut weights = Vec::new();
        if options.markers {
            let w = 1.0 / (options.marker_sigma_m * options.marker_sigma_m);
            for &v in &self.markers {
                for d in 0..3 {
                    axes.push(vec![(v, Vector3::ith(d, 1.0))]);
                    weights.push(w);
                }
            }
        }
        if let Some(depth) = &options.depth {
            let (normals, seen) = self.seen_by(x, obs, depth);
            for (vertex, depth_m, pixels) in seen {
                let variance = depth.noise.pixel_variance(depth_m) / pixels.max(1e-12)
                    + depth.noise.correlated_sigma_m * depth.noise.correlated_sigma_m;
                axes.push(vec![(vertex, normals[vertex as usize])]);
                weights.push(1.0 / variance);
            }
        }
        (axes, weights)
    }
}
