//! The GPIS posterior: a mean function plus a GP on the residuals, with dense and narrow-band
//! grid queries.
//!
//! `f(x) = m(x) + Σ_j w_j k(x, z_j)`: for exact inference `z` are the observations and `w = α`;
//! for the sparse approximation `z` are the inducing points. Grid queries truncate the kernel
//! sum at the radius where `|w_j|·k` can no longer change the result by more than 1 nm in total
//! (see [`Gpis::cutoff_radius`]), processing blocks of nodes with only the observations near them.
//!
//! **Narrow-band meshing.** Marching tetrahedra needs exact values only at nodes next to a sign
//! change. [`Gpis::grid_values_for_meshing`] walks an octree of node blocks: for a block with
//! centre `c` and radius `ρ` (half its diagonal plus one cell diagonal, so the neighbouring nodes
//! are covered too), `|f(x) − m(c)| ≤ L·ρ + Σ_j |w_j| k(max(0, ‖z_j − c‖ − ρ))` where `L` is the
//! mean's Lipschitz constant. If `|m(c)|` exceeds that bound, the block and its neighbours all
//! have the sign of `m(c)`; the block is filled with `m(c)` and no crossing is computed from it.
//! Otherwise the block is split, down to 2×2×2 blocks that are evaluated exactly. The mesh is
//! therefore the same as from the dense evaluation, at a fraction of the cost.

use moe_geom::{Point3, Real};
use rayon::prelude::*;

use crate::error::GpisError;
use crate::gp::ExactGp;
use crate::grid::Grid3;
use crate::kernel::Kernel;
use crate::mean::MeanFunction;
use crate::sparse::SparseGp;

/// The conditioned residual GP: exact or sparse.
#[derive(Debug, Clone)]
pub enum ResidualGp {
    /// Exact inference (Cholesky of the full kernel matrix).
    Exact(ExactGp),
    /// Subset-of-regressors approximation on inducing points.
    Sparse(SparseGp),
}

impl ResidualGp {
    /// The kernel.
    pub fn kernel(&self) -> Kernel {
        match self {
            Self::Exact(g) => g.kernel(),
            Self::Sparse(g) => g.kernel(),
        }
    }

    /// `(z, w)` of the mean `Σ_j w_j k(x, z_j)`.
    pub fn support(&self) -> (&[Point3], &[Real]) {
        match self {
            Self::Exact(g) => (g.points(), g.alpha()),
            Self::Sparse(g) => (g.inducing(), g.weights()),
        }
    }

    /// Posterior mean of the residual at `p`.
    pub fn mean_residual(&self, p: &Point3) -> Real {
        match self {
            Self::Exact(g) => g.mean_residual(p),
            Self::Sparse(g) => g.mean_residual(p),
        }
    }

    /// Posterior variance of the latent function at each query.
    pub fn variances(&self, queries: &[Point3]) -> Vec<Real> {
        match self {
            Self::Exact(g) => g.variances(queries),
            Self::Sparse(g) => g.variances(queries),
        }
    }

    /// Diagonal jitter that was added.
    pub fn jitter(&self) -> Real {
        match self {
            Self::Exact(g) => g.jitter(),
            Self::Sparse(g) => g.jitter(),
        }
    }
}

/// A Gaussian-process implicit surface: mean function plus conditioned residual GP.
#[derive(Debug, Clone)]
pub struct Gpis<M> {
    /// The mean function (prior SDF).
    pub mean: M,
    /// The residual GP.
    pub gp: ResidualGp,
}

/// Nodes per side of the top-level blocks of grid queries.
const TOP_BLOCK: usize = 16;

#[derive(Clone, Copy)]
struct Block {
    lo: [usize; 3],
    hi: [usize; 3], // exclusive
}

