//! The SR-ARAP solver: local/global iterations on a factorised system.

use faer::dyn_stack::MemBuffer;
use moe_geom::math::is_finite_point;
use moe_geom::{Matrix3, Point3, Real, Topology, TriMesh, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cells::Cells;
use crate::config::ArapConfig;
use crate::error::ArapError;
use crate::newton::Rows;
use crate::rotation::{fit_rotations_from, orthonormalize, rows};
use crate::system::{FIXED, ReducedSystem, SmallCholesky};

/// Meshes with fewer vertices run the local step sequentially even when `parallel` is set. The
/// parallel local step (chunks of at least 256 vertices) costs 3–6 % more CPU time than the
/// sequential one for 1k–16k vertices (measured with `perf stat`), so it pays whenever a second
/// core is free; below about a thousand vertices the fork-join latency is no longer small against
/// an iteration.
const PARALLEL_MIN_VERTICES: usize = 1024;

/// Cells whose rotations are fitted together in the local step (see `newton.rs`).
const LANES: usize = 2;

/// Where the iterations start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start<'a> {
    /// The rest mesh (the paper's setting; handles are not pre-placed).
    Rest,
    /// Given positions, one per vertex (a warm start).
    Positions(&'a [Point3]),
    /// Whatever the workspace holds: the result of its previous solve, or the rest mesh for a
    /// fresh workspace. The allocation-free warm start for tracking.
    Previous,
}

/// What a solve did, beside its result.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ArapInfo {
    /// Local/global iterations run.
    pub iterations: usize,
    /// `energy[t]`: the energy `E(p′⁽ᵗ⁺¹⁾, R⁽ᵗ⁾)` after the global step of iteration `t` (squared
    /// mesh units). With `alpha = 0` it never increases. Evaluated through expanded squares
    /// (the tests check it against the direct form), so it carries a rounding error of about
    /// 1e-16 of `Σ w (‖e‖² + ‖e′‖²)`.
    pub energy: Vec<Real>,
    /// Vertex ids of the switchable handles that were constrained in this solve, in handle order.
    pub handles_used: Vec<u32>,
    /// Local-step rotations computed by the SVD route rather than the polar iteration (flat or
    /// inverted cells), summed over iterations.
    pub svd_fallbacks: usize,
}

/// The solution of one solve.
#[derive(Debug, Clone, PartialEq)]
pub struct ArapSolution {
    /// Deformed vertex positions, one per rest vertex.
    pub vertices: Vec<Point3>,
    /// Iterations, energies and handles used.
    pub info: ArapInfo,
}

/// Preallocated buffers of a solver; reusing one makes the per-frame path allocation-free.
pub(crate) struct ArapWorkspace {
    deformed: Vec<Point3>,
    rot: Vec<Matrix3>,
    rot_prev: Vec<Matrix3>,
    edge_rhs: Vec<Vector3>,
    fixed_rhs: Vec<Vector3>,
    rhs: Vec<[Real; 3]>,
    solve_tmp: Vec<[Real; 3]>,
    buf: MemBuffer,
    active: Vec<usize>,
    active_targets: Vec<Point3>,
    chol: SmallCholesky,
    lambda: Vec<Real>,
    /// Per vertex, the soft rows' pull `Σ μ y` of the current global step.
    surface_rhs: Vec<Vector3>,
}

impl std::fmt::Debug for ArapWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArapWorkspace")
            .field("vertices", &self.deformed.len())
            .field("active_handles", &self.active)
            .finish_non_exhaustive()
    }
}

impl ArapWorkspace {
    /// The positions of the last solve (the rest mesh before the first).
    pub(crate) fn vertices(&self) -> &[Point3] {
        &self.deformed
    }

    /// The rotations of the last iteration's local step, one per vertex.
    #[cfg(test)]
    pub(crate) fn rotations(&self) -> &[Matrix3] {
        &self.rot_prev
    }
}

/// A soft pull of the surface towards a plane: the mesh predicts `Σ a_v · x_v` over `terms`,
/// an observation says `value`, and the energy gains `weight · (Σ a_v · x_v − value)²` (a
/// depth patch's point-to-plane distance, [`moe_geom::depth::PooledPatch`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SurfaceRow {
    /// `(vertex, a_v)`.
    pub(crate) terms: Vec<(u32, Vector3)>,
    /// What the observation says, metres.
    pub(crate) value: Real,
    /// Weight of the squared residual, per square metre of residual.
    pub(crate) weight: Real,
}

