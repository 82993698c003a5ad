//! The reduced global-step system, factorised once, with switchable handles imposed through a
//! small Schur complement.
//!
//! Unknowns are the non-fixed vertices. The matrix `K = L′[free, free]` (the Laplacian with the
//! system weights `c_e w_e / 2`) is factorised once by faer's sparse Cholesky. Handle vertices stay
//! unknowns of `K`; a frame's active handles `A` are imposed with Lagrange multipliers:
//!
//! ```text
//! [K  E_A] [x]   [b]          y = K⁻¹ b,   (E_Aᵀ K⁻¹ E_A) λ = y_A − t_A,   x = y − K⁻¹ E_A λ,
//! [E_Aᵀ 0] [λ] = [t_A]   ⇒
//! ```
//!
//! where `E_A` selects the active handle rows. The columns `Z = K⁻¹ E_H` for all handles `H`
//! and `S = E_Hᵀ Z` are computed once (one solve per handle). A frame picks the rows and columns
//! of its active handles from `S` (at most a few dozen, dense) and factorises that tiny block; the
//! sparse factor is never recomputed when markers are occluded. The result equals the solution of
//! the system reduced by the active handles, because the multiplier rows only replace the
//! handles' own equations.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymbolicCholeskyRaw, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Conj, Mat, MatMut, Par, Side};
use moe_geom::Real;
use std::sync::Arc;

use crate::cells::Cells;
use crate::error::ArapError;

/// Marker for a fixed vertex in `unknown_of`.
pub(crate) const FIXED: u32 = u32::MAX;

/// `K`'s lower triangle, with the index in its values of every column's diagonal entry.
#[derive(Debug)]
struct BaseMatrix {
    k: SparseColMat<u32, Real>,
    diagonal: Vec<usize>,
}

impl BaseMatrix {
    fn new(k: SparseColMat<u32, Real>) -> Self {
        let col_ptr = k.symbolic().col_ptr();
        let row_idx = k.symbolic().row_idx();
        // Every unknown has a diagonal triplet, so every column holds its entry.
        let diagonal = (0..k.ncols())
            .map(|j| {
                (col_ptr[j] as usize..col_ptr[j + 1] as usize)
                    .find(|&i| row_idx[i] as usize == j)
                    .unwrap_or(col_ptr[j] as usize)
            })
            .collect();
        Self { k, diagonal }
    }
}

/// The factorised reduced system and the handle Schur data.
#[derive(Debug)]
pub(crate) struct ReducedSystem {
    /// Unknown index of every vertex, or [`FIXED`].
    pub(crate) unknown_of: Vec<u32>,
    /// Vertex of every unknown.
    pub(crate) vertex_of: Vec<u32>,
    symbolic: Option<Arc<SymbolicCholesky<u32>>>,
    values: Vec<Real>,
    /// `K`'s lower triangle and where its diagonal entries are, found once and shared with
    /// the systems made from this one, to factorise `K + D` for a diagonal `D`
    /// ([`ReducedSystem::with_diagonal`]).
    matrix: Option<Arc<BaseMatrix>>,
    /// The factor's structure when faer chose a simplicial factorisation (small meshes), for the
    /// three-column solve of every iteration.
    simplicial: Option<SimplicialFactor>,
    /// Per unknown, the fixed neighbours (slot in the fixed list) and system weights (CSR).
    pub(crate) coupling_offsets: Vec<usize>,
    pub(crate) coupling: Vec<(u32, Real)>,
    /// Unknown index of every handle.
    pub(crate) handle_unknowns: Vec<u32>,
    /// `Z = K⁻¹ E_H` row-major (`m × h`): row `u` holds the handle columns' entries for
    /// unknown `u`, read together in the correction pass.
    z: Vec<Real>,
    /// `S = E_Hᵀ K⁻¹ E_H`, row-major `h × h`.
    schur: Vec<Real>,
}

