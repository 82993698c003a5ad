//! Compliance by reciprocity: the linear model of the observations (marker coordinates, depth
//! patches) about one configuration, from one factorisation of the static tangent and a solve
//! per observed quantity.

use faer::Mat;
use moe_geom::{Point3, Real, Vector3};

use super::{FingerInverse, FingerObservation, to_physics};
use crate::error::PhysicsError;
use crate::mechanics::PatchLoad;

/// The linear model of the markers about one configuration.
pub(super) struct Linear {
    /// Observed coordinates.
    pub(super) n_obs: usize,
    /// Residual to explain: the free residual linearised at the configuration.
    pub(super) r: Vec<Real>,
    /// `responses[(c·3 + d)·n_obs + j]`: response of observed coordinate `j` to a unit force
    /// along axis `d` over candidate `c`'s patch.
    pub(super) responses: Vec<Real>,
    /// Per candidate: inward unit normal over its patch.
    pub(super) inward: Vec<Vector3>,
}

impl Linear {
    /// The response of the observed coordinates to force `f` at candidate `c`, into `out`.
    pub(super) fn response_into(&self, c: usize, f: &Vector3, out: &mut [Real]) {
        let n = self.n_obs;
        let base = 3 * c * n;
        for (j, o) in out.iter_mut().enumerate().take(n) {
            *o = self.responses[base + j] * f.x
                + self.responses[base + n + j] * f.y
                + self.responses[base + 2 * n + j] * f.z;
        }
    }

    pub(super) fn response(&self, c: usize, f: &Vector3) -> Vec<Real> {
        let mut out = vec![0.0; self.n_obs];
        self.response_into(c, f, &mut out);
        out
    }
}

pub(super) fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl FingerInverse {
    /// Vertex normals of the surface `s` (area-weighted).
    pub(super) fn normals_of(&self, s: &[Point3]) -> Vec<Vector3> {
        let mut n = vec![Vector3::zeros(); s.len()];
        for f in &self.faces {
            let [a, b, c] = f.map(|i| s[i as usize]);
            let fn_ = (b - a).cross(&(c - a));
            for &i in f {
                n[i as usize] += fn_;
            }
        }
        n.iter_mut().for_each(|v| {
            if let Some(u) = v.try_normalize(0.0) {
                *v = u;
            }
        });
        n
    }

    /// The linear model about nodes `x` where `loads` act.
    pub(super) fn linearise(
        &mut self,
        x: &[Point3],
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        solves: &mut usize,
    ) -> Result<Linear, PhysicsError> {
        let mut axes = Vec::new();
        let mut r = Vec::new();
        for (slot, m) in obs.markers.iter().enumerate() {
            if let Some(p) = m {
                let v = self.markers[slot];
                let model = self.mech.surface_position(x, v);
                for d in 0..3 {
                    axes.push(vec![(v, Vector3::ith(d, 1.0))]);
                    r.push(p[d] - model[d]);
                }
            }
        }
        // Each depth row weighted for its loss at `x` (iteratively reweighted least squares).
        for row in obs.depth {
            let (residual, w) = self.depth_linearised(x, row);
            axes.push(row.terms.iter().map(|&(v, a)| (v, a * w)).collect());
            r.push(residual * w);
        }
        let patch_loads: Vec<PatchLoad> = loads
            .iter()
            .map(|&(c, force)| PatchLoad {
                patch: self.patches[c].clone(),
                force,
            })
            .collect();
        let ctx = self.ctx();
        let fields = self
            .mech
            .reciprocal_fields(x, &obs.commands(), &obs.gravity, &patch_loads, &axes, ctx)
            .map_err(|e| to_physics(self.index, "(tangent)", e))?;
        *solves += 1;
        let n_obs = axes.len();
        let responses = self.candidate_responses(&fields);
        let inward = self.inward_normals(x);
        let mut lin = Linear {
            n_obs,
            r,
            responses,
            inward,
        };
        let mut buf = vec![0.0; n_obs];
        for &(c, f) in loads {
            lin.response_into(c, &f, &mut buf);
            for (r, b) in lin.r.iter_mut().zip(&buf) {
                *r += b;
            }
        }
        Ok(lin)
    }

    /// `responses[(c·3 + d)·n + j]`: the response of observation `j` (column `j` of `fields`,
    /// its reciprocal field, `n` columns) to a unit force along axis `d` over candidate `c`'s
    /// patch.
    pub(super) fn candidate_responses(&self, fields: &Mat<Real>) -> Vec<Real> {
        let n_obs = fields.ncols();
        // Row-major copy: row `3i + d` holds the `n_obs` responses at free node `i`, axis `d`.
        let rows = fields.nrows();
        let mut rm = vec![0.0; rows * n_obs];
        for j in 0..n_obs {
            for row in 0..rows {
                rm[row * n_obs + j] = fields[(row, j)];
            }
        }
        let nc = self.candidates.len();
        let mut responses = vec![0.0; 3 * nc * n_obs];
        for (c, nodes) in self.patch_nodes.iter().enumerate() {
            let out = &mut responses[3 * c * n_obs..3 * (c + 1) * n_obs];
            for &(i, w) in nodes {
                for d in 0..3 {
                    let src = &rm[(3 * i as usize + d) * n_obs..(3 * i as usize + d + 1) * n_obs];
                    let dst = &mut out[d * n_obs..(d + 1) * n_obs];
                    for (o, s) in dst.iter_mut().zip(src) {
                        *o += w * s;
                    }
                }
            }
        }
        responses
    }

    /// Per candidate: the inward unit normal over its patch on the surface at `x`.
    pub(super) fn inward_normals(&self, x: &[Point3]) -> Vec<Vector3> {
        let normals = self.normals_of(&self.surface_of(x));
        self.patches
            .iter()
            .map(|patch| {
                let n: Vector3 = patch.iter().map(|&(u, s)| normals[u as usize] * s).sum();
                -n.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
            })
            .collect()
    }
}
