//! Tests of the SR-ARAP solver.

use super::*;
use crate::config::ArapEnergy;
use crate::testmesh::{SplitMix64, jittered_sphere};
use moe_geom::Iso3;
use proptest::prelude::*;

fn max_error(a: &[Point3], b: &[Point3]) -> Real {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max)
}

fn at(mesh: &TriMesh, ids: &[u32]) -> Vec<Point3> {
    ids.iter().map(|&v| mesh.vertices()[v as usize]).collect()
}

#[test]
fn unmoved_handles_return_the_rest_mesh() {
    let mesh = jittered_sphere(8, 16, 0.1, 1);
    let size = mesh.aabb().diagonal();
    for energy in ArapEnergy::ALL {
        let config = ArapConfig {
            energy,
            ..Default::default()
        };
        let fixed = [0, 40, 77];
        let handles = [5, 60, 100];
        let solver = PartSolver::new(&mesh, &config, &fixed, &handles).unwrap();
        let targets: Vec<Option<Point3>> = at(&mesh, &handles).into_iter().map(Some).collect();
        let sol = solver
            .solve(&at(&mesh, &fixed), &targets, Start::Rest)
            .unwrap();
        let err = max_error(&sol.vertices, mesh.vertices());
        assert!(err <= 1e-12 * size, "{energy}: {err:e}");
        assert_eq!(sol.info.iterations, 50);
        assert!(
            sol.info.energy.iter().all(|&e| e.abs() < 1e-12),
            "{:?}",
            sol.info.energy
        );
    }
}

/// All handles moved by one rigid motion: the solution converges to the moved rest mesh.
/// Starting from the unmoved rest mesh, the error falls below 1e-6 of the mesh size after 150
/// iterations of plain ARAP (1.2e-6 after 100, 5e-9 after 150), 300 of spokes-and-rims with
/// α = 0.01 (7.6e-9) and 400 of SR-ARAP with α = 0.01 (3.9e-8; 1.3e-6 after 300): the
/// smoothing term slows the propagation of the rotation through the mesh.
#[test]
fn rigid_motion_of_the_handles_converges_to_the_moved_mesh() {
    let mesh = jittered_sphere(10, 20, 0.15, 7);
    let size = mesh.aabb().diagonal();
    let motion = Iso3::new(Vector3::new(0.3, -0.2, 0.5), Vector3::new(0.4, 0.7, -0.3));
    let moved: Vec<Point3> = mesh.vertices().iter().map(|p| motion * p).collect();
    let fixed = [0, 33, 90, 150];
    let handles = [12, 120];
    for (energy, alpha, iterations) in [
        (ArapEnergy::Spokes, 0.0, 150),
        (ArapEnergy::Smoothed, 0.01, 400),
        (ArapEnergy::SpokesAndRims, 0.01, 300),
    ] {
        let config = ArapConfig {
            energy,
            alpha,
            iterations,
            parallel: false,
        };
        let solver = PartSolver::new(&mesh, &config, &fixed, &handles).unwrap();
        let targets: Vec<Option<Point3>> =
            handles.iter().map(|&h| Some(moved[h as usize])).collect();
        let fixed_targets: Vec<Point3> = fixed.iter().map(|&v| moved[v as usize]).collect();
        let sol = solver.solve(&fixed_targets, &targets, Start::Rest).unwrap();
        let err = max_error(&sol.vertices, &moved) / size;
        assert!(
            err <= 1e-6,
            "{energy}: relative error {err:e} after {iterations}"
        );
    }
}

