//! Smoothed as-rigid-as-possible (SR-ARAP) shape estimation of soft fingers from tracked keypoints
//! (paper §4.2, App. B, App. C).
//!
//! # Example
//!
//! A hand's fingers from their markers ([`MultiShapeEstimator`]), or any mesh pulled by handles
//! ([`ArapSolver`]; `cargo run -p moe-arap --example deform` runs a longer version):
//!
//! ```
//! use moe_arap::{ArapConfig, ArapSolver, Start};
//! use moe_geom::{Point3, Vector3, shapes::icosphere};
//!
//! let mesh = icosphere(2, 0.01); // any closed or open mesh, metres
//! let lowest = |a: &&Point3, b: &&Point3| a.z.total_cmp(&b.z);
//! let bottom = mesh.vertices().iter().min_by(lowest).unwrap().z;
//! let base: Vec<u32> = (0..mesh.num_vertices() as u32)
//!     .filter(|&v| mesh.vertices()[v as usize].z < bottom + 0.003)
//!     .collect();
//! let top = (0..mesh.num_vertices() as u32)
//!     .max_by(|&a, &b| mesh.vertices()[a as usize].z.total_cmp(&mesh.vertices()[b as usize].z))
//!     .unwrap();
//! // Factorise once for these fixed vertices and this handle; then solve for any targets.
//! let solver = ArapSolver::new(&mesh, &ArapConfig::default(), &base, &[top])?;
//! let fixed: Vec<Point3> = base.iter().map(|&v| mesh.vertices()[v as usize]).collect();
//! let target = mesh.vertices()[top as usize] + Vector3::new(0.004, 0.0, 0.0);
//! let bent = solver.solve(&fixed, &[Some(target)], Start::Rest)?;
//! assert!((bent.vertices[top as usize] - target).norm() < 1e-9);
//! # Ok::<(), moe_arap::ArapError>(())
//! ```
//!
//! # The energy
//!
//! For a rest mesh with vertices `p_i` and a deformed copy `p′_i`, every vertex `i` owns a cell of
//! edges `e = (a, b)` (its one-ring spokes by default; spokes and rims as an option) and a rotation
//! `R_i`. With cotangent weights `w_e` (mean cotangent of the angles opposite the edge, clamped at
//! 0, on the rest mesh), rest surface area `A`, one-ring `N(i)` and smoothing weight `α`:
//!
//! ```text
//! E(p′, R) = Σ_i Σ_{e∈cell(i)} w_e ‖(p′_a − p′_b) − R_i (p_a − p_b)‖²
//!          + Σ_i (α A / |N(i)|) Σ_{j∈N(i)} ‖R_i − R_j‖²_F
//! ```
//!
//! minimised over `p′` with fixed and handle vertices on their targets. `α = 0` is plain ARAP
//! (Sorkine & Alexa); `α > 0` is SR-ARAP (Levi & Gotsman), which penalises rotation changes
//! between neighbours and gives smooth bends. The default convention is docs/design.md's, i.e. that of
//! Open3D's "Smoothed" ARAP used by the paper's authors:
//!
//! * the deformed mesh starts as the rest mesh (handles are not pre-placed);
//! * local step at iteration `t`: `S_i = Σ_j w_ij (p_i − p_j)(p′_i − p′_j)ᵀ`; with smoothing on and
//!   `t > 0`, `S_i ← 2 S_i + (4αA/|N(i)|)(Σ_{j∈N(i)} R_j⁽ᵗ⁻¹⁾)ᵀ` (Jacobi: the previous iteration's
//!   rotations); `R_i = V diag(1, 1, det(VUᵀ)) Uᵀ` for `S_i = UΣVᵀ`. This maximises
//!   `tr(R_i S_i)`, i.e. minimises cell `i`'s data term plus `(2αA/|N(i)|) Σ_j ‖R_i − R_j⁽ᵗ⁻¹⁾‖²`,
//!   which is the exact block minimiser of `E` for regular valence;
//! * global step: `Σ_j w_ij (p′_i − p′_j) = Σ_j (w_ij/2)(R_i + R_j)(p_i − p_j)` for every free
//!   vertex, fixed and handle vertices equal their targets. For spokes and rims the weights become
//!   `c_e w_e / 2` and the rotation sum runs over the `c_e` cells containing the edge
//!   (`cells.rs`).
//!
//! With `α = 0` both steps are exact block minimisers, so `E(p′⁽ᵗ⁺¹⁾, R⁽ᵗ⁾)` never increases
//! once the constraints are met (from the first solved iteration on); [`ArapInfo::energy`] records
//! it every iteration.
//!
//! # Factorise once, solve many
//!
//! The global-step matrix depends only on the rest mesh and on which vertices are fixed, so it is
//! factorised once with faer's sparse Cholesky (symbolic and numeric) when the solver is built.
//! Markers come and go with occlusion; rather than refactorising per visibility pattern (or caching
//! up to 2⁷ factors per finger), handle vertices stay unknowns of the factorised system and a
//! frame's visible handles are imposed with Lagrange multipliers through a dense Schur complement
//! of at most one row per marker (`system.rs`): `K⁻¹E_H` is precomputed with one
//! solve per handle, and a frame only factorises the ≤ 7 × 7 block of its visible markers. Each
//! iteration then costs the local step, a right-hand side, one 3-column triangular solve pair and
//! an `O(n·h)` correction. The per-finger solves of [`MultiShapeEstimator`] allocate nothing
//! once warm (each finger keeps its workspace); registration to a depth image allocates in each
//! pass (the association, the patches and the refactorised system), and [`ArapSolver::solve`]
//! allocates its result.
//!
//! # Rotations
//!
//! The maximiser of `tr(R S_i)` is found by Newton's method on SO(3) warm-started from the
//! previous iteration's `R_i` (one to three steps of a few dozen flops, quadratic convergence,
//! stopped when the step is below 1e-6 rad, i.e. at ~1e-12 of the exact rotation), two cells in
//! lockstep so that their dependent chains interleave (`newton.rs`; bit-identical to one at a
//! time). Cells where
//! that does not apply fall back to the orthogonal polar factor of `S_iᵀ` by scaled Newton
//! iteration (equal to the SVD formula when `det S_i > 0`) and then to the SVD formula itself
//! (flat or inverted cells, counted in [`ArapInfo::svd_fallbacks`]). A solve from rest resets the
//! warm start to the identity, so its result does not depend on earlier solves.
//!
//! # Registration to a depth image
//!
//! With [`ShapeConfig::depth`] enabled, [`MultiShapeEstimator::estimate_with`] also reads the
//! wrist camera's depth image: after the markers-only solve, the pixels each finger's estimate
//! predicts are pooled over patches of its surface, and every patch adds a soft point-to-plane
//! term `w (aᵀp′ − c)²` to the energy (the markers stay hard handles). The term is split as in
//! projective dynamics: the local step also projects the positions onto each patch's plane, the
//! global step solves `K + diag(w‖a‖²/2)` (one numeric refactorisation per pass, on the same
//! symbolic factor, and one solve per handle), so both steps stay exact block minimisers. See
//! [`ShapeDepth`] for the weights, gates and passes.
//!
//! # Parallelism
//!
//! [`MultiShapeEstimator`] solves the fingers in parallel on the rayon pool, one finger per task,
//! with sequential local steps inside. A single large mesh ([`ArapSolver`] with
//! `ArapConfig::parallel`) runs its local step on the pool from 1024 vertices up (measured CPU
//! overhead 3–6 %).
//!
//! Architecture invariant: depends only on `moe-geom` (vocabulary types, cotangent weights),
//! faer (sparse Cholesky) and rayon. No file IO.

/// ARAP cells (spokes, spokes and rims) and per-edge data.
mod cells;
/// The solver of a whole mesh: one factorised system per connected part, parts in parallel.
mod components;
/// Solver configuration.
mod config;
/// Registration to the depth image.
mod depth;
/// The crate's error type.
mod error;
/// Multi-finger shape estimation over a hand model.
mod multi;
/// Warm-started Newton iteration on SO(3), several cells in lockstep.
mod newton;
/// Best-fitting rotations for the local step.
mod rotation;
/// The solver of one part: cells, the local/global iteration, the allocation-free workspace.
mod solver;
/// The factorised reduced system and the handle Schur complement.
mod system;
/// Handle lists given as `(vertex, target)` pairs.
mod targets;
#[cfg(test)]
mod testmesh;

pub use components::ArapSolver;
pub use config::{ArapConfig, ArapEnergy};
pub use depth::ShapeDepth;
pub use error::ArapError;
pub use moe_geom::HandShape;
pub use multi::{FingerReport, MultiShapeEstimator, ShapeConfig, ShapeEstimate};
pub use solver::{ArapInfo, ArapSolution, Start};
pub use targets::HandleTargets;
