//! The sparse symmetric system of one body: a block (3 × 3 per node pair) lower-triangular CSC
//! pattern over the free nodes, analysed once (AMD ordering + symbolic Cholesky), refactorised
//! numerically every step, with all scratch memory allocated up front and sequential (`Par::Seq`)
//! kernels so that results are bit-for-bit reproducible.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, MatMut, Par, Side};
use moe_geom::{Matrix3, Real};

/// Marker for a node that is not a free unknown.
pub(crate) const FIXED: u32 = u32::MAX;

/// Sparsity pattern and symbolic factorisation of a body's system matrix. Cloning shares the
/// symbolic factorisation, which no solve changes.
#[derive(Debug, Clone)]
pub(crate) struct SparseSystem {
    /// Free index of each node, or [`FIXED`].
    free_of: Vec<u32>,
    n_free: usize,
    /// For free column node `J`: rows `row_nodes[row_ptr[J]..row_ptr[J+1]]`, `J` first, then the
    /// other free nodes `I > J`, sorted.
    row_ptr: Vec<usize>,
    row_nodes: Vec<u32>,
    matrix: SymbolicSparseColMat<u32>,
    cholesky: std::sync::Arc<SymbolicCholesky<u32>>,
    max_rhs: usize,
}

/// Per-step numeric storage for a [`SparseSystem`].
pub(crate) struct SystemBuffers {
    /// Values of the lower triangle, in the pattern's CSC order.
    pub(crate) values: Vec<Real>,
    l_values: Vec<Real>,
    mem: MemBuffer,
    /// Right-hand sides, `3·n_free × k`.
    pub(crate) rhs: Mat<Real>,
}

/// The matrix was not numerically positive definite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct NotPositiveDefinite;

