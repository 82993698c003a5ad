//! `moe_touch` for Python: the MOE-Touch pipeline, the hand, SR-ARAP, the contact estimators and
//! the readers of episodes, ROS 2 recordings and data sets, with numpy arrays in and out.
//!
//! Built by maturin (`pip install ./python`); its tests are the pytest suite in
//! `python/tests`. Every failure of the Rust code is raised as a `MoeTouchError` whose message is
//! the one line the `moe-touch` tool prints for the same error: `MoeTouchFileNotFoundError`
//! (also a `FileNotFoundError`) for a missing file, `MoeTouchOSError` (an `OSError`) for another
//! failure to read one, `MoeTouchValueError` (a `ValueError`) for everything else.
//! Calls that take longer than a few microseconds (the pipeline, SR-ARAP, the network, file
//! reading) release the GIL.

mod card;
mod contact;
mod convert;
mod data;
mod errors;
mod hand;
mod physics;
mod pipeline;
mod settings;
mod shape;

use pyo3::prelude::*;

/// The Python module.
#[pymodule]
#[pyo3(name = "moe_touch")]
fn moe_touch_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MoeTouchError", py.get_type::<errors::MoeTouchError>())?;
    for class in errors::classes(py)? {
        let class = class.bind(py);
        m.add(class.name()?, class)?;
    }
    m.add_class::<hand::Hand>()?;
    m.add_class::<hand::Camera>()?;
    m.add_class::<shape::ArapSolver>()?;
    m.add_class::<shape::MultiShapeEstimator>()?;
    m.add_class::<contact::ContactModel>()?;
    m.add_class::<card::ModelCard>()?;
    m.add_class::<card::CardHand>()?;
    m.add_class::<card::CardTraining>()?;
    m.add_class::<card::CardDataset>()?;
    m.add_class::<card::CardDataSource>()?;
    m.add_class::<card::CardMetrics>()?;
    m.add_class::<card::EpochRecord>()?;
    m.add_class::<physics::PhysicsEstimator>()?;
    m.add_class::<physics::PhysicsEstimate>()?;
    m.add_class::<physics::ContactLoad>()?;
    m.add_class::<pipeline::Pipeline>()?;
    m.add_class::<pipeline::FrameEstimate>()?;
    m.add_class::<pipeline::StageTimings>()?;
    m.add_class::<data::Episode>()?;
    m.add_class::<data::EpisodeFrame>()?;
    m.add_class::<data::Dataset>()?;
    m.add_class::<data::DatasetFrames>()?;
    m.add_class::<card::DatasetCard>()?;
    m.add_class::<card::DatasetLayout>()?;
    m.add_class::<card::ShardEntry>()?;
    m.add_class::<card::FrameStats>()?;
    m.add_function(wrap_pyfunction!(data::read_episode, m)?)?;
    m.add_function(wrap_pyfunction!(data::read_ros2_bag, m)?)?;
    m.add_function(wrap_pyfunction!(data::is_ros2_recording, m)?)?;
    Ok(())
}