impl SurfaceRow {
    /// `Σ a_v · x_v − value` at `x`.
    fn residual(&self, x: &[Point3]) -> Real {
        self.terms
            .iter()
            .map(|&(v, a)| a.dot(&x[v as usize].coords))
            .sum::<Real>()
            - self.value
    }

    fn norm_sq(&self) -> Real {
        self.terms.iter().map(|(_, a)| a.norm_squared()).sum()
    }
}

/// Soft rows and the global-step system that holds them.
///
/// A row's energy `w (aᵀx − c)²` is split as in projective dynamics: with `μ = w ‖a‖²` it is
/// the minimum over `y` on the plane `aᵀy = c` of `μ Σ_v ‖x_v − y_v‖²`. The local step
/// projects the current positions onto every row's plane (`y = x − a (aᵀx − c)/‖a‖²`), the
/// global step solves `(K + diag(Σ μ/2)) x = b + Σ (μ/2) y`: the global-step system `K x = b`
/// is the stationarity of a quarter of the ARAP energy (`½ xᵀK x − bᵀx = E/4 + const`), so
/// the rows enter at half their weight. Both steps are exact block minimisers of the whole
/// energy, so with `α = 0` it still never increases. The matrix is factorised once per set of
/// rows.
#[derive(Debug)]
pub(crate) struct SurfaceTerms {
    rows: Vec<SurfaceRow>,
    /// Per row, `‖a‖²`.
    norm_sq: Vec<Real>,
    system: ReducedSystem,
}

impl SurfaceTerms {
    /// The rows' energy `Σ w (aᵀx − c)²` at `x`.
    fn energy(&self, x: &[Point3]) -> Real {
        self.rows
            .iter()
            .map(|row| {
                let r = row.residual(x);
                row.weight * r * r
            })
            .sum()
    }

    /// Accumulates `Σ (μ/2) y` per vertex of the rows' planes' projections of `x` into `out`.
    fn pull(&self, x: &[Point3], out: &mut [Vector3]) {
        out.fill(Vector3::zeros());
        for (row, &norm_sq) in self.rows.iter().zip(&self.norm_sq) {
            if norm_sq <= 0.0 {
                continue;
            }
            let step = row.residual(x) / norm_sq;
            let half_mu = 0.5 * row.weight * norm_sq;
            for &(v, a) in &row.terms {
                out[v as usize] += (x[v as usize].coords - a * step) * half_mu;
            }
        }
    }
}

/// The SR-ARAP solver of one connected part (or one factorised system) and one constraint
/// structure: `fixed` vertices (always
/// constrained, eliminated from the factorised system) and switchable `handles` (constrained in a
/// solve when a target is given, through a small Schur complement; see the crate documentation).
#[derive(Debug)]
pub(crate) struct PartSolver {
    config: ArapConfig,
    rest: Vec<Point3>,
    cells: Cells,
    system: ReducedSystem,
    fixed: Vec<u32>,
    handles: Vec<u32>,
    surface_area: Real,
    /// `α A / |N(i)|` per vertex (zero when smoothing is off).
    smoothing: Vec<Real>,
}

impl PartSolver {
    /// Builds the cells and factorises the system for `mesh` with the given fixed vertices and
    /// switchable handles.
    ///
    /// # Errors
    /// An invalid config, an out-of-range or repeated vertex id, or a part of the mesh connected to
    /// no fixed vertex ([`ArapError::Unanchored`]).
    pub(crate) fn new(
        mesh: &TriMesh,
        config: &ArapConfig,
        fixed: &[u32],
        handles: &[u32],
    ) -> Result<Self, ArapError> {
        config.validate()?;
        let n = mesh.num_vertices();
        let mut fixed_slot: Vec<Option<u32>> = vec![None; n];
        for (slot, &v) in fixed.iter().enumerate() {
            let v = check_id("fixed", v, n)?;
            if fixed_slot[v].replace(slot as u32).is_some() {
                return Err(ArapError::DuplicateVertex {
                    what: "fixed",
                    vertex: v,
                });
            }
        }
        let topology = Topology::new(mesh);
        let cells = Cells::new(mesh, &topology, config.energy);
        let system = ReducedSystem::new(&cells, &fixed_slot)?;
        let surface_area = mesh.surface_area();
        let alpha = config.effective_alpha();
        let smoothing = (0..n)
            .map(|v| {
                let valence = cells.ring(v).len().max(1) as Real;
                alpha * surface_area / valence
            })
            .collect();
        let mut solver = Self {
            config: config.clone(),
            rest: mesh.vertices().to_vec(),
            cells,
            system,
            fixed: fixed.to_vec(),
            handles: Vec::new(),
            surface_area,
            smoothing,
        };
        solver.set_handles(handles)?;
        Ok(solver)
    }