impl<M: MeanFunction> Gpis<M> {
    /// The radius beyond which kernel terms are dropped: the total dropped contribution is below
    /// 1 nm (`σ²·tol·Σ|w| ≤ 1e-9`, with `tol ≤ 1e-12`).
    pub fn cutoff_radius(&self) -> Real {
        let kernel = self.gp.kernel();
        let (_, w) = self.gp.support();
        let sum_w: Real = w.iter().map(|v| v.abs()).sum();
        let tol = (1e-9 / (kernel.signal_variance * sum_w).max(1e-300)).min(1e-12);
        kernel.cutoff_radius(tol)
    }

    /// Posterior mean of the SDF at `p` (exact sum, no truncation).
    pub fn mean_at(&self, p: &Point3) -> Real {
        self.mean.value(p) + self.gp.mean_residual(p)
    }

    /// Posterior mean and standard deviation at each query point, in input order.
    ///
    /// # Errors
    /// [`GpisError::NonFiniteObservation`] naming the first non-finite query.
    pub fn query(&self, points: &[Point3]) -> Result<Vec<(Real, Real)>, GpisError> {
        if let Some(index) = points
            .iter()
            .position(|p| !moe_geom::math::is_finite_point(p))
        {
            return Err(GpisError::NonFiniteObservation {
                what: "query point",
                index,
            });
        }
        let means: Vec<Real> = points.par_iter().map(|p| self.mean_at(p)).collect();
        let vars = self.gp.variances(points);
        Ok(means
            .into_iter()
            .zip(vars)
            .map(|(m, v)| (m, v.sqrt()))
            .collect())
    }

    /// Posterior variance at each point; points farther than [`Gpis::cutoff_radius`] from every
    /// support point get the prior variance `σ²` without a solve.
    pub fn variances(&self, points: &[Point3]) -> Vec<Real> {
        let (z, _) = self.gp.support();
        let kernel = self.gp.kernel();
        let r2 = self.cutoff_radius().powi(2);
        let near: Vec<bool> = match moe_geom::PointIndex::new(z, "support") {
            Ok(index) => points
                .par_iter()
                .map(|p| index.nearest(p).distance.powi(2) < r2)
                .collect(),
            Err(_) => vec![true; points.len()],
        };
        let near_pts: Vec<Point3> = points
            .iter()
            .zip(&near)
            .filter(|(_, n)| **n)
            .map(|(p, _)| *p)
            .collect();
        let mut near_var = self.gp.variances(&near_pts).into_iter();
        near.iter()
            .map(|&n| {
                if n {
                    near_var.next().unwrap_or(kernel.signal_variance)
                } else {
                    kernel.signal_variance
                }
            })
            .collect()
    }

    /// The posterior mean at every grid node (exact up to the 1 nm truncation).
    pub fn grid_values(&self, grid: &Grid3) -> Vec<Real> {
        self.eval_grid(grid, false)
    }

    /// Grid values for meshing: exact near the zero level set, sign-certified elsewhere (module
    /// docs). Gives the same mesh as [`Gpis::grid_values`].
    pub fn grid_values_for_meshing(&self, grid: &Grid3) -> Vec<Real> {
        self.eval_grid(grid, true)
    }

    fn eval_grid(&self, grid: &Grid3, narrow: bool) -> Vec<Real> {
        let [nx, ny, nz] = grid.dims;
        let mut tops = Vec::new();
        for k in (0..nz).step_by(TOP_BLOCK) {
            for j in (0..ny).step_by(TOP_BLOCK) {
                for i in (0..nx).step_by(TOP_BLOCK) {
                    tops.push(Block {
                        lo: [i, j, k],
                        hi: [
                            (i + TOP_BLOCK).min(nx),
                            (j + TOP_BLOCK).min(ny),
                            (k + TOP_BLOCK).min(nz),
                        ],
                    });
                }
            }
        }
        let (z, w) = self.gp.support();
        let cutoff = self.cutoff_radius();
        let all: Vec<u32> = (0..z.len() as u32).collect();
        let pieces: Vec<Vec<(usize, Real)>> = tops
            .par_iter()
            .map(|b| {
                let cands = self.near_block(grid, b, &all, cutoff);
                let mut out = Vec::new();
                self.fill(grid, *b, &cands, z, w, cutoff, narrow, &mut out);
                out
            })
            .collect();
        let mut values = vec![0.0; grid.num_nodes()];
        for piece in pieces {
            for (i, v) in piece {
                values[i] = v;
            }
        }
        values
    }

