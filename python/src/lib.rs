//! `moe_touch` for Python: the MOE-Touch pipeline, the hand, SR-ARAP, the contact estimators and
//! the readers of episodes, ROS 2 recordings and data sets, with numpy arrays in and out.
//!
//! Built by maturin (`pip install ./python`); its tests are the pytest suite in
//! `python/tests`. Every failure of the Rust code is raised as [`MoeTouchError`], a
//! `ValueError` whose message is the one line the `moe-touch` tool prints for the same error.
//! Calls that take longer than a few microseconds (the pipeline, SR-ARAP, the network, file
//! reading) release the GIL.

mod contact;
mod convert;
mod data;
mod hand;
mod physics;
mod pipeline;
mod shape;

use pyo3::prelude::*;

pyo3::create_exception!(
    moe_touch,
    MoeTouchError,
    pyo3::exceptions::PyValueError,
    "A failure of MOE-Touch (bad input, an unreadable file, a failing stage): a ValueError whose \
     message is the line the moe-touch tool prints for the same error."
);

/// The Python module.
#[pymodule]
#[pyo3(name = "moe_touch")]
fn moe_touch_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MoeTouchError", m.py().get_type::<MoeTouchError>())?;
    m.add_class::<hand::Hand>()?;
    m.add_class::<hand::Camera>()?;
    m.add_class::<shape::ArapSolver>()?;
    m.add_class::<shape::ShapeEstimator>()?;
    m.add_class::<contact::ContactModel>()?;
    m.add_class::<physics::PhysicsEstimator>()?;
    m.add_class::<physics::PhysicsResult>()?;
    m.add_class::<pipeline::Pipeline>()?;
    m.add_class::<pipeline::FrameResult>()?;
    m.add_class::<pipeline::Timings>()?;
    m.add_class::<data::Episode>()?;
    m.add_class::<data::EpisodeFrame>()?;
    m.add_class::<data::Dataset>()?;
    m.add_class::<data::DatasetFrames>()?;
    m.add_function(wrap_pyfunction!(data::read_episode, m)?)?;
    m.add_function(wrap_pyfunction!(data::read_ros2_bag, m)?)?;
    m.add_function(wrap_pyfunction!(data::is_ros2_recording, m)?)?;
    Ok(())
}