    /// Replaces the switchable handles. Costs one sparse solve per handle; the factorisation is
    /// kept.
    ///
    /// # Errors
    /// An out-of-range id, a repeated id, or a handle that is also fixed.
    pub(crate) fn set_handles(&mut self, handles: &[u32]) -> Result<(), ArapError> {
        let n = self.rest.len();
        let mut unknowns = Vec::with_capacity(handles.len());
        let mut seen = std::collections::HashSet::with_capacity(handles.len());
        for &v in handles {
            let vi = check_id("handle", v, n)?;
            let u = self.system.unknown_of[vi];
            if u == FIXED || !seen.insert(v) {
                return Err(ArapError::DuplicateVertex {
                    what: "handle",
                    vertex: vi,
                });
            }
            unknowns.push(u);
        }
        self.system.set_handles(unknowns);
        self.handles = handles.to_vec();
        Ok(())
    }

    /// Soft `rows` on this solver's mesh, with the global-step matrix that holds them
    /// factorised (on the same symbolic factor, for the current handles).
    ///
    /// # Errors
    /// A row naming a vertex outside the mesh, a weight, value or term that is not finite, a
    /// negative weight, or a failed factorisation.
    pub(crate) fn surface_terms(&self, rows: Vec<SurfaceRow>) -> Result<SurfaceTerms, ArapError> {
        let n = self.rest.len();
        let mut extra = vec![0.0; self.system.num_unknowns()];
        let mut norm_sq = Vec::with_capacity(rows.len());
        for (index, row) in rows.iter().enumerate() {
            let finite = row.value.is_finite()
                && row.weight.is_finite()
                && row
                    .terms
                    .iter()
                    .all(|(_, a)| a.iter().all(|c| c.is_finite()));
            if !finite {
                return Err(ArapError::NonFiniteTarget {
                    what: "surface row",
                    index,
                });
            }
            if row.weight < 0.0 {
                return Err(ArapError::InvalidConfig {
                    name: "surface row weight",
                    value: row.weight,
                    reason: "must be non-negative",
                });
            }
            let q = row.norm_sq();
            for &(v, _) in &row.terms {
                let v = check_id("surface row vertex", v, n)?;
                let u = self.system.unknown_of[v];
                if u != FIXED {
                    extra[u as usize] += 0.5 * row.weight * q;
                }
            }
            norm_sq.push(q);
        }
        Ok(SurfaceTerms {
            system: self.system.with_diagonal(&extra)?,
            rows,
            norm_sq,
        })
    }

    /// Rest vertex positions.
    pub(crate) fn rest_vertices(&self) -> &[Point3] {
        &self.rest
    }

    /// Rest surface area `A` (squared mesh units).
    pub(crate) fn surface_area(&self) -> Real {
        self.surface_area
    }

    /// Buffers for [`PartSolver::solve_in`], holding the rest mesh.
    pub(crate) fn workspace(&self) -> ArapWorkspace {
        let n = self.rest.len();
        let h = self.system.num_handles();
        ArapWorkspace {
            deformed: self.rest.clone(),
            rot: vec![Matrix3::identity(); n],
            rot_prev: vec![Matrix3::identity(); n],
            edge_rhs: vec![Vector3::zeros(); self.cells.edges.len()],
            fixed_rhs: vec![Vector3::zeros(); self.system.num_unknowns()],
            rhs: vec![[0.0; 3]; self.system.num_unknowns()],
            solve_tmp: vec![[0.0; 3]; self.system.num_unknowns()],
            buf: self.system.scratch(3),
            active: Vec::with_capacity(h),
            active_targets: Vec::with_capacity(h),
            chol: SmallCholesky::default(),
            lambda: Vec::with_capacity(3 * h),
            surface_rhs: vec![Vector3::zeros(); n],
        }
    }