impl ReducedSystem {
    /// Assembles and factorises `K` for the given fixed vertices (`fixed_slot[v]` is the slot of
    /// `v` in the fixed list, or `None`).
    pub(crate) fn new(cells: &Cells, fixed_slot: &[Option<u32>]) -> Result<Self, ArapError> {
        let n = cells.num_vertices();
        check_anchored(cells, fixed_slot)?;
        let mut unknown_of = vec![FIXED; n];
        let mut vertex_of = Vec::with_capacity(n);
        for v in 0..n {
            if fixed_slot[v].is_none() {
                unknown_of[v] = vertex_of.len() as u32;
                vertex_of.push(v as u32);
            }
        }
        let m = vertex_of.len();
        let mut triplets = Vec::with_capacity(m + 2 * cells.edges.len());
        let mut coupling_offsets = Vec::with_capacity(m + 1);
        let mut coupling = Vec::new();
        coupling_offsets.push(0);
        for (u, &v) in vertex_of.iter().enumerate() {
            let mut diag = 0.0;
            for (&w, &e) in cells
                .ring(v as usize)
                .iter()
                .zip(cells.ring_edge_ids(v as usize))
            {
                let weight = cells.matrix_weight(e as usize);
                diag += weight;
                match fixed_slot[w as usize] {
                    Some(slot) => coupling.push((slot, weight)),
                    None => {
                        let uw = unknown_of[w as usize];
                        if uw < u as u32 {
                            triplets.push(Triplet::new(u as u32, uw, -weight));
                        }
                    }
                }
            }
            triplets.push(Triplet::new(u as u32, u as u32, diag));
            coupling_offsets.push(coupling.len());
        }
        let (symbolic, values, matrix) = if m == 0 {
            (None, Vec::new(), None)
        } else {
            let a = SparseColMat::<u32, Real>::try_new_from_triplets(m, m, &triplets)
                .map_err(|e| factor_err(format!("{e:?}")))?;
            let symbolic = factorize_symbolic_cholesky(
                a.symbolic(),
                Side::Lower,
                Default::default(),
                Default::default(),
            )
            .map_err(|e| factor_err(format!("{e:?}")))?;
            let values = factorize(&symbolic, a.as_ref())?;
            (
                Some(Arc::new(symbolic)),
                values,
                Some(Arc::new(BaseMatrix::new(a))),
            )
        };
        let simplicial = symbolic.as_deref().and_then(SimplicialFactor::new);
        Ok(Self {
            unknown_of,
            vertex_of,
            symbolic,
            values,
            matrix,
            simplicial,
            coupling_offsets,
            coupling,
            handle_unknowns: Vec::new(),
            z: Vec::new(),
            schur: Vec::new(),
        })
    }

    /// The same system with `K + diag(extra)` (one non-negative entry per unknown; `K` is
    /// always this system's original matrix) factorised in place of `K`, on the same symbolic
    /// factor, and its handle columns recomputed: the global step of an energy with soft pulls
    /// on single vertices. Costs one numeric factorisation and one solve per handle.
    ///
    /// # Errors
    /// [`ArapError::Factorization`] when the numeric factorisation fails.
    pub(crate) fn with_diagonal(&self, extra: &[Real]) -> Result<Self, ArapError> {
        debug_assert_eq!(extra.len(), self.num_unknowns());
        let values = match (&self.symbolic, &self.matrix) {
            (Some(symbolic), Some(base)) => {
                let mut val = base.k.val().to_vec();
                for (&k, &add) in base.diagonal.iter().zip(extra) {
                    val[k] += add;
                }
                factorize(symbolic, SparseColMatRef::new(base.k.symbolic(), &val))?
            }
            _ => Vec::new(),
        };
        let mut out = Self {
            unknown_of: self.unknown_of.clone(),
            vertex_of: self.vertex_of.clone(),
            symbolic: self.symbolic.clone(),
            values,
            matrix: self.matrix.clone(),
            simplicial: self.simplicial.clone(),
            coupling_offsets: self.coupling_offsets.clone(),
            coupling: self.coupling.clone(),
            handle_unknowns: Vec::new(),
            z: Vec::new(),
            schur: Vec::new(),
        };
        out.set_handles(self.handle_unknowns.clone());
        Ok(out)
    }

