//! The golden regression: every committed reference result of the numerical stages (SR-ARAP,
//! the contact network, physics, surfaces, patting, grasping, the simulator and the paper's
//! scenes) is recomputed and compared with its file. `cargo xtask fixtures --update` rewrites
//! them after an intended change.

#[test]
fn golden_fixtures_match_fresh_results() {
    if let Err(err) = moe_touch_cli::golden::run(moe_touch_cli::golden::Mode::Check) {
        panic!("{}", moe_touch::error::one_line(err.as_ref()));
    }
}
