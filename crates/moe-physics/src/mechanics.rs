//! One finger's FEM model as the inverse uses it: static shapes under the tendon pulls, gravity
//! and point loads on the surface, and the compliance from surface loads to the observed marker
//! coordinates by reciprocity.
//!
//! Everything is in the finger frame with the base fixed at rest: the hand-level estimator
//! turns markers and gravity into this frame and the results back.

use faer::Mat;
use moe_geom::{FingerModel, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{
    Embedded, FemWorkspace, FingerBody, Integrator, PointTerm, StepContext, Tangent, Terms,
};
use moe_tendon_sim::{BodyState, Material, SimError, TendonCommand, TendonParams, VoxelParams};

/// A force on the surface, spread over a patch of vertices.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PatchLoad {
    /// `(surface vertex, share)`: shares sum to 1.
    pub(crate) patch: Vec<(u32, Real)>,
    /// The force, newtons, finger frame.
    pub(crate) force: Vector3,
}

/// The unit normal of a patch of surface with node positions `x`: the area-weighted normals of
/// its triangles `faces`, each times its weight (`None` for a patch of no area).
pub(crate) fn patch_normal(
    faces: &[([u32; 3], Real)],
    body: &FingerBody,
    x: &[Point3],
) -> Option<Vector3> {
    let points = body.surface().points();
    let n: Vector3 = faces
        .iter()
        .map(|&(f, w)| {
            let [a, b, c] = f.map(|v| points[v as usize].position(x));
            (b - a).cross(&(c - a)) * w
        })
        .sum();
    n.try_normalize(0.0)
}

/// `force`, given where the patch of triangles `faces` had the unit normal `from`, turned with
/// the patch to node positions `x` (a follower load): by the smallest rotation from `from` to
/// the patch's normal there.
pub(crate) fn turned_with_patch(
    force: &Vector3,
    from: &Vector3,
    faces: &[([u32; 3], Real)],
    body: &FingerBody,
    x: &[Point3],
) -> Vector3 {
    let Some(now) = patch_normal(faces, body, x) else {
        return *force;
    };
    match nalgebra::Rotation3::rotation_between(from, &now) {
        Some(rotation) => rotation * force,
        // Turned half a revolution: about any axis across the normal.
        None => {
            let axis = from
                .cross(&Vector3::x())
                .try_normalize(1e-6)
                .unwrap_or_else(|| from.cross(&Vector3::y()).normalize());
            nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Unit::new_unchecked(axis),
                std::f64::consts::PI,
            ) * force
        }
    }
}

/// A linear observation of the surface: the quantity `Σ a · s_v` over its terms `(v, a)`,
/// where `s_v` is surface vertex `v`'s position.
pub(crate) type Axis = Vec<(u32, Vector3)>;

/// Settings of the static solves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StaticSettings {
    pub(crate) tolerance_m: Real,
    pub(crate) max_iterations: usize,
}

/// A finger's FEM body with the scratch memory of its solves.
#[derive(Debug)]
pub(crate) struct FingerMechanics {
    body: FingerBody,
    ws: FemWorkspace,
    tangent: Tangent,
    rest_nodes: Vec<Point3>,
    /// Per surface vertex: where a load on it acts, its embedding with the barycentric weights
    /// clamped to the element (a vertex outside the voxel mesh is extrapolated by the surface
    /// embedding; a force there would lever the element's nodes).
    load_points: Vec<Embedded>,
    tendon: TendonParams,
    terms: Terms,
}

impl FingerMechanics {
    /// Tetrahedralises `finger` at `voxel` with `material`.
    pub(crate) fn new(
        finger: &FingerModel,
        material: &Material,
        voxel: &VoxelParams,
        tendon: &TendonParams,
    ) -> Result<Self, SimError> {
        tendon.validate()?;
        let mut body = FingerBody::new(finger, material, voxel)?;
        // Static solves converge quadratically, and the tangent is the true linear response.
        body.fem_mut().set_exact_static_tangent(true);
        // The estimator's terms (tendons, dead loads) follow their quadratic models: its
        // solves keep the cheaper line search, and their results as validated.
        body.fem_mut().set_modelled_line_search(true);
        let ws = body.workspace(0);
        let tangent = body.fem().tangent();
        let rest_nodes = body.fem().mesh().nodes().to_vec();
        let load_points = body
            .surface()
            .points()
            .iter()
            .map(|e| {
                let mut w = e.weights.map(|w| w.max(0.0));
                let sum: Real = w.iter().sum();
                w.iter_mut().for_each(|v| *v /= sum);
                Embedded { weights: w, ..*e }
            })
            .collect();
        Ok(Self {
            body,
            ws,
            tangent,
            rest_nodes,
            load_points,
            tendon: tendon.clone(),
            terms: Terms::default(),
        })
    }

