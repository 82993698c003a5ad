//! Tetrahedral corotational FEM simulation of tendon-driven soft fingers pressed against rigid
//! obstacles: the source of training data and ground truth (paper §4.3.1, the SOFA setup:
//! E = 100 kPa, ν = 0.1, Rayleigh mass 0.1 and stiffness 0.1, displacement-driven tendons).
//!
//! Architecture invariant: depends only on `moe-geom`, nalgebra, faer, parry3d-f64, serde and
//! thiserror. No file IO; scene files are parsed by `moe-io`
//! (`moe_io::read_config::<SceneConfig>`), and results are returned as in-memory values. Every
//! loop that feeds the state is sequential (faer runs with `Par::Seq`), so a scene is
//! bit-for-bit deterministic on a given machine. The per-step path does not allocate:
//! [`Scene::step_into`] reuses per-scene, per-finger ([`mechanics::FemWorkspace`]) and per-term
//! scratch sized when the scene is built (tendon node maps are precomputed, contact
//! buffers hold a term per surface vertex and obstacle); `tests/alloc.rs` counts the heap
//! allocations of steps with a counting global allocator.
//!
//! # Pipeline
//!
//! 1. **Volume** ([`mechanics::voxelize()`]): a background grid of cubes of edge `cell_size_m` (3.5 mm by
//!    default, ≈ 3 000 tets per default finger), each split into six Kuhn tetrahedra (a
//!    conforming split), keeping the tetrahedra whose centroid is inside the closed surface
//!    (parry's oriented-mesh inside test) and the largest node-connected component. The grid's
//!    lowest layer lies on the base plane, so base nodes sit exactly at z = 0 (how closely the
//!    tets fill the surface at the default resolution: docs/results.md).
//! 2. **Embedding** ([`mechanics::Embedding`]): each surface vertex is mapped to its containing tet, or
//!    (≈ 45 % of the vertices of a voxel mesh) to the nearest tet with *unclamped*
//!    barycentric weights, so `x_s = Σ_k w_k x_{n_k}` reproduces the rest surface exactly and
//!    follows the body affinely (SOFA's barycentric mapping). Surface vertex `i` of the
//!    simulation is vertex `i` of the finger mesh. Tendon points are embedded the same way but
//!    must lie inside (else [`SimError::TendonOutsideBody`]).
//! 3. **Elasticity** ([`mechanics::FemModel`]): linear tets with shape gradients `g_a`, deformation
//!    gradient `F = Σ_a x_a g_aᵀ`, rotation `R` from the polar decomposition `F = R S`
//!    ([`mechanics::polar_rotation`], Higham's scaled Newton iteration). An inverted element
//!    (`det F ≤ 0`) gets a proper rotation from the SVD with the smallest singular value's sign
//!    flipped ([`mechanics::corotation`], Irving, Teran and Fedkiw 2004): its stretch has a
//!    negative eigenvalue and its stress pushes it back out, so a step that inverts an element
//!    goes on. Corotated linear stress `σ = λ tr(ε) I + 2μ ε` with `ε = S − I`, nodal force
//!    `f_a = −V R σ g_a` (the exact gradient of the energy `V (μ‖S − I‖² + ½λ tr²(S − I))`, zero
//!    for rigid motions) and the per-step corotated stiffness blocks
//!    `K_ab = V (λ r_a r_bᵀ + μ r_b r_aᵀ + μ (g_a·g_b) I)` with `r_a = R g_a` (= `R K⁰_ab Rᵀ`,
//!    SOFA's "large" method; the derivative of `R` is omitted). Lumped mass `ρV/4` per node
//!    (ρ = 1070 kg/m³), gravity. Nodes on the base plane (z ≤ 1 nm in the finger frame) are
//!    fixed: they follow `world_from_hand(t)·hand_from_finger` exactly.
//! 4. **Backward Euler with Rayleigh damping** `D = α_M M + β_K K`: with `Δx = h v₁`,
//!    `M(v₁ − v₀) = h (f(x₀) − K Δx − D v₁ + f_ext)` gives
//!
//!    `[M (1 + h α_M) + (h β_K + h²) K + h² K_ext + h D_ext] Δx = h M v₀ + h² (f(x₀) + f_ext)`,
//!
//!    one linear solve per step (as SOFA's implicit Euler), where `K_ext`, `D_ext` and `f_ext`
//!    are the tendon and contact terms linearised at `x₀` (not Rayleigh-damped). Fixed nodes
//!    enter with their prescribed `Δx`, moved to the right-hand side. The matrix is SPD on the
//!    free nodes; its block pattern (element couplings plus tendon-segment couplings) is
//!    analysed once (AMD + symbolic Cholesky) and refactorised numerically every step.
//!    **Quasi-static mode** ([`mechanics::Integrator::Static`]): Newton iterations `K Δx = f(x)` with a
//!    backtracking line search on the total potential, every interaction term made where the
//!    step leads (needed because the corotated tangent omits `∂R/∂x` and the terms are
//!    linearised, so a full step can overshoot or miss a contact beginning); a solve slow after
//!    20 iterations goes on with the exact Hessian and lengthens its full steps while the
//!    energy falls, and a scene's static step that does not converge is substepped.
//! 5. **Tendons** ([`mechanics::Tendon`], [`TendonParams`]): polylines through the body, cable force
//!    `f_k = T (u_k − u_{k−1})` at each embedded point, distributed by barycentric weights.
//!    Displacement drive (the paper's input): `T = k_t max(0, L − (L₀ − pull))`, the
//!    rank-one stiffness `k_t ∇L ∇Lᵀ` solved exactly by a Woodbury update with a pull-only
//!    active set (no fill in the sparse pattern), plus the geometric stiffness
//!    `(T/ℓ)(I − u uᵀ)` of each segment in the pattern. Force drive: `T` given. A negative pull
//!    pays cable out: the scenes drive an antagonistic pair like a pulley, `(+d, −d)`.
//! 6. **Contact** ([`ContactParams`]): implicit penalty on each surface vertex inside an obstacle at
//!    its end-of-step pose: force `−k d n` with stiffness `k n nᵀ` in the system matrix
//!    (k = 1e4 N/m per vertex), optional regularised Coulomb friction as an implicit tangential
//!    damping. Every saved frame reports each vertex's penalty force (N). **Label rule** (default,
//!    [`LabelRule::Press`]): a vertex that can move is in contact when it is within 1 mm of an
//!    obstacle while its finger carries at least 10 mN of contact force.
//! 7. **Scene** ([`Scene`]): a `HandModel` on a wrist trajectory, per-finger tendon schedules,
//!    kinematic obstacles; `step(&mut state)` with the state explicit ([`SimState`]);
//!    divergence (NaN, kinetic energy above a limit, an element inverted at a static
//!    equilibrium) stops with a
//!    [`SimError`] naming the step, the finger and the element or node.

