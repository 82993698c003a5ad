//! The load search: the non-negative force at every candidate patch along its admissible
//! directions that best explains the residual, and the best single load or pair.

use moe_geom::{Point3, Real, Vector3};
use nalgebra::{DMatrix, DVector};

use super::FingerInverse;
use super::compliance::{Linear, dot};
use crate::nnls::nnls;

/// A fit of loads at some candidates.
#[derive(Debug, Clone)]
pub(super) struct Fit {
    pub(super) candidates: Vec<usize>,
    pub(super) forces: Vec<Vector3>,
    pub(super) residual_sq: Real,
}

/// Spacing of the candidates of the coarse pair search, metres.
pub(super) const PAIR_SPACING_M: Real = 0.005;

/// Alternating re-placements of a pair's loads.
const PAIR_SWEEPS: usize = 6;

/// `‖r − a₁u₁ − a₂u₂‖²` at the best `a ≥ 0`, from `‖r‖²`, the Gram entries and `h = uᵀr`.
fn pair_residual(r_sq: Real, g11: Real, g22: Real, g12: Real, h1: Real, h2: Real) -> Real {
    let single = |g: Real, h: Real| {
        if g > 0.0 && h > 0.0 {
            r_sq - h * h / g
        } else {
            r_sq
        }
    };
    let det = g11 * g22 - g12 * g12;
    if det > 1e-12 * g11 * g22 {
        let a1 = (g22 * h1 - g12 * h2) / det;
        let a2 = (g11 * h2 - g12 * h1) / det;
        if a1 >= 0.0 && a2 >= 0.0 {
            return (r_sq - a1 * h1 - a2 * h2).max(0.0);
        }
    }
    single(g11, h1).min(single(g22, h2)).max(0.0)
}

impl FingerInverse {
    /// The admissible force directions at a patch with inward normal `inward`: the normal, or
    /// the edges of the friction pyramid around it.
    fn directions(&self, inward: &Vector3) -> Vec<Vector3> {
        let mu = self.config.friction;
        if mu <= 0.0 {
            return vec![*inward];
        }
        let helper = if inward.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let t1 = inward.cross(&helper).normalize();
        let t2 = inward.cross(&t1);
        vec![
            inward + t1 * mu,
            inward - t1 * mu,
            inward + t2 * mu,
            inward - t2 * mu,
        ]
    }

    /// The best single load at candidate `c` for residual `r`, with its residual.
    fn fit_single(
        &self,
        lin: &Linear,
        r: &[Real],
        r_sq: Real,
        c: usize,
        buf: &mut [Real],
    ) -> (Vector3, Real) {
        if self.config.friction <= 0.0 {
            let n = lin.inward[c];
            lin.response_into(c, &n, buf);
            let uu = dot(buf, buf);
            let ur = dot(buf, r);
            if uu > 0.0 && ur > 0.0 {
                (n * (ur / uu), (r_sq - ur * ur / uu).max(0.0))
            } else {
                (Vector3::zeros(), r_sq)
            }
        } else {
            let fit = self.fit(lin, r, &[c]);
            (fit.forces[0], fit.residual_sq)
        }
    }

    /// The best single load at every candidate for residual `r`.
    pub(super) fn single_fits(&self, lin: &Linear, r: &[Real]) -> Vec<(Vector3, Real)> {
        let r_sq = dot(r, r);
        let mut buf = vec![0.0; lin.n_obs];
        (0..self.candidates.len())
            .map(|c| self.fit_single(lin, r, r_sq, c, &mut buf))
            .collect()
    }

    /// Fits loads at `cands` to residual `r`: non-negative combinations of each candidate's
    /// admissible directions.
    fn fit(&self, lin: &Linear, r: &[Real], cands: &[usize]) -> Fit {
        let mut cols: Vec<Vec<Real>> = Vec::new();
        let mut dirs: Vec<(usize, Vector3)> = Vec::new();
        for (k, &c) in cands.iter().enumerate() {
            for d in self.directions(&lin.inward[c]) {
                cols.push(lin.response(c, &d));
                dirs.push((k, d));
            }
        }
        let n = cols.len();
        let g = DMatrix::from_fn(n, n, |i, j| dot(&cols[i], &cols[j]));
        let h = DVector::from_fn(n, |i, _| dot(&cols[i], r));
        let sol = nnls(&g, &h, dot(r, r));
        let mut forces = vec![Vector3::zeros(); cands.len()];
        for (a, (k, d)) in sol.coefficients.iter().zip(&dirs) {
            forces[*k] += d * *a;
        }
        Fit {
            candidates: cands.to_vec(),
            forces,
            residual_sq: sol.residual_sq,
        }
    }

