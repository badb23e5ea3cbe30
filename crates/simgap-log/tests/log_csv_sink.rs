//! The CSV sink writes a run as it goes (`NAME.partial.csv` until the run ends, then `NAME.csv`),
//! and a partial log cut anywhere, as a killed writer leaves it, reads up to its last complete
//! row: a cut last line is dropped, a gzip member cut short ends the data, with a warning.

use std::path::Path;

use simgap_core::{Formulation, Model};
use simgap_log::csv_sink::{is_partial, partial_path};
use simgap_log::{read_log_with_warnings, CsvSink, LogOptions};
use simgap_sim::paper;
use simgap_sim::{simulate, MemorySink, Plant, Run, SimParams};

/// The paper's experiment for `duration` seconds, into `sink`.
fn run_into(duration: f64, sink: &mut dyn simgap_sim::Sink) {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let mut pd = paper::controller();
    let params = SimParams { duration, ..SimParams::default() };
    simulate(&plant, &mut pd, &paper::reference(), &params, sink, None).unwrap();
}

fn reference(duration: f64) -> Run {
    let mut sink = MemorySink::new();
    run_into(duration, &mut sink);
    sink.into_run()
}

fn assert_prefix(run: &Run, whole: &Run, what: &str) {
    let (n, d) = (run.len(), run.dof());
    assert_eq!(run.t[..], whole.t[..n], "{what}: t");
    assert_eq!(run.q[..], whole.q[..n * d], "{what}: q");
    assert_eq!(run.qd[..], whole.qd[..n * d], "{what}: qd");
    assert_eq!(run.tau[..], whole.tau[..n * d], "{what}: tau");
    assert_eq!(run.q_ref[..], whole.q_ref[..n * d], "{what}: q_ref");
}

#[test]
fn partial_names_keep_the_extension() {
    assert_eq!(partial_path(Path::new("/a/run.csv")), Path::new("/a/run.partial.csv"));
    assert_eq!(partial_path(Path::new("run.CSV.gz")), Path::new("run.partial.CSV.gz"));
    assert!(is_partial(Path::new("x/run.partial.csv")) && is_partial(Path::new("run.partial.csv.gz")));
    assert!(!is_partial(Path::new("run.csv")) && !is_partial(Path::new("partial.csv")));
}

#[test]
fn csv_sink_writes_the_run_and_renames_it_when_finished() {
    // removed when the test ends, also when it fails
    let scratch = tempfile::Builder::new().prefix("simgap-csv-sink-").tempdir().unwrap();
    let dir = scratch.path();
    let whole = reference(20.0);
    for name in ["run.csv", "run.csv.gz"] {
        let path = dir.join(name);
        let mut sink = CsvSink::create(&path).unwrap();
        assert!(partial_path(&path).exists(), "{name}: the partial file is there from the start");
        run_into(20.0, &mut sink);
        assert!(path.exists() && !partial_path(&path).exists(), "{name}: renamed when finished");
        let read = read_log_with_warnings(&path, &LogOptions::default()).unwrap();
        assert!(read.warnings.is_empty(), "{name}: {:?}", read.warnings);
        assert_eq!(read.run.len(), whole.len(), "{name}");
        assert_prefix(&read.run, &whole, name);
        assert!(read.run.experiment.is_some(), "{name}: the sidecar");
    }
}

#[test]
fn a_partial_csv_cut_anywhere_reads_its_complete_rows() {
    // removed when the test ends, also when it fails
    let scratch = tempfile::Builder::new().prefix("simgap-csv-cut-").tempdir().unwrap();
    let dir = scratch.path();
    let whole = reference(20.0);
    for name in ["run.csv", "run.csv.gz"] {
        let path = dir.join(name);
        let mut sink = CsvSink::create(&path).unwrap();
        run_into(20.0, &mut sink);
        let bytes = std::fs::read(&path).unwrap();
        let partial = partial_path(&path);
        // cuts inside the header's batch are files without a row; the others end anywhere
        for cut in [bytes.len() / 7, bytes.len() / 3 + 1, bytes.len() / 2 + 13, bytes.len() - 5, bytes.len()] {
            std::fs::write(&partial, &bytes[..cut]).unwrap();
            let what = format!("{name} cut at {cut} of {}", bytes.len());
            let read = read_log_with_warnings(&partial, &LogOptions::default()).unwrap_or_else(|e| panic!("{what}: {e}"));
            let w = read.warnings.join("; ");
            assert!(w.contains("did not finish") && w.contains(&format!("{} complete rows recovered", read.run.len())), "{what}: {w}");
            if !name.ends_with(".gz") {
                // every line the cut file ends is a row
                let lines = bytes[..cut].iter().filter(|&&b| b == b'\n').count();
                assert_eq!(read.run.len(), lines - 1, "{what}");
                assert_eq!(w.contains("a cut last line"), bytes[cut - 1] != b'\n', "{what}: {w}");
            } else if cut < bytes.len() {
                assert!(w.contains("gzip member"), "{what}: {w}");
            }
            assert!(!read.run.is_empty() && read.run.len() <= whole.len(), "{what}");
            assert_prefix(&read.run, &whole, &what);
        }
    }
}
