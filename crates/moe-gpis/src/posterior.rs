//! The GPIS posterior: a mean function plus a GP on the residuals, with dense and narrow-band
//! grid queries.
//!
//! `f(x) = m(x) + g(x)`, `g(x) = Σ_j w_j k(x, z_j)`: for exact inference `z` are the
//! observations and `w = α`; for the sparse approximation `z` are the inducing points.
//!
//! **Grid queries.** The residual `g` is computed at every node first ([`Gpis::residual_on_grid`]:
//! a matrix product for the separable RBF kernel). The mean `m` — a BVH query for a prior mesh,
//! the expensive part — is evaluated exactly only where meshing needs it:
//!
//! **Narrow band.** Marching tetrahedra needs exact values only at the end points of grid edges
//! whose sign changes. [`Gpis::grid_values_for_meshing`] first walks an octree of node blocks:
//! for a block with centre `c` and radius `ρ` (half its diagonal), `m(x) ∈ m(c) ± L·ρ` where `L`
//! is the mean's Lipschitz constant (1 for a signed distance), and `g` is known at every node.
//! If `m(c) − Lρ + min g > 0` (or `m(c) + Lρ + max g < 0`), every node of the block has that
//! sign and gets the value `m(c) + g(x)`, which has the certified sign. Otherwise the block is
//! split, down to 2×2×2 blocks that are evaluated exactly. A second pass evaluates exactly every
//! certified node that shares a tetrahedron edge with a node of the other sign (as marching will
//! classify it). Every crossing is therefore interpolated from exact values, and the mesh is the
//! same as from the dense evaluation.

use moe_geom::{Point3, Real};
use rayon::prelude::*;

use crate::error::GpisError;
use crate::gp::ExactGp;
use crate::grid::Grid3;
use crate::kernel::{Kernel, KernelKind};
use crate::mean::MeanFunction;
use crate::sparse::SparseGp;
use faer::Mat;

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

