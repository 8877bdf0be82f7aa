//! The `hbcontact` command. `main` is the only place that prints an error and picks the exit
//! code: 0 success, 2 bad input (pipeline, geometry, mesh, gmsh), 3 a model that cannot be
//! solved as set up, 4 the nonlinear solver did not converge, 5 writing results failed.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, RunOptions};
use hbcontact::Error;

#[derive(Parser)]
#[command(name = "hbcontact", version, about = "Periodic steady-state vibration of 2-D elastic bodies with unilateral contact, by harmonic-balance finite elements")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args)]
struct Common {
    /// The pipeline YAML.
    pipeline: PathBuf,
    /// Override a pipeline value, e.g. `--set harmonic_balance.harmonics=20` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Write results here instead of `output.directory`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Compute the periodic steady state by harmonic balance and write the results.
    Run(Common),
    /// March in time from rest to the periodic state (the cross-check) and write the results.
    Transient(Common),
    /// Validate the pipeline and the geometry's groups without solving.
    Check(Common),
}

fn exit_code(e: &Error) -> u8 {
    match e {
        Error::Config { .. } | Error::Gmsh(_) | Error::Mesh { .. } => 2,
        Error::Model(_) => 3,
        Error::NotConverged(_) => 4,
        Error::Io { .. } => 5,
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let (common, result) = match &cli.command {
        Command::Run(c) => (c, run(c, Mode::Run)),
        Command::Transient(c) => (c, run(c, Mode::Transient)),
        Command::Check(c) => (c, run(c, Mode::Check)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let _ = common;
            eprintln!("error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
}

#[derive(Clone, Copy)]
enum Mode {
    Run,
    Transient,
    Check,
}

fn run(c: &Common, mode: Mode) -> hbcontact::Result<()> {
    let pipeline = load_pipeline(&c.pipeline, &c.set)?;
    let options = RunOptions {
        out: c.out.clone(),
        quiet: c.quiet,
    };
    match mode {
        Mode::Run => {
            pipeline::run(&pipeline, &options)?;
        }
        Mode::Transient => {
            pipeline::run_transient(&pipeline, &options)?;
        }
        Mode::Check => {
            let report = pipeline::check(&pipeline, &options)?;
            if !c.quiet {
                println!("{}", serde_json::to_string_pretty(&report).unwrap_or_default());
                println!("ok: {} is valid", c.pipeline.display());
            }
        }
    }
    Ok(())
}