    /// Solves with a fresh workspace and returns owned results.
    ///
    /// `fixed_targets[k]` is the target of `fixed()[k]`; `handle_targets[k]` that of
    /// `handles()[k]`, `None` when the handle is free in this solve.
    ///
    /// # Errors
    /// See [`PartSolver::solve_in`].
    pub(crate) fn solve(
        &self,
        fixed_targets: &[Point3],
        handle_targets: &[Option<Point3>],
        start: Start<'_>,
    ) -> Result<ArapSolution, ArapError> {
        let mut ws = self.workspace();
        let mut info = ArapInfo::default();
        self.solve_in(&mut ws, fixed_targets, handle_targets, start, &mut info)?;
        Ok(ArapSolution {
            vertices: ws.deformed,
            info,
        })
    }

    /// Runs the configuration's `iterations` local/global iterations in `ws`; the result is
    /// [`ArapWorkspace::vertices`]. Does not allocate once `ws` and `info` have been used.
    ///
    /// # Errors
    /// Wrong target or start counts, non-finite targets or start positions.
    pub(crate) fn solve_in(
        &self,
        ws: &mut ArapWorkspace,
        fixed_targets: &[Point3],
        handle_targets: &[Option<Point3>],
        start: Start<'_>,
        info: &mut ArapInfo,
    ) -> Result<(), ArapError> {
        self.solve_in_with(ws, fixed_targets, handle_targets, start, info, None)
    }

    /// As [`PartSolver::solve_in`], with the soft rows of `surface` (made by this solver's
    /// [`PartSolver::surface_terms`] for its current handles) in the energy.
    ///
    /// # Errors
    /// As [`PartSolver::solve_in`].
    pub(crate) fn solve_in_with(
        &self,
        ws: &mut ArapWorkspace,
        fixed_targets: &[Point3],
        handle_targets: &[Option<Point3>],
        start: Start<'_>,
        info: &mut ArapInfo,
        surface: Option<&SurfaceTerms>,
    ) -> Result<(), ArapError> {
        check_inputs(
            [self.rest.len(), self.fixed.len(), self.handles.len()],
            fixed_targets,
            handle_targets,
            start,
        )?;
        info.iterations = 0;
        info.energy.clear();
        info.handles_used.clear();
        info.svd_fallbacks = 0;
        match start {
            Start::Rest => {
                // The rest mesh's best rotations are the identity: the local step's warm start,
                // which also makes a solve from rest independent of the workspace's history.
                ws.deformed.copy_from_slice(&self.rest);
                ws.rot_prev.fill(Matrix3::identity());
            }
            Start::Positions(p) => {
                ws.deformed.copy_from_slice(p);
                ws.rot_prev.iter_mut().for_each(|r| *r = orthonormalize(r));
            }
            Start::Previous => ws.rot_prev.iter_mut().for_each(|r| *r = orthonormalize(r)),
        }
        let sys = surface.map_or(&self.system, |s| &s.system);
        debug_assert_eq!(
            sys.handle_unknowns, self.system.handle_unknowns,
            "surface terms made for other handles"
        );
        self.prepare_frame(sys, ws, fixed_targets, handle_targets, info);
        let surface_energy = |x: &[Point3]| surface.map_or(0.0, |s| s.energy(x));
        let iterations = self.config.iterations;
        for t in 0..iterations {
            let (energy, fallbacks) = self.local_step(ws, t > 0);
            if t > 0 {
                info.energy.push(energy + surface_energy(&ws.deformed));
            }
            info.svd_fallbacks += fallbacks;
            std::mem::swap(&mut ws.rot, &mut ws.rot_prev);
            self.global_step(sys, ws, fixed_targets, surface);
            info.iterations += 1;
        }
        if iterations > 0 {
            info.energy.push(
                self.energy_expanded(&ws.deformed, &ws.rot_prev) + surface_energy(&ws.deformed),
            );
        } else {
            self.place_constraints(ws, fixed_targets);
        }
        Ok(())
    }

    /// The energy `E(p′, R)` of positions `deformed` with per-vertex rotations `rotations`:
    /// `Σ_i Σ_{e∈cell(i)} w_e ‖e′ − R_i e‖² + Σ_i (αA/|N(i)|) Σ_{j∈N(i)} ‖R_i − R_j‖²_F`.
    ///
    /// # Panics
    /// If the slices do not have one entry per vertex (a programming error).
    #[cfg(test)]
    pub(crate) fn energy(&self, deformed: &[Point3], rotations: &[Matrix3]) -> Real {
        assert_eq!(deformed.len(), self.rest.len());
        assert_eq!(rotations.len(), self.rest.len());
        (0..self.rest.len())
            .map(|i| self.vertex_energy(i, deformed, rotations))
            .sum()
    }