impl SparseSystem {
    /// Builds the pattern from node pairs (node ids; pairs with a fixed node are ignored), with
    /// room for right-hand sides of up to `max_rhs` columns.
    pub(crate) fn new(
        fixed: &[bool],
        pairs: impl IntoIterator<Item = (u32, u32)>,
        max_rhs: usize,
    ) -> Self {
        let mut free_of = vec![FIXED; fixed.len()];
        let mut n_free = 0usize;
        for (i, &f) in fixed.iter().enumerate() {
            if !f {
                free_of[i] = n_free as u32;
                n_free += 1;
            }
        }
        let mut cols: Vec<Vec<u32>> = (0..n_free).map(|j| vec![j as u32]).collect();
        for (a, b) in pairs {
            let (fa, fb) = (free_of[a as usize], free_of[b as usize]);
            if fa == FIXED || fb == FIXED || fa == fb {
                continue;
            }
            cols[fa.min(fb) as usize].push(fa.max(fb));
        }
        let mut row_ptr = Vec::with_capacity(n_free + 1);
        let mut row_nodes = Vec::new();
        row_ptr.push(0);
        for mut c in cols {
            c[1..].sort_unstable();
            c.dedup();
            row_nodes.extend_from_slice(&c);
            row_ptr.push(row_nodes.len());
        }
        let n = 3 * n_free;
        let mut col_ptr: Vec<u32> = Vec::with_capacity(n + 1);
        let mut row_idx: Vec<u32> = Vec::new();
        col_ptr.push(0);
        for j in 0..n_free {
            let rows = &row_nodes[row_ptr[j]..row_ptr[j + 1]];
            for c in 0..3 {
                for r in c..3 {
                    row_idx.push((3 * j + r) as u32);
                }
                for &i in &rows[1..] {
                    for r in 0..3 {
                        row_idx.push(3 * i + r);
                    }
                }
                col_ptr.push(row_idx.len() as u32);
            }
        }
        let matrix = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let cholesky = factorize_symbolic_cholesky(
            matrix.as_ref(),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .expect("symbolic analysis of a valid pattern only fails when out of memory");
        Self {
            free_of,
            n_free,
            row_ptr,
            row_nodes,
            matrix,
            cholesky: std::sync::Arc::new(cholesky),
            max_rhs: max_rhs.max(1),
        }
    }

    /// Number of free nodes.
    pub(crate) fn n_free(&self) -> usize {
        self.n_free
    }

    /// Free index of a node, or [`FIXED`].
    #[inline]
    pub(crate) fn free_of(&self, node: u32) -> u32 {
        self.free_of[node as usize]
    }

    /// Allocates the numeric storage.
    pub(crate) fn buffers(&self) -> SystemBuffers {
        let req = self.solve_scratch(self.max_rhs);
        SystemBuffers {
            values: vec![0.0; self.matrix.row_idx().len()],
            l_values: vec![0.0; self.cholesky.len_val()],
            mem: MemBuffer::new(req),
            rhs: Mat::zeros(3 * self.n_free, 1),
        }
    }

    /// Adds `scale · block` at (row free node `i`, column free node `j`), mirrored into the
    /// lower triangle. For `i == j` only the lower part of `block` is read.
    #[inline]
    pub(crate) fn add_block(&self, values: &mut [Real], i: u32, j: u32, block: &Matrix3) {
        let col_ptr = self.matrix.col_ptr();
        if i == j {
            for c in 0..3 {
                let p0 = col_ptr[3 * j as usize + c] as usize;
                for r in c..3 {
                    values[p0 + r - c] += block[(r, c)];
                }
            }
            return;
        }
        // Stored entry (row node hi, column node lo) holds A_{hi,lo}.
        let (hi, lo, transpose) = if i > j { (i, j, false) } else { (j, i, true) };
        let rows = &self.row_nodes[self.row_ptr[lo as usize] + 1..self.row_ptr[lo as usize + 1]];
        let k = rows
            .binary_search(&hi)
            .expect("node pair missing from the system pattern");
        for c in 0..3 {
            let p0 = col_ptr[3 * lo as usize + c] as usize + (3 - c) + 3 * k;
            for r in 0..3 {
                values[p0 + r] += if transpose {
                    block[(c, r)]
                } else {
                    block[(r, c)]
                };
            }
        }
    }

    /// The position of free node `hi` among the off-diagonal row nodes of column node `lo`
    /// (`hi > lo`): the slot [`SparseSystem::add_lower_block_at`] takes, so that a caller
    /// adding the same pairs every step searches once. `None` for a pair outside the pattern.
    pub(crate) fn lower_slot(&self, hi: u32, lo: u32) -> Option<u32> {
        let rows = &self.row_nodes[self.row_ptr[lo as usize] + 1..self.row_ptr[lo as usize + 1]];
        rows.binary_search(&hi).ok().map(|k| k as u32)
    }

    /// Adds `block` = `A_{hi,lo}` for free nodes `hi > lo`, `k` the slot of `hi` in column `lo`
    /// ([`SparseSystem::lower_slot`]): what [`SparseSystem::add_block`] does for that pair,
    /// without the search.
    #[inline]
    pub(crate) fn add_lower_block_at(&self, values: &mut [Real], lo: u32, k: u32, block: &Matrix3) {
        let col_ptr = self.matrix.col_ptr();
        for c in 0..3 {
            let p0 = col_ptr[3 * lo as usize + c] as usize + (3 - c) + 3 * k as usize;
            for r in 0..3 {
                values[p0 + r] += block[(r, c)];
            }
        }
    }

    /// Factorises the values in `buf` and solves in place for the first `ncols` columns of
    /// `buf.rhs`.
    pub(crate) fn factor_and_solve(
        &self,
        buf: &mut SystemBuffers,
        ncols: usize,
    ) -> Result<(), NotPositiveDefinite> {
        let SystemBuffers {
            values,
            l_values,
            mem,
            rhs,
        } = buf;
        self.factor_values(values, l_values, mem)?;
        self.solve_factored(l_values, mem, rhs.as_mut().subcols_mut(0, ncols));
        Ok(())
    }

    /// Factorises the matrix of `values` into `l_values` (for
    /// [`SparseSystem::solve_factored`]); `mem` must hold at least the factorisation's scratch
    /// (as [`SparseSystem::buffers`] and [`SparseSystem::solve_scratch`] size it).
    pub(crate) fn factor_values(
        &self,
        values: &[Real],
        l_values: &mut [Real],
        mem: &mut MemBuffer,
    ) -> Result<(), NotPositiveDefinite> {
        let stack = MemStack::new(mem);
        let a = SparseColMatRef::new(self.matrix.as_ref(), values);
        self.cholesky
            .factorize_numeric_llt(
                l_values,
                a,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .map_err(|_| NotPositiveDefinite)?;
        Ok(())
    }

    /// Solves in place with the factor `l_values` left by [`SparseSystem::factor`]; `mem` must
    /// hold the scratch of [`SparseSystem::solve_scratch`] for `rhs.ncols()` columns.
    pub(crate) fn solve_factored(
        &self,
        l_values: &[Real],
        mem: &mut MemBuffer,
        rhs: MatMut<'_, Real>,
    ) {
        let llt: LltRef<'_, u32, Real> = LltRef::new(&self.cholesky, l_values);
        let stack = MemStack::new(mem);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack);
    }

    /// Scratch of a factorisation and of a solve with `ncols` right-hand sides.
    pub(crate) fn solve_scratch(&self, ncols: usize) -> StackReq {
        StackReq::any_of(&[
            self.cholesky
                .factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
            self.cholesky
                .solve_in_place_scratch::<Real>(ncols, Par::Seq),
        ])
    }

    /// Number of values of the factor.
    pub(crate) fn factor_len(&self) -> usize {
        self.cholesky.len_val()
    }

    /// Ensures `buf.rhs` has at least `ncols` columns and zeroes the first `ncols`.
    pub(crate) fn prepare_rhs(&self, buf: &mut SystemBuffers, ncols: usize) {
        if buf.rhs.ncols() < ncols {
            buf.rhs = Mat::zeros(3 * self.n_free, ncols);
        } else {
            buf.rhs.as_mut().subcols_mut(0, ncols).fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_assembly_and_solve_match_a_dense_reference() {
        // Path graph of 4 nodes, node 1 fixed: free nodes 0, 2, 3 with pairs (2,3) only.
        let fixed = [false, true, false, false];
        let sys = SparseSystem::new(&fixed, [(0, 1), (1, 2), (2, 3), (0, 2)], 2);
        assert_eq!(sys.n_free(), 3);
        let mut buf = sys.buffers();
        let n = 9;
        let mut dense = nalgebra::DMatrix::<Real>::zeros(n, n);
        let blocks = [
            (
                0u32,
                0u32,
                Matrix3::new(4.0, 1.0, 0.5, 1.0, 5.0, 0.2, 0.5, 0.2, 6.0),
            ),
            (1, 1, Matrix3::from_diagonal_element(7.0)),
            (2, 2, Matrix3::from_diagonal_element(8.0)),
            (
                1,
                2,
                Matrix3::new(0.1, -0.3, 0.2, 0.4, 0.0, -0.1, 0.3, 0.2, -0.5),
            ),
            (
                0,
                1,
                Matrix3::new(0.2, 0.1, 0.0, -0.2, 0.3, 0.1, 0.0, 0.0, 0.4),
            ),
        ];
        for (i, j, b) in blocks {
            sys.add_block(&mut buf.values, i, j, &b);
            for r in 0..3 {
                for c in 0..3 {
                    let (ri, cj) = (3 * i as usize + r, 3 * j as usize + c);
                    if i == j {
                        dense[(ri, cj)] += b[(r.max(c), r.min(c))];
                    } else {
                        dense[(ri, cj)] += b[(r, c)];
                        dense[(cj, ri)] += b[(r, c)];
                    }
                }
            }
        }
        sys.prepare_rhs(&mut buf, 2);
        let b =
            nalgebra::DMatrix::<Real>::from_fn(n, 2, |i, j| (i as Real + 1.0) * (j as Real - 0.5));
        for i in 0..n {
            for j in 0..2 {
                buf.rhs[(i, j)] = b[(i, j)];
            }
        }
        sys.factor_and_solve(&mut buf, 2).unwrap();
        let x = dense.clone().cholesky().unwrap().solve(&b);
        for i in 0..n {
            for j in 0..2 {
                assert!((buf.rhs[(i, j)] - x[(i, j)]).abs() < 1e-12);
            }
        }
        // Not positive definite: reported, not panicking.
        buf.values.iter_mut().for_each(|v| *v = -*v);
        sys.prepare_rhs(&mut buf, 1);
        assert_eq!(sys.factor_and_solve(&mut buf, 1), Err(NotPositiveDefinite));
    }
}
