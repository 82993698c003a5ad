//! The per-step path does not allocate: a counting global allocator (in this separate test
//! binary, so that it affects no other test) counts the heap allocations made by the stepping
//! thread during scene steps after a few warm-up steps.
//!
//! Steps are sequential (faer runs with `Par::Seq`), so counting on the stepping thread sees
//! every allocation of a step.

// A global allocator can only be written with `unsafe`; this test binary contains nothing else
// that needs it.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use moe_geom::FingerParams;
use moe_tendon_sim::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, ContactParams, ObstacleConfig,
    ObstacleShape, PoseKeyframe, PoseTrajectory, Scene, SceneConfig, SolverConfig, SolverMode,
    StepInfo,
};

/// The system allocator, counting the allocations (and reallocations) of threads that asked
/// for it.
struct Counting;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    // `try_with`: the thread-locals may be gone while a thread shuts down.
    let _ = ARMED.try_with(|armed| {
        if armed.get() {
            let _ = COUNT.try_with(|c| c.set(c.get() + 1));
        }
    });
}

// SAFETY: every call is forwarded unchanged to the system allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Number of allocations `f` makes on this thread.
fn count_allocations<R>(f: impl FnOnce() -> R) -> (usize, R) {
    COUNT.with(|c| c.set(0));
    ARMED.with(|a| a.set(true));
    let r = f();
    ARMED.with(|a| a.set(false));
    (COUNT.with(Cell::get), r)
}

/// Two fingers with both antagonistic tendon pairs pulled (displacement or force drive), a plate
/// pressing finger 1's outer side deeper and deeper (more vertices come into contact during the
/// counted steps), friction on.
fn contact_scene(mode: ActuationMode, solver: SolverMode) -> SceneConfig {
    let p = FingerParams::default();
    let x0 = -0.025 - p.radius_at(0.03) - 0.0015;
    let values = match mode {
        ActuationMode::Displacement => vec![0.002, -0.002, 0.001, -0.001],
        ActuationMode::Force => vec![0.0, 1.0, 0.0, 0.5],
    };
    let schedule = ActuationSchedule {
        mode,
        keyframes: vec![
            ActuationKeyframe {
                time_secs: 0.0,
                values: vec![0.0; 4],
            },
            ActuationKeyframe {
                time_secs: 0.1,
                values,
            },
        ],
    };
    SceneConfig {
        duration_secs: 1.0,
        wrist: PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(0.0, [0.0, 0.0, 0.0]),
                PoseKeyframe::at(1.0, [0.0, 0.0, 0.01]),
            ],
        },
        actuation: vec![schedule.clone(), schedule],
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.001, 0.03, 0.02],
            },
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [x0, 0.0, 0.05]),
                    PoseKeyframe::at(0.12, [x0 + 0.004, 0.0, 0.05]),
                ],
            },
        }],
        contact: ContactParams {
            friction: 0.5,
            ..ContactParams::default()
        },
        solver: SolverConfig {
            mode: solver,
            static_tolerance_m: 1e-7,
            ..SolverConfig::default()
        },
        ..SceneConfig::default()
    }
}

/// Runs `warm_up` steps, then counts the allocations of `counted` more (all through
/// [`Scene::step_into`] with one reused [`StepInfo`]); checks that the plate touches finger 1
/// and that the tendons of finger 1 pull.
fn allocations_per_step(config: SceneConfig, warm_up: usize, counted: usize) -> Vec<usize> {
    let mut scene = Scene::new(config).unwrap();
    let mut state = scene.initial_state();
    let mut info = StepInfo::default();
    for _ in 0..warm_up {
        scene.step_into(&mut state, &mut info).unwrap();
    }
    let mut counts = Vec::with_capacity(counted);
    for _ in 0..counted {
        let (n, result) = count_allocations(|| scene.step_into(&mut state, &mut info));
        result.unwrap();
        counts.push(n);
    }
    let tension: f64 = info.tendons[1].iter().map(|t| t.tension_n).sum();
    assert!(tension > 0.0, "the tendons of finger 1 are slack");
    let frame = scene.frame(&state);
    let force: f64 = frame.fingers[1].contact_force_n.iter().sum();
    assert!(force > 0.0, "the plate does not press finger 1");
    // `Scene::step` allocates only the vectors of the `StepInfo` it returns: the kinetic
    // energies, the iteration counts, the tendon states and one vector of them per finger,
    // and in static mode the substep counts.
    let statics = scene.config().solver.mode == SolverMode::Static;
    let (n, result) = count_allocations(|| scene.step(&mut state));
    let fingers = result.unwrap().tendons.len();
    assert_eq!(
        n,
        3 + fingers + usize::from(statics),
        "allocations of Scene::step"
    );
    counts
}

#[test]
fn dynamic_steps_with_contact_and_pulled_tendons_do_not_allocate() {
    // The plate keeps moving in during the counted steps: more vertices touch it each step.
    let counts = allocations_per_step(
        contact_scene(ActuationMode::Displacement, SolverMode::Dynamic),
        4,
        6,
    );
    assert!(
        counts.iter().all(|&n| n == 0),
        "allocations per step: {counts:?}"
    );
}

#[test]
fn static_steps_with_force_driven_tendons_do_not_allocate() {
    let counts = allocations_per_step(
        contact_scene(ActuationMode::Force, SolverMode::Static),
        2,
        2,
    );
    assert!(
        counts.iter().all(|&n| n == 0),
        "allocations per step: {counts:?}"
    );
}

#[test]
fn static_steps_with_displacement_driven_tendons_do_not_allocate() {
    let counts = allocations_per_step(
        contact_scene(ActuationMode::Displacement, SolverMode::Static),
        2,
        2,
    );
    assert!(
        counts.iter().all(|&n| n == 0),
        "allocations per step: {counts:?}"
    );
}