    #[cfg(test)]
    fn vertex_energy(&self, i: usize, deformed: &[Point3], rotations: &[Matrix3]) -> Real {
        let r = &rotations[i];
        let mut e = self.cells.cell_energy(i, deformed, r);
        let s = self.smoothing[i];
        if s > 0.0 {
            let sum: Real = self
                .cells
                .ring(i)
                .iter()
                .map(|&j| (r - rotations[j as usize]).norm_squared())
                .sum();
            e += s * sum;
        }
        e
    }

    /// Per-solve set-up: fixed-vertex contributions to the right-hand side, the active handles and
    /// the factor of their Schur block.
    fn prepare_frame(
        &self,
        sys: &ReducedSystem,
        ws: &mut ArapWorkspace,
        fixed_targets: &[Point3],
        handle_targets: &[Option<Point3>],
        info: &mut ArapInfo,
    ) {
        for (u, acc) in ws.fixed_rhs.iter_mut().enumerate() {
            *acc = sys.coupling[sys.coupling_offsets[u]..sys.coupling_offsets[u + 1]]
                .iter()
                .map(|&(slot, w)| fixed_targets[slot as usize].coords * w)
                .sum();
        }
        ws.active.clear();
        ws.active_targets.clear();
        for (k, t) in handle_targets.iter().enumerate() {
            if let Some(t) = t {
                ws.active.push(k);
                ws.active_targets.push(*t);
                info.handles_used.push(self.handles[k]);
            }
        }
        let active = &ws.active;
        // S is a principal block of K⁻¹ (SPD), so this factorisation succeeds for distinct handles.
        let ok = ws
            .chol
            .factor(active.len(), |i, j| sys.schur(active[i], active[j]));
        debug_assert!(ok, "Schur block of distinct handles is positive definite");
    }

    /// Fits every rotation (into `ws.rot`) and returns the energy of the current positions with
    /// the previous rotations (when `smooth_and_measure`) and the number of SVD fallbacks.
    fn local_step(&self, ws: &mut ArapWorkspace, previous_valid: bool) -> (Real, usize) {
        let deformed = &ws.deformed;
        let rot_prev = &ws.rot_prev;
        // The matrix whose best rotation is wanted, and the cell's energy with the previous one.
        let target = |i: usize| -> (Rows, Real) {
            let (mut s, deformed_sq) = self.cell_covariance(i, deformed);
            let coeff = self.smoothing[i];
            let mut energy = 0.0;
            if previous_valid {
                let r_prev = &rot_prev[i];
                // A sum of squares: clamp the rounding of the expansion at zero.
                energy = (self.cells.rest_energy[i] + deformed_sq
                    - 2.0 * r_prev.transpose().dot(&s))
                .max(0.0);
                if coeff > 0.0 {
                    let ring = self.cells.ring(i);
                    let mut sum = ring
                        .first()
                        .map_or_else(Matrix3::zeros, |&j| rot_prev[j as usize]);
                    for &j in ring.iter().skip(1) {
                        sum += rot_prev[j as usize];
                    }
                    energy += smoothing_energy(coeff, ring.len(), r_prev, &sum);
                    s = s * 2.0 + sum.transpose() * (4.0 * coeff);
                }
            }
            (rows(&s), energy)
        };
        // Rotations are fitted `LANES` cells at a time (see `newton.rs`): `out` holds the
        // rotations of cells `first..first + out.len()`; returns their energies and SVD fallbacks.
        let work = |first: usize, out: &mut [Matrix3]| -> ([Real; LANES], usize) {
            let mut energies = [0.0; LANES];
            let mut fallbacks = 0;
            if out.len() == LANES {
                let mut s = [[[0.0; 3]; 3]; LANES];
                for (k, (sk, ek)) in s.iter_mut().zip(&mut energies).enumerate() {
                    (*sk, *ek) = target(first + k);
                }
                let warm = std::array::from_fn(|k| rows(&rot_prev[first + k]));
                let fits = fit_rotations_from::<LANES>(&s, &warm);
                for (r, (fit, fallback)) in out.iter_mut().zip(fits) {
                    *r = fit;
                    fallbacks += usize::from(fallback);
                }
            } else {
                for (k, r) in out.iter_mut().enumerate() {
                    let (s, e) = target(first + k);
                    let [(fit, fallback)] =
                        fit_rotations_from::<1>(&[s], &[rows(&rot_prev[first + k])]);
                    *r = fit;
                    energies[k] = e;
                    fallbacks += usize::from(fallback);
                }
            }
            (energies, fallbacks)
        };
        if self.config.parallel && self.rest.len() >= PARALLEL_MIN_VERTICES {
            ws.rot
                .par_chunks_mut(LANES)
                .enumerate()
                .with_min_len(256 / LANES)
                .map(|(c, out)| {
                    let (e, f) = work(LANES * c, out);
                    (e.iter().sum::<Real>(), f)
                })
                .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        } else {
            ws.rot
                .chunks_mut(LANES)
                .enumerate()
                .fold((0.0, 0), |acc, (c, out)| {
                    let (e, f) = work(LANES * c, out);
                    (e.iter().fold(acc.0, |a, e| a + e), acc.1 + f)
                })
        }
    }

