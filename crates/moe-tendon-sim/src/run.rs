//! Running a scene: stepping it from its start state and keeping the saved frames
//! ([`run_with`] calls back at each, [`run_saving`] collects them as [`SimFrame`]s).

use crate::error::SimError;
use crate::scene::{Scene, SimFrame, SimState, StepInfo};

/// What a run leaves besides its saved frames.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// The state after the last step.
    pub final_state: SimState,
    /// Figures of the last step (`None` for a run of zero steps).
    pub last_step: Option<StepInfo>,
}

/// Runs `scene` for `steps` steps from its start state ([`Scene::start_state`]), calling
/// `on_frame` with the state at every saved frame: the initial one, every `save_every_steps`
/// steps, and the last one.
///
/// # Errors
/// [`SimError::StepsBeyondScene`] for more `steps` than the scene's duration covers
/// ([`Scene::num_steps`], which the scene's own limits bound); a settled start whose
/// equilibrium is not found; divergence, naming the step and the element (see
/// [`Scene::step`]), or the first error of `on_frame`; the run stops there.
pub fn run_with<E: From<SimError>>(
    scene: &mut Scene,
    steps: u64,
    mut on_frame: impl FnMut(&Scene, &SimState) -> Result<(), E>,
) -> Result<RunOutcome, E> {
    let covered = scene.num_steps();
    if steps > covered {
        return Err(SimError::StepsBeyondScene { steps, covered }.into());
    }
    let every = scene.config().save_every_steps.max(1);
    let mut state = scene.start_state()?;
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

/// Runs `scene` for `steps` steps from its start state and returns the frames saved every
/// `save_every_steps` steps (the initial frame and the last one included).
///
/// # Errors
/// As [`run_with`].
pub fn run_saving(scene: &mut Scene, steps: u64) -> Result<Vec<SimFrame>, SimError> {
    let mut frames = Vec::new();
    run_with(scene, steps, |scene, state| {
        frames.push(scene.frame(state));
        Ok::<(), SimError>(())
    })?;
    Ok(frames)
}
