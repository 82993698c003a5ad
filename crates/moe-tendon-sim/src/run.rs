//! Running a scene: stepping it from its initial state and keeping the saved frames
//! ([`run_with`] calls back at each, [`run_saving`] collects them as [`TrajectoryFrame`]s).

use moe_geom::Real;

use crate::error::SimError;
use crate::scene::{Scene, SimFrame, SimState, StepInfo, command};
use crate::tendon::TendonCommand;

/// One saved frame of a simulated trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryFrame {
    /// Surfaces, distances and labels.
    pub frame: SimFrame,
    /// The command of every tendon at this time, each with its unit (a pull in metres or a
    /// tension in newtons): `[finger][tendon]`.
    pub tendons: Vec<Vec<TendonCommand>>,
}

impl TrajectoryFrame {
    /// The pulled length of every tendon, metres: `[finger][tendon]`.
    ///
    /// # Errors
    /// [`SimError::ForceDriven`] naming the first tendon driven by force, whose command is a
    /// tension, not a length.
    pub fn tendon_pulls_m(&self) -> Result<Vec<Vec<Real>>, SimError> {
        self.tendons
            .iter()
            .enumerate()
            .map(|(finger, commands)| {
                commands
                    .iter()
                    .enumerate()
                    .map(|(tendon, c)| match *c {
                        TendonCommand::Displacement { pull_m } => Ok(pull_m),
                        TendonCommand::Force { .. } => {
                            Err(SimError::ForceDriven { finger, tendon })
                        }
                    })
                    .collect()
            })
            .collect()
    }
}

/// What a run leaves besides its saved frames.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// The state after the last step.
    pub final_state: SimState,
    /// Figures of the last step (`None` for a run of zero steps).
    pub last_step: Option<StepInfo>,
}

/// Runs `scene` for `steps` steps from its initial state, calling `on_frame` with the state at
/// every saved frame: the initial one, every `save_every_steps` steps, and the last one.
///
/// # Errors
/// Divergence, naming the step and the element (see [`Scene::step`]), or the first error of
/// `on_frame`; the run stops there.
pub fn run_with<E: From<SimError>>(
    scene: &mut Scene,
    steps: u64,
    mut on_frame: impl FnMut(&Scene, &SimState) -> Result<(), E>,
) -> Result<RunOutcome, E> {
    let every = scene.config().save_every_steps.max(1);
    let mut state = scene.initial_state();
    on_frame(scene, &state)?;
    // One `StepInfo` reused by every step: the stepping itself does not allocate.
    let mut info = StepInfo::default();
    for k in 1..=steps {
        scene.step_into(&mut state, &mut info)?;
        if k % every == 0 || k == steps {
            on_frame(scene, &state)?;
        }
    }
    Ok(RunOutcome {
        final_state: state,
        last_step: (steps > 0).then_some(info),
    })
}

/// Runs `scene` for `steps` steps from its initial state and returns the frames saved every
/// `save_every_steps` steps (the initial frame and the last one included).
///
/// # Errors
/// Divergence, naming the step and the element (see [`Scene::step`]).
pub fn run_saving(scene: &mut Scene, steps: u64) -> Result<Vec<TrajectoryFrame>, SimError> {
    let mut frames = Vec::new();
    run_with(scene, steps, |scene, state| {
        frames.push(saved(scene, state));
        Ok::<(), SimError>(())
    })?;
    Ok(frames)
}

fn saved(scene: &Scene, state: &SimState) -> TrajectoryFrame {
    let t = state.time_secs;
    let config = scene.config();
    let tendons = scene
        .hand()
        .fingers()
        .iter()
        .enumerate()
        .map(|(i, f)| {
            (0..f.model.tendon_routes().len())
                .map(|j| command(config.actuation.get(i), j, t))
                .collect()
        })
        .collect();
    TrajectoryFrame {
        frame: scene.frame(state),
        tendons,
    }
}
