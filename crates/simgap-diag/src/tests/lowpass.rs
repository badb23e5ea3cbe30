//! The recorder's low-pass filter told from the positions (`prepare::lowpass`): an encoder's
//! positions are not flagged, filtered ones are, and none of the DFKI hardware logs is.

use simgap_sim::Run;

use super::common::{have_data, shared_data};
use crate::prepare::lowpass::recorder_bandwidth;

/// A 20 s two-joint run at 400 Hz: a multisine of 0.2–2 Hz, positions quantised by a 20-bit
/// encoder.
fn encoder_run() -> Run {
    let (n, fs) = (2, 400.0);
    let samples = 8000;
    let step = std::f64::consts::TAU / 1_048_576.0;
    let mut run = Run::new(vec!["a".into(), "b".into()]);
    run.t = (0..samples).map(|k| k as f64 / fs).collect();
    run.q = run.t.iter().flat_map(|t| (0..n).map(move |j| ((0.5 * (1.3 * t + j as f64).sin() + 0.2 * (12.0 * t).sin() / (1.0 + j as f64)) / step).round() * step)).collect();
    run.qd = vec![0.0; samples * n];
    run.tau = vec![0.0; samples * n];
    run
}

#[test]
fn an_encoder_s_positions_are_not_filtered() {
    assert_eq!(recorder_bandwidth(&encoder_run()), None);
}

#[test]
fn positions_filtered_at_a_few_hertz_are_found_and_their_content_ends_above_the_cut_off() {
    for hz in [4.0, 8.0] {
        let mut run = encoder_run();
        crate::check::bench::zero_phase_lowpass(&mut run.q, 2, hz, 0.0025);
        let b = recorder_bandwidth(&run).expect("filtered positions found");
        // what passes the filter ends above its cut-off, far below where noise would be
        assert!((hz..=50.0).contains(&b), "bandwidth {b} Hz for a filter at {hz} Hz");
    }
}

#[test]
fn a_run_that_does_not_move_or_is_too_short_says_nothing() {
    let mut still = Run::new(vec!["a".into()]);
    still.t = (0..2000).map(|k| k as f64 * 0.0025).collect();
    still.q = vec![0.3; 2000];
    still.qd = vec![0.0; 2000];
    still.tau = vec![0.0; 2000];
    assert_eq!(recorder_bandwidth(&still), None);
    let short = encoder_run().slice(0..300);
    assert_eq!(recorder_bandwidth(&short), None);
}

#[test]
fn real_encoder_logs_are_not_taken_for_filtered_ones() {
    // the DFKI pendulums' hardware logs: encoders of the motors' own drives
    let root = shared_data();
    let dp = root.join("dfki-double-pendulum/experiment_records");
    if !have_data("real_encoder_logs_are_not_taken_for_filtered_ones", &dp) {
        return;
    }
    let mut logs: Vec<std::path::PathBuf> = (0..5).map(|i| dp.join(format!("design_C.0/20220914/sys_id/trajectory_0{i}.csv.gz"))).collect();
    logs.push(dp.join("design_A.0/20220812/sys_id/20220812-061157-PM_measured.csv.gz"));
    logs.push(root.join("dfki-simple-pendulum/control_method_pd/system_identification/data_measured.csv.gz"));
    for path in logs {
        let run = simgap_log::csv::read_csv_auto(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(recorder_bandwidth(&run), None, "{} taken for a filtered log", path.display());
    }
}