    /// Number of unknowns.
    pub(crate) fn num_unknowns(&self) -> usize {
        self.vertex_of.len()
    }

    /// Number of handles.
    pub(crate) fn num_handles(&self) -> usize {
        self.handle_unknowns.len()
    }

    /// Scratch needed by [`ReducedSystem::solve_in_place`] for `ncols` right-hand sides.
    pub(crate) fn scratch(&self, ncols: usize) -> MemBuffer {
        match &self.symbolic {
            Some(s) => MemBuffer::new(s.solve_in_place_scratch::<Real>(ncols, Par::Seq)),
            None => MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
        }
    }

    /// `rhs ← K⁻¹ rhs`.
    pub(crate) fn solve_in_place(&self, rhs: MatMut<'_, Real>, buf: &mut MemBuffer) {
        if let Some(symbolic) = &self.symbolic {
            LltRef::new(symbolic.as_ref(), &self.values).solve_in_place_with_conj(
                Conj::No,
                rhs,
                Par::Seq,
                MemStack::new(buf),
            );
        }
    }

    /// `rhs ← K⁻¹ rhs` for three interleaved right-hand sides (x, y, z per unknown); `tmp` has one
    /// entry per unknown.
    pub(crate) fn solve3_in_place(
        &self,
        rhs: &mut [[Real; 3]],
        tmp: &mut [[Real; 3]],
        buf: &mut MemBuffer,
    ) {
        match &self.simplicial {
            Some(f) => f.solve3(&self.values, rhs, tmp),
            None => {
                // Supernodal factors (large meshes) go through faer's solver.
                let m = rhs.len();
                let mut mat = Mat::<Real>::from_fn(m, 3, |i, c| rhs[i][c]);
                self.solve_in_place(mat.as_mut(), buf);
                for (i, x) in rhs.iter_mut().enumerate() {
                    *x = [mat[(i, 0)], mat[(i, 1)], mat[(i, 2)]];
                }
            }
        }
    }

    /// Sets the handle unknowns and computes `Z` and `S` (one sparse solve per handle).
    pub(crate) fn set_handles(&mut self, handle_unknowns: Vec<u32>) {
        let m = self.num_unknowns();
        let h = handle_unknowns.len();
        let mut z = Mat::<Real>::zeros(m, h);
        for (j, &u) in handle_unknowns.iter().enumerate() {
            z[(u as usize, j)] = 1.0;
        }
        if h > 0 {
            let mut buf = self.scratch(h);
            self.solve_in_place(z.as_mut(), &mut buf);
        }
        let mut schur = vec![0.0; h * h];
        for (i, &u) in handle_unknowns.iter().enumerate() {
            for j in 0..h {
                schur[i * h + j] = z[(u as usize, j)];
            }
        }
        self.handle_unknowns = handle_unknowns;
        self.z = (0..m * h).map(|k| z[(k / h, k % h)]).collect();
        self.schur = schur;
    }

    /// Row `u` of `Z = K⁻¹ E_H`: entry `j` is `(K⁻¹)[u, h_j]`.
    pub(crate) fn z_row(&self, u: usize) -> &[Real] {
        let h = self.num_handles();
        &self.z[u * h..(u + 1) * h]
    }

    /// `S[i, j] = (K⁻¹)[h_i, h_j]`.
    pub(crate) fn schur(&self, i: usize, j: usize) -> Real {
        self.schur[i * self.num_handles() + j]
    }
}

fn factor_err(reason: String) -> ArapError {
    ArapError::Factorization { reason }
}