    /// Replaces the material.
    pub(crate) fn set_material(&mut self, material: &Material) -> Result<(), SimError> {
        self.body.fem_mut().set_material(material)
    }

    /// The FEM body.
    pub(crate) fn body(&self) -> &FingerBody {
        &self.body
    }

    /// Rest node positions (finger frame).
    pub(crate) fn rest_nodes(&self) -> &[Point3] {
        &self.rest_nodes
    }

    /// Position of surface vertex `v` for node positions `x`.
    pub(crate) fn surface_position(&self, x: &[Point3], v: u32) -> Point3 {
        self.body.surface().points()[v as usize].position(x)
    }

    /// The static equilibrium under `commands`, `gravity` (finger frame) and `loads`, by Newton
    /// iterations from `x` (updated in place). Returns the iterations run.
    pub(crate) fn solve_static(
        &mut self,
        x: &mut Vec<Point3>,
        commands: &[TendonCommand],
        gravity: &Vector3,
        loads: &[PatchLoad],
        settings: StaticSettings,
        ctx: StepContext,
    ) -> Result<usize, SimError> {
        if commands.len() != self.body.tendons().len() {
            return Err(SimError::LengthMismatch {
                what: "tendon commands",
                expected: self.body.tendons().len(),
                got: commands.len(),
            });
        }
        let mut state = BodyState {
            x: std::mem::take(x),
            v: vec![Vector3::zeros(); self.rest_nodes.len()],
        };
        let Self {
            body,
            ws,
            rest_nodes,
            ..
        } = self;
        let me = &*body;
        let (tendon, load_points) = (&self.tendon, &self.load_points);
        let mut terms_fn = |xs: &[Point3], _: &[Vector3], terms: &mut Terms| {
            add_terms(me, tendon, load_points, xs, commands, loads, terms);
        };
        let result = me.fem().step(
            ws,
            ctx,
            Integrator::Static {
                tolerance_m: settings.tolerance_m,
                max_iterations: settings.max_iterations,
            },
            &mut state,
            moe_tendon_sim::mechanics::FemInputs {
                targets: rest_nodes,
                gravity: *gravity,
                terms: &mut terms_fn,
            },
        );
        *x = state.x;
        result.map(|r| r.iterations)
    }

    /// Advances `state` by one backward-Euler step of `dt_secs` under `commands` (their values at
    /// the end of the step) and `gravity`, with the material's Rayleigh damping and no load; the
    /// fixed nodes move to `targets` (the frame of `state`, `targets` and `gravity` is the
    /// caller's: the world, for a finger on a moving wrist).
    pub(crate) fn step_free(
        &mut self,
        state: &mut BodyState,
        commands: &[TendonCommand],
        gravity: &Vector3,
        targets: &[Point3],
        dt_secs: Real,
        ctx: StepContext,
    ) -> Result<(), SimError> {
        let Self { body, ws, .. } = self;
        let me = &*body;
        let (tendon, load_points) = (&self.tendon, &self.load_points);
        let mut terms_fn = |xs: &[Point3], _: &[Vector3], terms: &mut Terms| {
            add_terms(me, tendon, load_points, xs, commands, &[], terms);
        };
        me.fem().step(
            ws,
            ctx,
            Integrator::Dynamic { dt_secs },
            state,
            moe_tendon_sim::mechanics::FemInputs {
                targets,
                gravity: *gravity,
                terms: &mut terms_fn,
            },
        )?;
        Ok(())
    }