    /// Support points within `cutoff` of the block's box.
    fn near_block(&self, grid: &Grid3, b: &Block, cands: &[u32], cutoff: Real) -> Vec<u32> {
        let (z, _) = self.gp.support();
        let lo = grid.point(b.lo[0], b.lo[1], b.lo[2]);
        let hi = grid.point(b.hi[0] - 1, b.hi[1] - 1, b.hi[2] - 1);
        let c2 = cutoff * cutoff;
        cands
            .iter()
            .copied()
            .filter(|&j| {
                let p = z[j as usize];
                let d = (lo - p).sup(&(p - hi)).sup(&moe_geom::Vector3::zeros());
                d.norm_squared() <= c2
            })
            .collect()
    }

    #[allow(clippy::too_many_arguments)]
    fn fill(
        &self,
        grid: &Grid3,
        b: Block,
        cands: &[u32],
        z: &[Point3],
        w: &[Real],
        cutoff: Real,
        narrow: bool,
        out: &mut Vec<(usize, Real)>,
    ) {
        let size = [0, 1, 2].map(|d| b.hi[d] - b.lo[d]);
        let kernel = self.gp.kernel();
        if narrow && size.iter().any(|&s| s > 2) {
            let lo = grid.point(b.lo[0], b.lo[1], b.lo[2]);
            let hi = grid.point(b.hi[0] - 1, b.hi[1] - 1, b.hi[2] - 1);
            let c = nalgebra_center(&lo, &hi);
            let rho = 0.5 * (hi - lo).norm() + grid.spacing * 3f64.sqrt();
            let m_c = self.mean.value(&c);
            let bound: Real = cands
                .iter()
                .map(|&j| {
                    let r = ((z[j as usize] - c).norm() - rho).max(0.0);
                    w[j as usize].abs() * kernel.eval_r2(r * r)
                })
                .sum();
            if m_c.abs() > self.mean.lipschitz() * rho + bound {
                for k in b.lo[2]..b.hi[2] {
                    for j in b.lo[1]..b.hi[1] {
                        for i in b.lo[0]..b.hi[0] {
                            out.push((grid.index(i, j, k), m_c));
                        }
                    }
                }
                return;
            }
            // Split every axis longer than one node in two.
            let mids = [0, 1, 2].map(|d| {
                if size[d] > 1 {
                    b.lo[d] + size[d] / 2
                } else {
                    b.hi[d]
                }
            });
            for oz in 0..2 {
                for oy in 0..2 {
                    for ox in 0..2 {
                        let o = [ox, oy, oz];
                        let mut sub = b;
                        let mut empty = false;
                        for d in 0..3 {
                            if o[d] == 0 {
                                sub.hi[d] = mids[d];
                            } else {
                                sub.lo[d] = mids[d];
                            }
                            empty |= sub.lo[d] >= sub.hi[d];
                        }
                        if !empty {
                            let sub_cands = self.near_block(grid, &sub, cands, cutoff);
                            self.fill(grid, sub, &sub_cands, z, w, cutoff, narrow, out);
                        }
                    }
                }
            }
            return;
        }
        let c2 = cutoff * cutoff;
        for k in b.lo[2]..b.hi[2] {
            for j in b.lo[1]..b.hi[1] {
                for i in b.lo[0]..b.hi[0] {
                    let p = grid.point(i, j, k);
                    let mut v = self.mean.value(&p);
                    for &jj in cands {
                        let r2 = (p - z[jj as usize]).norm_squared();
                        if r2 <= c2 {
                            v += w[jj as usize] * kernel.eval_r2(r2);
                        }
                    }
                    out.push((grid.index(i, j, k), v));
                }
            }
        }
    }
}

fn nalgebra_center(a: &Point3, b: &Point3) -> Point3 {
    Point3::from((a.coords + b.coords) * 0.5)
}