/// Dropping handles through the Schur complement gives the same result as refactorising with
/// only the visible handles constrained.
#[test]
fn occluded_handles_match_a_refactorised_solver() {
    let mesh = jittered_sphere(8, 14, 0.1, 11);
    let fixed = [0, 1, 2, 3];
    let handles = [50, 60, 70, 80, 90, 100, 110];
    let config = ArapConfig {
        iterations: 20,
        ..Default::default()
    };
    let solver = PartSolver::new(&mesh, &config, &fixed, &handles).unwrap();
    let fixed_targets = at(&mesh, &fixed);
    let mut rng = SplitMix64(5);
    let moved: Vec<Point3> = at(&mesh, &handles)
        .iter()
        .map(|p| p + Vector3::new(rng.signed(), rng.signed(), rng.signed()) * 0.2)
        .collect();
    let mut ws = solver.workspace();
    let mut info = ArapInfo::default();
    for visible in [0b111_1111u32, 0b101_0110, 0b000_0001, 0] {
        let targets: Vec<Option<Point3>> = (0..handles.len())
            .map(|k| (visible >> k & 1 == 1).then_some(moved[k]))
            .collect();
        solver
            .solve_in(&mut ws, &fixed_targets, &targets, Start::Rest, &mut info)
            .unwrap();
        // Reference: the visible handles as fixed vertices of a freshly factorised solver.
        let mut ref_fixed = fixed.to_vec();
        let mut ref_targets = fixed_targets.clone();
        for (k, t) in targets.iter().enumerate() {
            if let Some(t) = t {
                ref_fixed.push(handles[k]);
                ref_targets.push(*t);
            }
        }
        let reference = PartSolver::new(&mesh, &config, &ref_fixed, &[]).unwrap();
        let expected = reference.solve(&ref_targets, &[], Start::Rest).unwrap();
        let err = max_error(ws.vertices(), &expected.vertices);
        assert!(err < 1e-10, "visible {visible:07b}: {err:e}");
        assert_eq!(info.handles_used.len(), visible.count_ones() as usize);
        for (e, r) in info.energy.iter().zip(&expected.info.energy) {
            assert!((e - r).abs() <= 1e-9 * r.abs() + 1e-12);
        }
        // The expanded energy of the iterations agrees with the direct form.
        let direct = solver.energy(ws.vertices(), ws.rotations());
        let last = *info.energy.last().unwrap();
        assert!(
            (direct - last).abs() <= 1e-9 * direct + 1e-12,
            "{direct} vs {last}"
        );
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let mesh = jittered_sphere(4, 8, 0.0, 1);
    let n = mesh.num_vertices();
    let c = ArapConfig::default();
    assert_eq!(
        PartSolver::new(&mesh, &c, &[], &[]).unwrap_err(),
        ArapError::Unanchored { vertex: 0 }
    );
    assert_eq!(
        PartSolver::new(&mesh, &c, &[0, n as u32], &[]).unwrap_err(),
        ArapError::VertexOutOfRange {
            what: "fixed",
            index: n,
            len: n
        }
    );
    assert_eq!(
        PartSolver::new(&mesh, &c, &[3, 3], &[]).unwrap_err(),
        ArapError::DuplicateVertex {
            what: "fixed",
            vertex: 3
        }
    );
    assert_eq!(
        PartSolver::new(&mesh, &c, &[3], &[3]).unwrap_err(),
        ArapError::DuplicateVertex {
            what: "handle",
            vertex: 3
        }
    );
    assert_eq!(
        PartSolver::new(&mesh, &c, &[3], &[9, 99]).unwrap_err(),
        ArapError::VertexOutOfRange {
            what: "handle",
            index: 99,
            len: n
        }
    );
    let bad_alpha = ArapConfig {
        alpha: -0.1,
        ..Default::default()
    };
    assert!(matches!(
        PartSolver::new(&mesh, &bad_alpha, &[3], &[]),
        Err(ArapError::InvalidConfig { name: "alpha", .. })
    ));
    let solver = PartSolver::new(&mesh, &c, &[3], &[9]).unwrap();
    let p = mesh.vertices()[3];
    let nan = Point3::new(0.0, Real::NAN, 0.0);
    assert_eq!(
        solver.solve(&[nan], &[None], Start::Rest).unwrap_err(),
        ArapError::NonFiniteTarget {
            what: "fixed target",
            index: 0
        }
    );
    assert_eq!(
        solver.solve(&[p], &[Some(nan)], Start::Rest).unwrap_err(),
        ArapError::NonFiniteTarget {
            what: "handle target",
            index: 0
        }
    );
    assert_eq!(
        solver.solve(&[p, p], &[None], Start::Rest).unwrap_err(),
        ArapError::LengthMismatch {
            what: "fixed targets",
            expected: 1,
            got: 2
        }
    );
    assert_eq!(
        solver
            .solve(&[p], &[None], Start::Positions(&[p]))
            .unwrap_err(),
        ArapError::LengthMismatch {
            what: "start positions",
            expected: n,
            got: 1
        }
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// With α = 0 the energy never increases from the first solved iteration on.
    #[test]
    fn plain_arap_energy_never_increases(
        rings in 3usize..8,
        segments in 5usize..12,
        jitter in 0.0f64..0.25,
        seed in any::<u64>(),
        num_fixed in 1usize..6,
        amplitude in 0.05f64..0.8,
        rims in any::<bool>(),
    ) {
        let mesh = jittered_sphere(rings, segments, jitter, seed);
        let n = mesh.num_vertices() as u64;
        let mut rng = SplitMix64(seed ^ 0xABCD);
        let mut fixed: Vec<u32> = Vec::new();
        while fixed.len() < num_fixed {
            let v = (rng.next_u64() % n) as u32;
            if !fixed.contains(&v) {
                fixed.push(v);
            }
        }
        let targets: Vec<Point3> = at(&mesh, &fixed)
            .iter()
            .map(|p| p + Vector3::new(rng.signed(), rng.signed(), rng.signed()) * amplitude)
            .collect();
        let energy = if rims { ArapEnergy::SpokesAndRims } else { ArapEnergy::Smoothed };
        let config = ArapConfig { energy, alpha: 0.0, iterations: 15, parallel: false };
        let solver = PartSolver::new(&mesh, &config, &fixed, &[]).unwrap();
        let sol = solver.solve(&targets, &[], Start::Rest).unwrap();
        let e = &sol.info.energy;
        prop_assert_eq!(e.len(), 15);
        for t in 1..e.len() {
            // Rounding of the expanded energy is ~1e-16 of Σ w‖e‖² (order 10 here).
            prop_assert!(e[t] <= e[t - 1] + 1e-11, "iteration {}: {} > {}", t, e[t], e[t - 1]);
        }
    }
}

/// Plain ARAP (spokes, α = 0) on `mesh` with `fixed` vertices and `iterations` per solve.
fn plain(mesh: &TriMesh, fixed: &[u32], iterations: usize) -> PartSolver {
    let config = ArapConfig {
        energy: ArapEnergy::Spokes,
        alpha: 0.0,
        iterations,
        parallel: false,
    };
    PartSolver::new(mesh, &config, fixed, &[]).unwrap()
}

/// A row of `weight` asking vertex `v` of a sphere about the origin to sink by `depth_m` along
/// its radial normal; with the vertex's rest position and that normal.
fn sinking_row(
    mesh: &TriMesh,
    v: u32,
    depth_m: Real,
    weight: Real,
) -> (SurfaceRow, Point3, Vector3) {
    let p = mesh.vertices()[v as usize];
    let normal = (p - Point3::origin()).normalize();
    let row = SurfaceRow {
        terms: vec![(v, normal)],
        value: normal.dot(&p.coords) - depth_m,
        weight,
    };
    (row, p, normal)
}

/// A solve from rest with `rows`: the positions and what the solve recorded.
fn solve_with_rows(
    solver: &PartSolver,
    mesh: &TriMesh,
    fixed: &[u32],
    rows: Vec<SurfaceRow>,
) -> (Vec<Point3>, ArapInfo, SurfaceTerms) {
    let terms = solver.surface_terms(rows).unwrap();
    let mut ws = solver.workspace();
    let mut info = ArapInfo::default();
    solver
        .solve_in_with(
            &mut ws,
            &at(mesh, fixed),
            &[],
            Start::Rest,
            &mut info,
            Some(&terms),
        )
        .unwrap();
    (ws.vertices().to_vec(), info, terms)
}

/// Soft rows (depth patches) in plain ARAP: the energy with their term still never increases,
/// a heavy row puts its vertex on its plane, and the vertex is free to slide along the plane
/// (a row only sees the normal component): its tangential position is ARAP's.
#[test]
fn surface_rows_pull_along_their_normal_and_the_energy_never_increases() {
    let mesh = jittered_sphere(8, 14, 0.1, 3);
    let fixed = [0, 1, 2, 3, 4];
    let solver = plain(&mesh, &fixed, 200);
    let v = 60u32;
    let mut slide = Real::NAN;
    for weight in [1.0, 1e6] {
        let (row, p, normal) = sinking_row(&mesh, v, 0.02, weight);
        let (x, info, _) = solve_with_rows(&solver, &mesh, &fixed, vec![row]);
        let e = &info.energy;
        // Up to rounding: a heavy row makes the system stiff (condition ~ the weight).
        let tolerance = 1e-12 * e[0].max(1.0);
        for t in 1..e.len() {
            assert!(
                e[t] <= e[t - 1] + tolerance,
                "iteration {t}: {} > {}",
                e[t],
                e[t - 1]
            );
        }
        let moved = x[v as usize] - p;
        let along = moved.dot(&normal);
        assert!(along < -1e-3, "weight {weight}: {along}");
        if weight > 1.0 {
            assert!((along + 0.02).abs() < 1e-4, "heavy row: {along}");
        }
        slide = (moved - normal * along).norm();
    }
    // Pushed in by 2 % of the radius, the heavily held vertex drags its ring in and slides
    // little.
    assert!(slide < 0.01, "{slide}");
    // Bad rows are refused by name.
    let row = || sinking_row(&mesh, v, 0.02, 1.0).0;
    let mut bad = row();
    bad.weight = Real::NAN;
    assert!(matches!(
        solver.surface_terms(vec![row(), bad]),
        Err(ArapError::NonFiniteTarget {
            what: "surface row",
            index: 1
        })
    ));
    let mut negative = row();
    negative.weight = -1.0;
    assert!(matches!(
        solver.surface_terms(vec![negative]),
        Err(ArapError::InvalidConfig {
            name: "surface row weight",
            ..
        })
    ));
    let mut far = row();
    far.terms[0].0 = 10_000;
    assert!(matches!(
        solver.surface_terms(vec![far]),
        Err(ArapError::VertexOutOfRange { .. })
    ));
}

/// The global step minimises the whole energy: a converged plain-ARAP solve with a soft row is
/// a stationary point of `Σ_i min_R E_i(x, R) + w (aᵀx − c)²` (central differences at the
/// row's vertex and its ring vanish), not of the energy with the row counted twice.
#[test]
fn a_converged_solve_with_a_row_is_stationary_for_the_whole_energy() {
    use crate::rotation::fit_rotation;
    let mesh = jittered_sphere(6, 10, 0.1, 5);
    let fixed = [0, 1, 2, 3];
    let solver = plain(&mesh, &fixed, 4000);
    let v = 40u32;
    let (row, _, _) = sinking_row(&mesh, v, 0.05, 2.0);
    let (x, _, terms) = solve_with_rows(&solver, &mesh, &fixed, vec![row.clone()]);
    let arap = |x: &[Point3]| -> Real {
        (0..x.len())
            .map(|i| {
                let (s, _) = solver.cell_covariance(i, x);
                let (r, _) = fit_rotation(&s);
                solver.cells.cell_energy(i, x, &r)
            })
            .sum()
    };
    let whole = |x: &[Point3]| arap(x) + terms.energy(x);
    let slope = |f: &dyn Fn(&[Point3]) -> Real, k: usize, c: usize| {
        let h = 1e-6;
        let (mut plus, mut minus) = (x.clone(), x.clone());
        plus[k][c] += h;
        minus[k][c] -= h;
        (f(&plus) - f(&minus)) / (2.0 * h)
    };
    // The row's own pull at the solution, the scale a wrong weighting would leave unbalanced.
    let r = row.residual(&x);
    let pull = 2.0 * row.weight * r.abs();
    assert!(r.abs() > 1e-3, "the row is not met exactly: {r}");
    let mut probed = vec![v as usize];
    probed.extend(solver.cells.ring(v as usize).iter().map(|&w| w as usize));
    for k in probed {
        for c in 0..3 {
            let g = slope(&whole, k, c);
            assert!(
                g.abs() < 1e-3 * pull,
                "vertex {k}, axis {c}: slope {g:e} against the row's pull {pull:e}"
            );
        }
    }
    // Counted twice, the row's energy is not stationary there.
    let twice = |x: &[Point3]| arap(x) + 2.0 * terms.energy(x);
    let g = (0..3)
        .map(|c| slope(&twice, v as usize, c).abs())
        .fold(0.0, Real::max);
    assert!(g > 0.1 * pull, "{g:e}");
}

/// The local step fits rotations two cells at a time, sequentially or in parallel chunks: both
/// give the same positions and rotations bit for bit (an odd vertex count exercises the last,
/// single cell), and the same energies up to the order of their summation.
#[test]
fn parallel_and_sequential_local_steps_agree_exactly() {
    let mesh = jittered_sphere(31, 33, 0.1, 5);
    assert!(mesh.num_vertices() >= PARALLEL_MIN_VERTICES && mesh.num_vertices() % 2 == 1);
    let fixed = [0, 1, 2, 3];
    let handles = [500, 900];
    let targets = [
        Some(mesh.vertices()[500] + Vector3::new(0.2, -0.1, 0.05)),
        Some(mesh.vertices()[900] + Vector3::new(-0.1, 0.15, 0.1)),
    ];
    let solve = |parallel| {
        let config = ArapConfig {
            iterations: 12,
            parallel,
            ..Default::default()
        };
        let solver = PartSolver::new(&mesh, &config, &fixed, &handles).unwrap();
        let mut ws = solver.workspace();
        let mut info = ArapInfo::default();
        solver
            .solve_in(
                &mut ws,
                &at(&mesh, &fixed),
                &targets,
                Start::Rest,
                &mut info,
            )
            .unwrap();
        (ws, info)
    };
    let (seq, seq_info) = solve(false);
    let (par, par_info) = solve(true);
    assert_eq!(seq.vertices(), par.vertices());
    assert_eq!(seq.rotations(), par.rotations());
    assert_eq!(seq_info.svd_fallbacks, par_info.svd_fallbacks);
    for (a, b) in seq_info.energy.iter().zip(&par_info.energy) {
        assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} vs {b}");
    }
    // The handles moved the mesh.
    assert!(max_error(seq.vertices(), mesh.vertices()) > 0.05);
}