/// The numeric Cholesky factor of `a` (lower triangle) on `symbolic`.
fn factorize(
    symbolic: &SymbolicCholesky<u32>,
    a: SparseColMatRef<'_, u32, Real>,
) -> Result<Vec<Real>, ArapError> {
    let mut values = vec![0.0; symbolic.len_val()];
    let mut buf = MemBuffer::new(
        symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
    );
    symbolic
        .factorize_numeric_llt::<Real>(
            &mut values,
            a,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .map_err(|e| factor_err(format!("{e:?}")))?;
    Ok(values)
}

/// A simplicial Cholesky factor `P K Pᵀ = L Lᵀ` in compressed columns, diagonal first in every
/// column (faer's layout); the values stay in [`ReducedSystem`].
#[derive(Debug, Clone)]
struct SimplicialFactor {
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    /// `perm[i]`: the original index of permuted row `i`.
    perm: Vec<u32>,
}

impl SimplicialFactor {
    fn new(symbolic: &SymbolicCholesky<u32>) -> Option<Self> {
        let SymbolicCholeskyRaw::Simplicial(s) = symbolic.raw() else {
            return None;
        };
        let factor = s.factor();
        let n = symbolic.nrows();
        let perm = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n as u32).collect(),
        };
        Some(Self {
            col_ptr: factor.col_ptr().to_vec(),
            row_idx: factor.row_idx().to_vec(),
            perm,
        })
    }

    /// Forward and backward substitution with three right-hand sides at once.
    ///
    /// Two variants were measured on the 1k-vertex finger (930 unknowns, 20k factor entries)
    /// without gain: a supernodal forward pass (shared rows loaded once per run of columns) and
    /// two accumulators in the backward dot products.
    fn solve3(&self, values: &[Real], rhs: &mut [[Real; 3]], y: &mut [[Real; 3]]) {
        let n = self.perm.len();
        for (yi, &p) in y.iter_mut().zip(&self.perm) {
            *yi = rhs[p as usize];
        }
        // L z = y.
        for j in 0..n {
            let (start, end) = (self.col_ptr[j] as usize, self.col_ptr[j + 1] as usize);
            let d = 1.0 / values[start];
            let yj = [y[j][0] * d, y[j][1] * d, y[j][2] * d];
            y[j] = yj;
            for (&i, &l) in self.row_idx[start + 1..end]
                .iter()
                .zip(&values[start + 1..end])
            {
                let yi = &mut y[i as usize];
                yi[0] -= l * yj[0];
                yi[1] -= l * yj[1];
                yi[2] -= l * yj[2];
            }
        }
        // Lᵀ x = z.
        for j in (0..n).rev() {
            let (start, end) = (self.col_ptr[j] as usize, self.col_ptr[j + 1] as usize);
            let mut acc = y[j];
            for (&i, &l) in self.row_idx[start + 1..end]
                .iter()
                .zip(&values[start + 1..end])
            {
                let yi = y[i as usize];
                acc[0] -= l * yi[0];
                acc[1] -= l * yi[1];
                acc[2] -= l * yi[2];
            }
            let d = 1.0 / values[start];
            y[j] = [acc[0] * d, acc[1] * d, acc[2] * d];
        }
        for (yi, &p) in y.iter().zip(&self.perm) {
            rhs[p as usize] = *yi;
        }
    }
}

/// Every vertex must reach a fixed vertex through edges of positive system weight, otherwise `K`
/// is singular.
fn check_anchored(cells: &Cells, fixed_slot: &[Option<u32>]) -> Result<(), ArapError> {
    let n = cells.num_vertices();
    let mut reached: Vec<bool> = fixed_slot.iter().map(Option::is_some).collect();
    let mut stack: Vec<usize> = (0..n).filter(|&v| reached[v]).collect();
    while let Some(v) = stack.pop() {
        for (&w, &e) in cells.ring(v).iter().zip(cells.ring_edge_ids(v)) {
            if !reached[w as usize] && cells.matrix_weight(e as usize) > 0.0 {
                reached[w as usize] = true;
                stack.push(w as usize);
            }
        }
    }
    match reached.iter().position(|r| !r) {
        Some(vertex) => Err(ArapError::Unanchored { vertex }),
        None => Ok(()),
    }
}

/// A dense Cholesky factor of a small symmetric positive-definite matrix, reusing its storage.
#[derive(Debug, Clone, Default)]
pub(crate) struct SmallCholesky {
    n: usize,
    l: Vec<Real>,
}