    /// `S_i = Σ_{e∈cell(i)} w_e e e′ᵀ` and `Σ w_e ‖e′‖²` for the current positions.
    #[inline(always)]
    fn cell_covariance(&self, i: usize, deformed: &[Point3]) -> (Matrix3, Real) {
        let mut s = Matrix3::zeros();
        let mut sq = 0.0;
        for c in self.cells.cell(i) {
            let d = deformed[c.a as usize] - deformed[c.b as usize];
            s += c.weighted_rest * d.transpose();
            sq += c.weight * d.norm_squared();
        }
        (s, sq)
    }

    /// Energy of `deformed` with `rotations` evaluated as the iterations do, through
    /// `Σ w‖e′ − R e‖² = Σ w‖e‖² + Σ w‖e′‖² − 2 tr(R S)` and
    /// `Σ_j ‖R_i − R_j‖² = 6|N(i)| − 2 tr(R_iᵀ Σ_j R_j)`.
    fn energy_expanded(&self, deformed: &[Point3], rotations: &[Matrix3]) -> Real {
        (0..self.rest.len())
            .map(|i| {
                let (s, sq) = self.cell_covariance(i, deformed);
                let r = &rotations[i];
                let mut e = (self.cells.rest_energy[i] + sq - 2.0 * r.transpose().dot(&s)).max(0.0);
                let coeff = self.smoothing[i];
                if coeff > 0.0 {
                    let mut sum = Matrix3::zeros();
                    for &j in self.cells.ring(i) {
                        sum += rotations[j as usize];
                    }
                    e += smoothing_energy(coeff, self.cells.ring(i).len(), r, &sum);
                }
                e
            })
            .sum()
    }

