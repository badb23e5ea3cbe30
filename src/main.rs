//! The `simgap` command-line tool.

use clap::{Parser, Subcommand};

mod cli;

/// Why your simulation disagrees with your robot.
#[derive(Parser)]
#[command(name = "simgap", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Diagnose a built-in bench robot with hidden effects, blind, and print the report.
    Demo(cli::demo::Args),
    /// Print H, C, Ḣ and g as JSON lines, one object per state (joints in model order).
    Terms(cli::terms::Args),
    /// Simulate a closed-loop run and write it to MCAP.
    Simulate(cli::simulate::Args),
    /// Reproduce the seed paper's experiment with both formulations.
    Paper(cli::paper::Args),
    /// Diagnose the sim-to-real gap of a model against logs: where, which effect, how far.
    Diagnose(cli::diagnose::Args),
    /// Diagnose random blind scenarios and score the answers.
    Selfcheck(cli::selfcheck::Args),
    /// How well a model (plus effects) predicts logged runs k steps ahead.
    Predict(cli::predict::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => cli::demo::run(a),
        Command::Terms(a) => cli::terms::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
        Command::Paper(a) => cli::paper::run(a),
        Command::Diagnose(a) => cli::diagnose::run(a),
        Command::Selfcheck(a) => cli::selfcheck::run(a),
        Command::Predict(a) => cli::predict::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // after Ctrl-C: 128 + SIGINT, as a shell reports an interrupted program
        Err(e) if e.is::<cli::Interrupted>() => std::process::ExitCode::from(130),
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
