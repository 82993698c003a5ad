//! Tests of `physics_eval`.

use super::*;

fn outcome(trajectory: u64, pressed: bool, detected: bool) -> FingerOutcome {
    FingerOutcome {
        trajectory,
        pressed,
        truth_n: if pressed { 0.1 } else { 0.0 },
        detected,
        location_m: Real::NAN,
        along_m: Real::NAN,
        force_error_n: Real::NAN,
    }
}

#[test]
fn the_stream_table_counts_onsets_flicker_and_releases_per_finger_and_trajectory() {
    // Finger 0: a press missed at onset, then held with one drop, released cleanly; a press
    // that runs to the end of trajectory 0 and one that starts trajectory 1 (two presses,
    // not one), released with a false alarm. Finger 1: never pressed, one false alarm.
    let f0 = [
        (0, false, false),
        (0, true, false),
        (0, true, true),
        (0, true, false),
        (0, true, true),
        (0, false, false),
        (0, true, true),
        (1, true, true),
        (1, true, true),
        (1, false, true),
    ];
    let mut outcomes = Vec::new();
    for (k, &(t, p, d)) in f0.iter().enumerate() {
        outcomes.push(outcome(t, p, d));
        outcomes.push(outcome(t, false, k == 3));
    }
    let s = stream_table(&outcomes, 2);
    assert_eq!(s.presses, 3);
    assert_eq!(s.onset_detected, 2);
    // Held after first detection: 2 (first press) + 0 + 1.
    assert_eq!(s.held_frames, 3);
    assert_eq!(s.held_frames_dropped, 1);
    assert_eq!(s.presses_with_flicker, 1);
    // The first and the third press are released inside their trajectory.
    assert_eq!(s.releases, 2);
    assert_eq!(s.release_false_alarms, 1);
    assert!((s.onset_delay_frames_mean - 1.0 / 3.0).abs() < 1e-12);
}
