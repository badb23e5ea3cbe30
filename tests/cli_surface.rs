//! The CLI as a person types it: every numeric option checked against its documented range,
//! `--out` honouring its extension, Ctrl-C ending with status 130 and whole (or no) outputs,
//! non-finite results refused, the summary's SELECTED in rank order with joints in model order,
//! and no internal document named in any help text.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

mod common;
use common::{bin, Scratch};

fn simgap(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("simgap runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn scratch(name: &str) -> Scratch {
    Scratch::new("surface", name)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `args`, which must fail within 10 s with a message holding every one of `parts`.
#[track_caller]
fn refused(args: &[&str], parts: &[&str]) {
    let start = Instant::now();
    let o = simgap(args);
    let t = text(&o);
    assert!(!o.status.success(), "{args:?} succeeded:\n{t}");
    assert_eq!(o.status.code(), Some(1), "{args:?}: {t}");
    assert!(start.elapsed() < Duration::from_secs(10), "{args:?} took {:?}", start.elapsed());
    for p in parts {
        assert!(t.contains(p), "{args:?}: the message does not mention {p:?}:\n{t}");
    }
}

#[test]
fn sample_period_out_of_range_is_refused_with_the_range() {
    refused(&["simulate", "--sample-period", "1e-12"], &["invalid sample_period: 1e-12 s is out of range; expected 1e-6 ≤ sample_period ≤ 1 s"]);
}

#[test]
fn substeps_out_of_range_is_refused_with_the_range() {
    refused(&["simulate", "--substeps", "1000000000"], &["invalid substeps: 1e9 is out of range; expected 1 ≤ substeps ≤ 10000"]);
}

#[test]
fn negative_counts_per_rev_is_refused() {
    refused(&["simulate", "--counts-per-rev=-5"], &["--counts-per-rev -5 is out of range", "0 (exact positions)"]);
}

#[test]
fn other_numeric_options_are_checked() {
    refused(&["simulate", "--duration", "0"], &["invalid duration: 0 s is out of range; expected 0 < duration ≤ 86400 s"]);
    refused(&["simulate", "--duration", "nan"], &["invalid duration: NaN s is out of range"]);
    refused(&["simulate", "--noise=-1"], &["invalid noise_std: -1 rad is out of range; expected 0 ≤ noise_std ≤ 1 rad"]);
    refused(&["simulate", "--duration", "86401"], &["invalid duration: 86401 s is out of range"]);
    // a CSV log is written from the run in memory; an MCAP log as the run goes, whatever its length
    let dir = scratch("long-csv");
    let csv = dir.join("long.csv");
    refused(&["simulate", "--duration", "80000", "--sample-period", "0.001", "--out", s(&csv)], &["long.csv", "8e7 samples", "a CSV log holds at most 1e7"]);
    assert!(!csv.exists());
    refused(&["simulate", "--duration", "1000", "--substeps", "5000"], &["integration steps", "expected at most 1e9"]);
    refused(&["selfcheck", "--scenarios", "0"], &["--scenarios 0 is out of range"]);
    refused(&["paper", "--duration", "0.5"], &["--duration 0.5 s is out of range", "1.2 ≤ duration ≤ 600"]);
}

#[test]
fn huge_time_delay_neither_aborts_nor_allocates() {
    let start = Instant::now();
    let o = simgap(&["simulate", "--effect", "time_delay:delay=1e9"]);
    assert!(o.status.code().is_some(), "killed by a signal: {}", text(&o));
    assert!(start.elapsed() < Duration::from_secs(20), "took {:?}", start.elapsed());
}

#[test]
fn out_with_an_unknown_extension_is_refused_before_simulating() {
    let dir = scratch("ext");
    let out = dir.join("run.txt");
    refused(&["simulate", "--out", s(&out)], &["run.txt", "expected a file ending in .mcap, .csv or .csv.gz"]);
    assert!(!out.exists());
}

#[test]
fn out_honours_the_extension() {
    let dir = scratch("formats");
    let (mcap, csv) = (dir.join("run.mcap"), dir.join("run.csv"));
    for p in [&mcap, &csv] {
        let o = simgap(&["simulate", "--duration", "0.5", "--out", s(p)]);
        assert!(o.status.success(), "{}", text(&o));
    }
    assert!(std::fs::read(&mcap).unwrap().starts_with(b"\x89MCAP"), "run.mcap is MCAP");
    let head = std::fs::read_to_string(&csv).expect("run.csv is text");
    assert!(head.lines().next().unwrap().contains("shoulder"), "run.csv has a header naming the joints: {}", head.lines().next().unwrap());
    assert!(dir.join("run.experiment.json").is_file(), "the CSV log's experiment sidecar");
    // both read back as the same run
    let (a, b) = (simgap::log::read_log(&mcap, &Default::default()).unwrap(), simgap::log::read_log(&csv, &Default::default()).unwrap());
    assert_eq!(a.len(), b.len());
    let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).filter(|n| n.contains("partial")).collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// Starts `args`, sends SIGINT after `after`, and returns the output.
fn interrupt(args: &[&str], after: Duration) -> Output {
    let child = Command::new(bin()).args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    std::thread::sleep(after);
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    child.wait_with_output().unwrap()
}

#[test]
fn ctrl_c_during_simulate_exits_130_with_a_whole_log() {
    let dir = scratch("interrupt");
    let out = dir.join("long.mcap");
    let o = interrupt(&["simulate", "--duration", "20000", "--out", s(&out)], Duration::from_millis(1500));
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    assert!(text(&o).contains("interrupted at t ="), "{}", text(&o));
    // the log is finished (readable, the run so far) or absent; no temporary file remains
    if out.exists() {
        let run = simgap::log::read_log(&out, &Default::default()).expect("an interrupted simulation leaves a whole log");
        assert!(run.len() > 1 && run.duration() < 20_000.0);
    }
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    assert!(names.iter().all(|n| n == "long.mcap"), "{names:?}");
}

#[test]
fn terms_refuses_non_finite_results_naming_the_joint() {
    let o = simgap(&["terms", "--q", "1e308,1e308", "--qd", "1e308,1"]);
    let t = text(&o);
    assert!(!o.status.success(), "{t}");
    assert!(t.contains("not finite") && t.contains("joint 'shoulder'") && !t.contains("null"), "{t}");
}

#[test]
fn no_help_text_names_an_internal_document() {
    for cmd in [
        vec!["--help"],
        vec!["terms", "--help"],
        vec!["diagnose", "--help"],
        vec!["simulate", "--help"],
        vec!["paper", "--help"],
        vec!["demo", "--help"],
        vec!["selfcheck", "--help"],
    ] {
        let o = simgap(&cmd);
        let t = text(&o);
        assert!(o.status.success(), "{cmd:?}: {t}");
        for word in ["BRIEF", "brief", "§3"] {
            assert!(!t.contains(word), "{cmd:?} mentions {word:?}:\n{t}");
        }
    }
}

#[test]
fn numeric_help_texts_document_their_ranges() {
    let t = text(&simgap(&["simulate", "--help"]));
    for range in ["0 < duration ≤ 86400", "10⁻⁶ ≤ T ≤ 1", "1 ≤ substeps ≤ 10000", "1 ≤ counts ≤ 10¹²", "0 ≤ noise ≤ 1"] {
        assert!(t.contains(range), "simulate --help does not document {range:?}");
    }
}

#[test]
fn summary_lists_selected_effects_by_rank_with_joints_in_model_order() {
    let dir = scratch("demo");
    let o = simgap(&["demo", "--out-dir", s(&dir)]);
    let t = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", text(&o));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let joints: Vec<&str> = report["joints"].as_array().unwrap().iter().map(|j| j.as_str().unwrap()).collect();
    let mut ranked: Vec<(u64, &str)> =
        report["candidates"].as_array().unwrap().iter().filter(|c| c["selected"] == true).map(|c| (c["rank"].as_u64().unwrap(), c["effect"].as_str().unwrap())).collect();
    ranked.sort();
    let section = t.split("SELECTED").nth(1).expect("a SELECTED section");
    let section = section.split("\n\n").next().unwrap();
    // effect lines start at column 2; an effect's description follows, indented further
    let effect_lines: Vec<&str> = section.lines().skip(1).filter(|l| l.starts_with("  ") && !l.starts_with("   ")).collect();
    let listed: Vec<&str> = effect_lines.iter().filter_map(|l| l.split_whitespace().next()).collect();
    assert_eq!(listed, ranked.iter().map(|r| r.1).collect::<Vec<_>>(), "SELECTED in rank order:\n{section}");
    for line in &effect_lines {
        let named: Vec<usize> = joints.iter().enumerate().filter(|(_, j)| line.contains(&format!("\"{j}\""))).map(|(i, _)| i).collect();
        let positions: Vec<usize> = named.iter().map(|&i| line.find(&format!("\"{}\"", joints[i])).unwrap()).collect();
        assert!(positions.windows(2).all(|w| w[0] < w[1]), "joints not in model order: {line}");
    }
    // units on every parameter of the summary
    assert!(section.contains("N·m·s/rad") && section.contains("N·m"), "{section}");
}

#[test]
fn terms_prints_a_warning_per_repeated_urdf_element_and_reads_the_first() {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/simgap-core/models");
    let state = ["--q", "0.3,-0.7", "--qd", "1.2,0.4"];
    let repeated = simgap(&[&["terms", "--urdf", s(&models.join("paper_arm_repeated_elements.urdf"))][..], &state].concat());
    let paper = simgap(&[&["terms", "--urdf", s(&models.join("paper_arm.urdf"))][..], &state].concat());
    assert!(repeated.status.success() && paper.status.success(), "{}{}", text(&repeated), text(&paper));
    let stderr = String::from_utf8_lossy(&repeated.stderr);
    assert!(
        stderr.contains("warning: ") && stderr.contains("paper_arm_repeated_elements.urdf: line 52: joint 'upper_arm_end' has a second <origin> (the first is at line 51)"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().filter(|l| l.starts_with("warning: ")).count(), 14, "{stderr}");
    // the terms are the paper arm's, to rounding
    let (a, b): (Value, Value) = (serde_json::from_slice(&repeated.stdout).unwrap(), serde_json::from_slice(&paper.stdout).unwrap());
    for key in ["H", "C", "Hdot", "g"] {
        let flat = |v: &Value| -> Vec<f64> {
            let mut out = Vec::new();
            let mut stack = vec![v[key].clone()];
            while let Some(x) = stack.pop() {
                match x {
                    Value::Array(xs) => stack.extend(xs),
                    x => out.push(x.as_f64().unwrap()),
                }
            }
            out
        };
        let (x, y) = (flat(&a), flat(&b));
        assert!(x.len() == y.len() && x.iter().zip(&y).all(|(p, q)| (p - q).abs() < 1e-12), "{key}: {x:?} vs {y:?}");
    }
}

#[test]
fn a_dry_friction_without_w_on_a_prismatic_axis_simulates_the_prismatic_typical_width() {
    // one slide along x (no gravity along it): w left out must be 0.002 m/s, not 0.01
    let dir = scratch("prismatic_w");
    let urdf = dir.join("slide.urdf");
    std::fs::write(
        &urdf,
        r#"<robot name="slide">
  <link name="base"/>
  <link name="carriage"><inertial><origin xyz="0 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="100" velocity="1"/></joint>
</robot>"#,
    )
    .unwrap();
    let run = |effect: &str, name: &str| -> Vec<f64> {
        let out = dir.join(name);
        let o = simgap(&[
            "simulate",
            "--urdf",
            s(&urdf),
            "--kp",
            "200",
            "--kv",
            "5",
            "--target",
            "0.05",
            "--duration",
            "0.3",
            "--counts-per-rev",
            "0",
            "--effect",
            effect,
            "--out",
            s(&out),
        ]);
        assert!(o.status.success(), "{effect}: {}", text(&o));
        simgap::log::read_log(&out, &Default::default()).unwrap().q
    };
    let default = run("coulomb_friction:fc=5", "default.csv");
    let prismatic = run("coulomb_friction:fc=5;w=0.002", "w0002.csv");
    let revolute = run("coulomb_friction:fc=5;w=0.01", "w001.csv");
    assert_eq!(default, prismatic, "w left out is the prismatic typical width 0.002 m/s");
    assert_ne!(default, revolute, "and not the revolute 0.01");
}