impl SmallCholesky {
    /// Factorises the `n × n` matrix given by `entry(i, j)` (lower triangle read). Returns `false`
    /// when a pivot is not positive.
    pub(crate) fn factor(&mut self, n: usize, entry: impl Fn(usize, usize) -> Real) -> bool {
        self.n = n;
        self.l.clear();
        self.l.resize(n * n, 0.0);
        for j in 0..n {
            let mut d = entry(j, j);
            for k in 0..j {
                d -= self.l[j * n + k] * self.l[j * n + k];
            }
            if d.is_nan() || d <= 0.0 {
                return false;
            }
            let d = d.sqrt();
            self.l[j * n + j] = d;
            for i in (j + 1)..n {
                let mut s = entry(i, j);
                for k in 0..j {
                    s -= self.l[i * n + k] * self.l[j * n + k];
                }
                self.l[i * n + j] = s / d;
            }
        }
        true
    }

    /// Solves `M x = b` in place for one right-hand side of length `n`.
    pub(crate) fn solve_in_place(&self, b: &mut [Real]) {
        let n = self.n;
        for i in 0..n {
            let row = &self.l[i * n..i * n + i];
            let s = b[i] - row.iter().zip(&b[..i]).map(|(l, x)| l * x).sum::<Real>();
            b[i] = s / self.l[i * n + i];
        }
        for i in (0..n).rev() {
            let s = b[i]
                - ((i + 1)..n)
                    .zip(&b[i + 1..])
                    .map(|(k, x)| self.l[k * n + i] * x)
                    .sum::<Real>();
            b[i] = s / self.l[i * n + i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_cholesky_solves_a_known_system() {
        let m = [[4.0, 2.0, 0.4], [2.0, 5.0, 1.0], [0.4, 1.0, 3.0]];
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<Real> = (0..3)
            .map(|i| (0..3).map(|j| m[i][j] * x[j]).sum())
            .collect();
        let mut chol = SmallCholesky::default();
        assert!(chol.factor(3, |i, j| m[i][j]));
        chol.solve_in_place(&mut b);
        for (a, e) in b.iter().zip(x) {
            assert!((a - e).abs() < 1e-14);
        }
        assert!(!chol.factor(2, |i, j| if i == j { -1.0 } else { 0.0 }));
    }
}

#[cfg(test)]
mod solve_tests {
    use super::*;
    use crate::config::ArapEnergy;
    use crate::testmesh::{SplitMix64, jittered_sphere};
    use moe_geom::Topology;

    /// The three-column solve of every iteration agrees with faer's solver, for a small mesh
    /// (simplicial factor) and a large one (supernodal factor, through faer).
    #[test]
    fn three_column_solve_matches_faer() {
        for (rings, segments) in [(8, 12), (60, 120)] {
            let mesh = jittered_sphere(rings, segments, 0.05, 3);
            let topo = Topology::new(&mesh);
            let cells = Cells::new(&mesh, &topo, ArapEnergy::Smoothed);
            let mut fixed = vec![None; mesh.num_vertices()];
            fixed[0] = Some(0);
            fixed[5] = Some(1);
            let sys = ReducedSystem::new(&cells, &fixed).unwrap();
            let m = sys.num_unknowns();
            let mut rng = SplitMix64(9);
            let mut b: Vec<[Real; 3]> = (0..m)
                .map(|_| [rng.signed(), rng.signed(), rng.signed()])
                .collect();
            let mut reference = Mat::<Real>::from_fn(m, 3, |i, c| b[i][c]);
            let mut buf = sys.scratch(3);
            sys.solve_in_place(reference.as_mut(), &mut buf);
            let mut tmp = vec![[0.0; 3]; m];
            sys.solve3_in_place(&mut b, &mut tmp, &mut buf);
            let err = (0..m)
                .flat_map(|i| (0..3).map(move |c| (i, c)))
                .map(|(i, c)| (b[i][c] - reference[(i, c)]).abs())
                .fold(0.0, Real::max);
            assert!(err < 1e-10, "{rings}x{segments}: {err:e}");
        }
    }
}