    /// The best single load.
    pub(super) fn best_single(&self, lin: &Linear) -> Option<Fit> {
        let singles = self.single_fits(lin, &lin.r);
        // With a prior over the place, the most probable place: −log of likelihood × prior.
        let two_sigma2 = 2.0 * self.config.marker_sigma_m.powi(2);
        let cost = |c: usize, res: Real| match &self.place_prior {
            Some(prior) => res / two_sigma2 - prior[c].max(Real::MIN_POSITIVE).ln(),
            None => res,
        };
        singles
            .iter()
            .enumerate()
            .filter(|(_, (f, _))| f.norm() > 0.0)
            .min_by(|a, b| cost(a.0, a.1.1).total_cmp(&cost(b.0, b.1.1)))
            .map(|(c, &(f, res))| Fit {
                candidates: vec![c],
                forces: vec![f],
                residual_sq: res,
            })
    }

    /// Whether candidate `c` is at least the minimum separation from rest point `p`.
    fn far_from(&self, c: usize, p: &Point3) -> bool {
        (self.rest_surface[self.candidates[c] as usize] - p).norm()
            >= self.config.min_load_separation_m
    }

    /// The best pair of loads: every pair of a sparse subset of the candidates (at least the
    /// minimum separation apart) along their inward normals, then, from the best of them and
    /// from `first` with its best partner, each load placed again given the other over all
    /// candidates until neither moves; the best pair wins.
    pub(super) fn best_pair(&self, lin: &Linear, first: usize) -> Option<Fit> {
        let n = self.candidates.len();
        let best_with = |fixed: usize| {
            let p = self.rest_surface[self.candidates[fixed] as usize];
            (0..n)
                .filter(|&c| self.far_from(c, &p))
                .map(|c| self.fit(lin, &lin.r, &[fixed, c]))
                .min_by(|a, b| a.residual_sq.total_cmp(&b.residual_sq))
        };
        // Coarse exhaustive search on the normal directions.
        let sub = &self.pair_subset;
        let cols: Vec<Vec<Real>> = sub
            .iter()
            .map(|&c| lin.response(c, &lin.inward[c]))
            .collect();
        let h: Vec<Real> = cols.iter().map(|u| dot(u, &lin.r)).collect();
        let g: Vec<Real> = cols.iter().map(|u| dot(u, u)).collect();
        let r_sq = dot(&lin.r, &lin.r);
        let mut coarse: Option<(Real, usize, usize)> = None;
        for i in 0..sub.len() {
            let pi = self.rest_surface[self.candidates[sub[i]] as usize];
            for j in (i + 1)..sub.len() {
                if !self.far_from(sub[j], &pi) {
                    continue;
                }
                let gij = dot(&cols[i], &cols[j]);
                let res = pair_residual(r_sq, g[i], g[j], gij, h[i], h[j]);
                if coarse.is_none_or(|c| res < c.0) {
                    coarse = Some((res, sub[i], sub[j]));
                }
            }
        }
        let mut starts: Vec<Fit> = Vec::new();
        if let Some((_, a, b)) = coarse {
            starts.push(self.fit(lin, &lin.r, &[a, b]));
        }
        if let Some(p) = best_with(first) {
            starts.push(p);
        }
        let mut best: Option<Fit> = None;
        for mut pair in starts {
            for _ in 0..PAIR_SWEEPS {
                let mut moved = false;
                for k in 0..2 {
                    let other = pair.candidates[1 - k];
                    let Some(again) = best_with(other) else {
                        continue;
                    };
                    if again.residual_sq < pair.residual_sq * (1.0 - 1e-12) {
                        let mut c = vec![0; 2];
                        let mut f = vec![Vector3::zeros(); 2];
                        c[1 - k] = other;
                        f[1 - k] = again.forces[0];
                        c[k] = again.candidates[1];
                        f[k] = again.forces[1];
                        pair = Fit {
                            candidates: c,
                            forces: f,
                            residual_sq: again.residual_sq,
                        };
                        moved = true;
                    }
                }
                if !moved {
                    break;
                }
            }
            if best
                .as_ref()
                .is_none_or(|b| pair.residual_sq < b.residual_sq)
            {
                best = Some(pair);
            }
        }
        best
    }

    /// The loads of a fit scaled by `scale`, each capped at the largest plausible force, and
    /// without loads of zero force.
    pub(super) fn loads_of(&self, fit: &Fit, scale: Real) -> Vec<(usize, Vector3)> {
        let cap = self.config.max_force_n;
        fit.candidates
            .iter()
            .zip(&fit.forces)
            .filter(|(_, f)| f.norm() > 0.0)
            .map(|(&c, f)| {
                let f = f * scale;
                let m = f.norm();
                (c, if m > cap { f * (cap / m) } else { f })
            })
            .collect()
    }
}