// The user-facing API is re-exported at the root; the lower layers that tools and tests
// drive directly are gathered in `mechanics`; `camera`, `paper_scenes`, `randomize` and
// `testing` are separate namespaces. Every item has one public path.

// A simulated finger: tet mesh, fixed base, embedded surface and tendons.
mod body;
/// The virtual wrist RGB-D camera (rasteriser and noise model).
pub mod camera;
// Penalty contact, friction and contact labels.
mod contact;
// Linear embedding of points in tetrahedra.
mod embedding;
// The crate's error type.
mod error;
// Corotational elasticity, mass, damping and the implicit step.
mod fem;
// The sparse system pattern and its Cholesky factorisation.
mod linsys;
// Material parameters.
mod material;
pub mod mechanics;
// Rigid obstacles from parry3d shapes.
mod obstacle;
/// The scenes of the paper's experiments (head patting, arm patting, inclined plates).
pub mod paper_scenes;
// Polar decomposition.
mod polar;
/// Randomised contact scenes for training data.
pub mod randomize;
// Running a scene and keeping its saved frames.
mod run;
// Hand-level scenes with explicit state.
mod scene;
// Triangle meshes of obstacle surfaces.
mod surface;
// Tendons: embedded cables driven by displacement or force.
mod tendon;
// Interaction terms (forces at embedded points, couplings, rank-one penalties).
mod terms;
pub mod testing;
// Tetrahedral meshes.
mod tetmesh;
// Pose and actuation keyframes.
mod trajectory;
// Surface-to-volume discretisation.
mod voxelize;
// Rank-one (Woodbury) updates of the factorised system.
mod woodbury;

pub use contact::{
    ContactParams, LabelRule, SurfaceContact, contact_labels, surface_contact, surface_distances,
};
pub use error::SimError;
pub use fem::BodyState;
pub use material::Material;
pub use obstacle::{Obstacle, ObstacleConfig, ObstacleShape, SignedDistance};
pub use run::{RunOutcome, run_saving, run_with};
pub use scene::{
    FingerSimFrame, HandBodies, MAX_SAVED_FRAMES, MAX_STATIC_ITERATIONS,
    MAX_STATIC_SUBSTEP_HALVINGS, MAX_STEPS, PresetHandConfig, Scene, SceneConfig, SimFrame,
    SimState, SolverConfig, SolverMode, StepInfo,
};
pub use surface::obstacle_surface;
pub use tendon::{TendonCommand, TendonParams, TendonState};
pub use trajectory::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, PoseKeyframe, PoseTrajectory,
};
pub use voxelize::VoxelParams;

/// `skip_serializing_if` for a parameter whose default is zero: a default value writes nothing,
/// so files written before the parameter existed read and write the same.
pub(crate) fn is_zero(x: &moe_geom::Real) -> bool {
    *x == 0.0
}