/// Offsets to the 14 nodes that share a tetrahedron edge with a node (Freudenthal split).
const NEIGHBOURS: [[isize; 3]; 14] = [
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
    [1, 1, 0],
    [-1, -1, 0],
    [1, 0, 1],
    [-1, 0, -1],
    [0, 1, 1],
    [0, -1, -1],
    [1, 1, 1],
    [-1, -1, -1],
];

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
        crate::observations::check_finite(points, "query point")?;
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

    /// The posterior mean at every grid node (exact; see [`Gpis::residual_on_grid`]).
    pub fn grid_values(&self, grid: &Grid3) -> Vec<Real> {
        let g = self.residual_on_grid(grid);
        let pts = grid.points();
        let m = self.mean.values(&pts);
        m.iter().zip(&g).map(|(a, b)| a + b).collect()
    }

    /// Grid values for meshing: exact near the zero level set, sign-certified elsewhere (module
    /// docs). Gives the same mesh as [`Gpis::grid_values`].
    pub fn grid_values_for_meshing(&self, grid: &Grid3) -> Vec<Real> {
        let g = self.residual_on_grid(grid);
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
        let pieces: Vec<Vec<(usize, Real, bool)>> = tops
            .par_iter()
            .map(|b| {
                let mut out = Vec::new();
                self.fill(grid, *b, &g, None, &mut out);
                out
            })
            .collect();
        let mut values = g.clone();
        let mut exact = vec![false; grid.num_nodes()];
        for piece in pieces {
            for (i, v, e) in piece {
                values[i] = v;
                exact[i] = e;
            }
        }
        // Second pass: a certified node whose tetrahedron neighbour has the other sign (as
        // marching will see it) is an edge end point: evaluate it exactly. Certification is
        // rigorous for the node itself, so this creates no new sign change.
        let eps = crate::marching::near_zero(grid);
        let inside = |idx: usize, v: Real| crate::marching::counts_as_inside(grid, idx, v, eps);
        let [nx, ny, _] = grid.dims;
        let todo: Vec<usize> = (0..grid.num_nodes())
            .into_par_iter()
            .filter(|&idx| {
                if exact[idx] {
                    return false;
                }
                let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
                let me = inside(idx, values[idx]);
                NEIGHBOURS.iter().any(|&[di, dj, dk]| {
                    let (a, b, c) = (i as isize + di, j as isize + dj, k as isize + dk);
                    if a < 0 || b < 0 || c < 0 {
                        return false;
                    }
                    let (a, b, c) = (a as usize, b as usize, c as usize);
                    if a >= grid.dims[0] || b >= grid.dims[1] || c >= grid.dims[2] {
                        return false;
                    }
                    let n = grid.index(a, b, c);
                    inside(n, values[n]) != me
                })
            })
            .collect();
        let fixed: Vec<Real> = todo
            .par_iter()
            .map(|&idx| {
                let p = grid.point(idx % nx, (idx / nx) % ny, idx / (nx * ny));
                self.mean.value(&p) + g[idx]
            })
            .collect();
        for (idx, v) in todo.into_iter().zip(fixed) {
            values[idx] = v;
        }
        values
    }

    /// The residual mean `Σ_j w_j k(x, z_j)` at every grid node.
    ///
    /// For the RBF kernel this is exact and fast: the kernel factorises over the axes,
    /// `k(x, z) = σ² Π_a exp(−(x_a − z_a)²/(2l²))`, so the grid sum is the matrix product
    /// `A · E_z` with `A[(i,j), o] = w_o E_x[o,i] E_y[o,j]` (`O(n·nx·ny·nz)` flops through faer's
    /// matrix multiply). For Matérn 3/2 the sum is evaluated per node, truncated at
    /// [`Gpis::cutoff_radius`].
    pub fn residual_on_grid(&self, grid: &Grid3) -> Vec<Real> {
        let kernel = self.gp.kernel();
        let (z, w) = self.gp.support();
        let [nx, ny, nz] = grid.dims;
        match kernel.kind {
            KernelKind::Rbf => {
                let n = z.len();
                let inv = -0.5 / (kernel.lengthscale * kernel.lengthscale);
                let axis = |a: usize, count: usize| {
                    Mat::<Real>::from_fn(n, count, |o, i| {
                        let x = grid.origin[a] + i as Real * grid.spacing;
                        (inv * (x - z[o][a]).powi(2)).exp()
                    })
                };
                let (ex, ey, ez) = (axis(0, nx), axis(1, ny), axis(2, nz));
                let a = Mat::<Real>::from_fn(nx * ny, n, |ij, o| {
                    kernel.signal_variance * w[o] * ex[(o, ij % nx)] * ey[(o, ij / nx)]
                });
                let g = &a * &ez; // (nx·ny) × nz
                let mut out = vec![0.0; grid.num_nodes()];
                for k in 0..nz {
                    for ij in 0..nx * ny {
                        out[ij + nx * ny * k] = g[(ij, k)];
                    }
                }
                out
            }
            KernelKind::Matern32 => {
                let c2 = self.cutoff_radius().powi(2);
                (0..grid.num_nodes())
                    .into_par_iter()
                    .map(|idx| {
                        let p = grid.point(idx % nx, (idx / nx) % ny, idx / (nx * ny));
                        z.iter()
                            .zip(w)
                            .map(|(zj, wj)| {
                                let r2 = (p - zj).norm_squared();
                                if r2 <= c2 {
                                    wj * kernel.eval_r2(r2)
                                } else {
                                    0.0
                                }
                            })
                            .sum()
                    })
                    .collect()
            }
        }
    }

    /// Narrow-band recursion over a block: `g` holds the residual at every node.
    /// `parent` is the parent block's centre and the sign of `m` there.
    fn fill(
        &self,
        grid: &Grid3,
        b: Block,
        g: &[Real],
        parent: Option<(Point3, Real)>,
        out: &mut Vec<(usize, Real, bool)>,
    ) {
        let size = [0, 1, 2].map(|d| b.hi[d] - b.lo[d]);
        if size.iter().any(|&s| s > 2) {
            let lo = grid.point(b.lo[0], b.lo[1], b.lo[2]);
            let hi = grid.point(b.hi[0] - 1, b.hi[1] - 1, b.hi[2] - 1);
            let c = nalgebra_center(&lo, &hi);
            let rho = 0.5 * (hi - lo).norm();
            let (mut g_min, mut g_max) = (Real::INFINITY, Real::NEG_INFINITY);
            for k in b.lo[2]..b.hi[2] {
                for j in b.lo[1]..b.hi[1] {
                    for i in b.lo[0]..b.hi[0] {
                        let v = g[grid.index(i, j, k)];
                        g_min = g_min.min(v);
                        g_max = g_max.max(v);
                    }
                }
            }
            let lip = self.mean.lipschitz();
            let slack = lip * rho;
            // Far from the surface a bounded search answers "farther than t" cheaply; the sign is
            // then the parent centre's, which lies inside the surface-free ball of radius t.
            let g_abs = g_min.abs().max(g_max.abs());
            let t = slack + g_abs + 2.0 * crate::marching::near_zero(grid);
            // Node blocks do not nest exactly (the parent centre can be farther than `t`): the
            // bounded search radius is grown to reach it.
            let m_c = match parent {
                Some((pc, _)) if lip > 0.0 => {
                    self.mean.value_within(&c, t.max(1.0001 * (c - pc).norm()))
                }
                _ => Some(self.mean.value(&c)),
            };
            let Some(m_c) = m_c else {
                let sign = parent.map_or(1.0, |(_, s)| s);
                for k in b.lo[2]..b.hi[2] {
                    for j in b.lo[1]..b.hi[1] {
                        for i in b.lo[0]..b.hi[0] {
                            let idx = grid.index(i, j, k);
                            // |m| ≥ t − Lρ = |g|max + 2ε here, so this has the sign of f.
                            out.push((idx, sign * (t - slack) + g[idx], false));
                        }
                    }
                }
                return;
            };
            if m_c - slack + g_min > 0.0 || m_c + slack + g_max < 0.0 {
                for k in b.lo[2]..b.hi[2] {
                    for j in b.lo[1]..b.hi[1] {
                        for i in b.lo[0]..b.hi[0] {
                            let idx = grid.index(i, j, k);
                            out.push((idx, m_c + g[idx], false));
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
                            let sign = if m_c < 0.0 { -1.0 } else { 1.0 };
                            self.fill(grid, sub, g, Some((c, sign)), out);
                        }
                    }
                }
            }
            return;
        }
        for k in b.lo[2]..b.hi[2] {
            for j in b.lo[1]..b.hi[1] {
                for i in b.lo[0]..b.hi[0] {
                    let idx = grid.index(i, j, k);
                    out.push((idx, self.mean.value(&grid.point(i, j, k)) + g[idx], true));
                }
            }
        }
    }
}

fn nalgebra_center(a: &Point3, b: &Point3) -> Point3 {
    Point3::from((a.coords + b.coords) * 0.5)
}