    /// Right-hand side from the rotations in `ws.rot_prev` (the ones just fitted), sparse solve,
    /// handle correction, and write-back of the new positions.
    fn global_step(
        &self,
        sys: &ReducedSystem,
        ws: &mut ArapWorkspace,
        fixed_targets: &[Point3],
        surface: Option<&SurfaceTerms>,
    ) {
        let cells = &self.cells;
        if let Some(surface) = surface {
            surface.pull(&ws.deformed, &mut ws.surface_rhs);
        }
        let rot = &ws.rot_prev;
        if cells.edge_cells.len() == 2 * cells.edges.len() {
            // Spokes: the cells of edge `[a, b]` are exactly `a` and `b`.
            for (((out, &[a, b]), rest), &w) in ws
                .edge_rhs
                .iter_mut()
                .zip(&cells.edges)
                .zip(&cells.rest_edges)
                .zip(&cells.weights)
            {
                *out = (rot[a as usize] + rot[b as usize]) * rest * (0.5 * w);
            }
        } else {
            for (e, out) in ws.edge_rhs.iter_mut().enumerate() {
                let mut sum = Matrix3::zeros();
                for &i in cells.cells_of_edge(e) {
                    sum += rot[i as usize];
                }
                *out = sum * cells.rest_edges[e] * (0.5 * cells.weights[e]);
            }
        }
        for (u, &v) in sys.vertex_of.iter().enumerate() {
            let mut b = ws.fixed_rhs[u];
            let v = v as usize;
            if surface.is_some() {
                b += ws.surface_rhs[v];
            }
            for (&e, &sign) in cells.ring_edge_ids(v).iter().zip(cells.ring_edge_signs(v)) {
                // `b + (−1)·r` is `b − r` exactly.
                b += ws.edge_rhs[e as usize] * sign;
            }
            ws.rhs[u] = [b.x, b.y, b.z];
        }
        sys.solve3_in_place(&mut ws.rhs, &mut ws.solve_tmp, &mut ws.buf);
        let na = ws.active.len();
        ws.lambda.clear();
        ws.lambda.resize(3 * na, 0.0);
        for c in 0..3 {
            let lam = &mut ws.lambda[c * na..(c + 1) * na];
            for (k, &a) in ws.active.iter().enumerate() {
                let u = sys.handle_unknowns[a] as usize;
                lam[k] = ws.rhs[u][c] - ws.active_targets[k][c];
            }
            if na > 0 {
                ws.chol.solve_in_place(lam);
            }
        }
        // Handle correction `x ← x − Z λ` fused with the write-back, one pass over the unknowns.
        let (lx, rest) = ws.lambda.split_at(na);
        let (ly, lz) = rest.split_at(na);
        for (u, &v) in sys.vertex_of.iter().enumerate() {
            let mut x = ws.rhs[u];
            let z = sys.z_row(u);
            for (k, &a) in ws.active.iter().enumerate() {
                let zk = z[a];
                x[0] -= zk * lx[k];
                x[1] -= zk * ly[k];
                x[2] -= zk * lz[k];
            }
            ws.deformed[v as usize] = Point3::new(x[0], x[1], x[2]);
        }
        self.place_constraints(ws, fixed_targets);
    }

    /// Puts fixed vertices and active handles exactly on their targets.
    fn place_constraints(&self, ws: &mut ArapWorkspace, fixed_targets: &[Point3]) {
        for (&v, t) in self.fixed.iter().zip(fixed_targets) {
            ws.deformed[v as usize] = *t;
        }
        for (&a, t) in ws.active.iter().zip(&ws.active_targets) {
            ws.deformed[self.handles[a] as usize] = *t;
        }
    }
}

/// `coeff · Σ_j ‖R_i − R_j‖²_F` from `Σ_j R_j`, for rotations.
fn smoothing_energy(coeff: Real, valence: usize, r: &Matrix3, sum: &Matrix3) -> Real {
    (coeff * (6.0 * valence as Real - 2.0 * r.dot(sum))).max(0.0)
}

/// Checks a solve's inputs against `[vertices, fixed, handles]` counts: one target per fixed
/// vertex and per handle, one start position per vertex, every coordinate finite.
pub(crate) fn check_inputs(
    [num_vertices, num_fixed, num_handles]: [usize; 3],
    fixed_targets: &[Point3],
    handle_targets: &[Option<Point3>],
    start: Start<'_>,
) -> Result<(), ArapError> {
    let count = |what, expected, got| {
        if expected == got {
            Ok(())
        } else {
            Err(ArapError::LengthMismatch {
                what,
                expected,
                got,
            })
        }
    };
    count("fixed targets", num_fixed, fixed_targets.len())?;
    count("handle targets", num_handles, handle_targets.len())?;
    if let Some(index) = fixed_targets.iter().position(|p| !is_finite_point(p)) {
        return Err(ArapError::NonFiniteTarget {
            what: "fixed target",
            index,
        });
    }
    if let Some(index) = handle_targets
        .iter()
        .position(|p| p.is_some_and(|p| !is_finite_point(&p)))
    {
        return Err(ArapError::NonFiniteTarget {
            what: "handle target",
            index,
        });
    }
    if let Start::Positions(p) = start {
        count("start positions", num_vertices, p.len())?;
        if let Some(index) = p.iter().position(|p| !is_finite_point(p)) {
            return Err(ArapError::NonFiniteTarget {
                what: "start position",
                index,
            });
        }
    }
    Ok(())
}

pub(crate) fn check_id(what: &'static str, v: u32, len: usize) -> Result<usize, ArapError> {
    let v = v as usize;
    if v < len {
        Ok(v)
    } else {
        Err(ArapError::VertexOutOfRange {
            what,
            index: v,
            len,
        })
    }
}

#[cfg(test)]
mod tests;