    /// Factorises the tangent at `x` (with the tendon terms under `commands` and `loads`) and
    /// returns the displacement field of every observed quantity's unit load: column `j` of
    /// the result is `K_T⁻¹ s_j` where `s_j` puts the force `a` at surface vertex `v` for every
    /// term `(v, a)` of `axes[j]` (one term along a unit axis for a marker coordinate; for a
    /// depth observation, which sees only the normal component, the normal at a vertex or the
    /// weighted normals of the pixels of a patch). By reciprocity (`K_T` symmetric),
    /// the change of observation `j` under a unit force along axis `d` at any surface point
    /// `p` is the value of column `j` interpolated at `p` along `d`.
    pub(crate) fn reciprocal_fields(
        &mut self,
        x: &[Point3],
        commands: &[TendonCommand],
        gravity: &Vector3,
        loads: &[PatchLoad],
        axes: &[Axis],
        ctx: StepContext,
    ) -> Result<Mat<Real>, SimError> {
        let mut terms = std::mem::take(&mut self.terms);
        terms.clear();
        add_terms(
            &self.body,
            &self.tendon,
            &self.load_points,
            x,
            commands,
            loads,
            &mut terms,
        );
        let fem = self.body.fem();
        let result = fem.factor_tangent(&mut self.tangent, x, &terms, gravity, ctx);
        self.terms = terms;
        result?;
        let rows = self.tangent.num_rows();
        let mut rhs = Mat::<Real>::zeros(rows, axes.len());
        for (j, axis) in axes.iter().enumerate() {
            for &(v, direction) in axis {
                let e = self.body.surface().points()[v as usize];
                for k in 0..4 {
                    if let Some(i) = fem.free_index(e.nodes[k]) {
                        for d in 0..3 {
                            if direction[d] != 0.0 {
                                rhs[(3 * i + d, j)] += e.weights[k] * direction[d];
                            }
                        }
                    }
                }
            }
        }
        self.tangent.solve_in_place(fem, rhs.as_mut())?;
        Ok(rhs)
    }

    /// The gradients, with respect to the load point's rest position, of the weights with which
    /// a load near surface vertex `v` acts on the free nodes of its element: `(free index,
    /// ∇w)` (the element's shape-function gradients).
    pub(crate) fn load_weight_gradients(&self, v: u32) -> Vec<(u32, Vector3)> {
        let e = &self.load_points[v as usize];
        let fem = self.body.fem();
        let c = fem.mesh().corners(e.tet as usize);
        let m = moe_geom::Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
        let Some(inv) = m.try_inverse() else {
            return Vec::new();
        };
        let (g1, g2, g3) = (
            inv.row(0).transpose(),
            inv.row(1).transpose(),
            inv.row(2).transpose(),
        );
        let grads = [-(g1 + g2 + g3), g1, g2, g3];
        (0..4)
            .filter_map(|k| fem.free_index(e.nodes[k]).map(|i| (i as u32, grads[k])))
            .collect()
    }

    /// The free nodes a load on surface vertex `v` acts on, with their weights: `(free index,
    /// weight)` (rows `3i..3i + 3` of a tangent's unknowns); fixed nodes take their share.
    pub(crate) fn load_free_weights(&self, v: u32) -> Vec<(u32, Real)> {
        let e = &self.load_points[v as usize];
        let fem = self.body.fem();
        (0..4)
            .filter(|&k| e.weights[k] != 0.0)
            .filter_map(|k| fem.free_index(e.nodes[k]).map(|i| (i as u32, e.weights[k])))
            .collect()
    }
}

/// Adds the tendon terms under `commands` and the point forces of `loads` at `x`.
fn add_terms(
    body: &FingerBody,
    tendon: &TendonParams,
    load_points: &[Embedded],
    x: &[Point3],
    commands: &[TendonCommand],
    loads: &[PatchLoad],
    terms: &mut Terms,
) {
    for (t, &c) in body.tendons().iter().zip(commands) {
        t.add_terms(x, c, tendon, terms);
    }
    for load in loads {
        for &(v, share) in &load.patch {
            let point = load_points[v as usize];
            // A dead load's potential, −f·p.
            terms.point_energy_j -= (load.force * share).dot(&point.position(x).coords);
            terms.points.push(PointTerm {
                point,
                force: load.force * share,
                stiffness: Default::default(),
                damping: Default::default(),
                target_velocity: Vector3::zeros(),
            });
        }
    }
}
