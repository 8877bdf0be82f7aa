//! The `hbcontact` command. `main` is the only place that prints an error and picks the exit
//! code: 0 success, 2 bad input (pipeline, geometry, mesh, gmsh), 3 a model that cannot be
//! solved as set up, 4 the nonlinear solver did not converge, 5 writing results failed.

use std::path::PathBuf;
use std::process::ExitCode;

mod cli;

use clap::{Parser, Subcommand, ValueEnum};
use hbcontact::config::load_pipeline;
use hbcontact::pipeline::{self, RunOptions};
use hbcontact::{Error, Reporter, Silent};

#[derive(Parser)]
#[command(
    name = "hbcontact",
    version,
    about = "Periodic steady-state vibration of 2-D elastic bodies with unilateral contact, by harmonic-balance finite elements"
)]
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
    /// Write results here instead of `output.directory` (`transient`: instead of
    /// `<output.directory>-transient`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print nothing but errors (and, for `accuracy`, not its table either).
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Compute the periodic steady state by harmonic balance and write the results.
    Run(Common),
    /// March in time from rest to the periodic state (the cross-check) and write the results
    /// to `<output.directory>-transient` (or `--out`), beside the harmonic-balance result.
    Transient(Common),
    /// Validate the pipeline and the geometry's groups without solving.
    Check {
        #[command(flatten)]
        common: Common,
        /// Print the findings as JSON only (for scripts).
        #[arg(long)]
        json: bool,
    },
    /// What accuracy costs: run ladders of settings and tabulate error against wall time.
    Accuracy {
        #[command(flatten)]
        common: Common,
        /// A ladder `key=v1,v2,...` (cheapest first; the last value is the reference), e.g.
        /// `harmonic_balance.harmonics=5,10,20,40` or `geometry.mesh_size=0.004,0.002,0.001`
        /// (repeatable). Default: harmonics H/4, H/2, H, 2H for contact scenes and element
        /// order 1, 2.
        #[arg(long = "ladder", value_name = "KEY=V1,V2,...")]
        ladders: Vec<String>,
    },
    /// Natural frequencies with the scene's supports (contact open), mode shapes as a VTU
    /// series and effective modal masses, written to `<output.directory>-modes` (or `--out`).
    Modes {
        #[command(flatten)]
        common: Common,
        /// How many modes, lowest first.
        #[arg(long, default_value_t = 10)]
        count: usize,
    },
    /// Differences between a harmonic-balance result and a time-marching one of the same
    /// scene (probe amplitudes, contact forces, harmonics), printed and written as
    /// compare.json and compare.csv into HB_DIR (or `--out`).
    Compare {
        /// The `hbcontact run` result directory.
        hb_dir: PathBuf,
        /// The `hbcontact transient` result directory (`<dir>-transient`).
        transient_dir: PathBuf,
        /// Write compare.json and compare.csv here instead of HB_DIR.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Print the JSON Schema of a pipeline YAML (`pipeline`), summary.json (`summary`),
    /// modes.json (`modes`) or compare.json (`compare`).
    Schema {
        #[arg(value_enum)]
        which: SchemaKind,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum SchemaKind {
    /// A pipeline YAML (docs/pipeline.schema.json).
    Pipeline,
    /// summary.json (docs/summary.schema.json)
    Summary,
    /// modes.json (docs/modes.schema.json)
    Modes,
    /// compare.json (docs/compare.schema.json)
    Compare,
}

fn exit_code(e: &Error) -> u8 {
    match e.root() {
        Error::Config { .. } | Error::Input(_) | Error::Gmsh(_) | Error::Mesh { .. } => 2,
        Error::Model(_) => 3,
        Error::NotConverged(_) => 4,
        Error::Io { .. } => 5,
        Error::InStage { .. } => unreachable!("root() looks through stage context"),
    }
}

/// Exit code after SIGINT, SIGTERM or SIGHUP (128 + SIGINT, the shell's convention).
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let cli = Cli::parse();
    // gmsh runs in its own process group (so that a timeout can kill all of it), which also
    // keeps a terminal's Ctrl-C from reaching it: kill it here before going. A failure to
    // install the handler leaves the parent-death signal, which still ends gmsh with us.
    let _ = ctrlc::set_handler(|| {
        hbcontact::mesh::gmsh::kill_running();
        eprintln!("interrupted: gmsh stopped; no output written");
        std::process::exit(INTERRUPTED);
    });
    let result = match &cli.command {
        Command::Run(c) => run(c, Mode::Run),
        Command::Transient(c) => run(c, Mode::Transient),
        Command::Check { common, json } => check(common, *json),
        Command::Accuracy { common, ladders } => accuracy(common, ladders),
        Command::Schema { which } => schema(*which),
        Command::Modes { common, count } => modes(common, *count),
        Command::Compare {
            hb_dir,
            transient_dir,
            out,
            quiet,
        } => compare(hb_dir, transient_dir, out.as_deref(), *quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
}

#[derive(Clone, Copy)]
enum Mode {
    Run,
    Transient,
}

/// The reporter a subcommand uses: nothing with `--quiet`, bars or lines otherwise.
fn reporter(quiet: bool) -> Box<dyn Reporter> {
    if quiet {
        Box::new(Silent)
    } else {
        Box::new(cli::reporter::Cli::new())
    }
}

fn run(c: &Common, mode: Mode) -> hbcontact::Result<()> {
    let pipeline = load_pipeline(&c.pipeline, &c.set)?;
    let options = RunOptions { out: c.out.clone() };
    let reporter = reporter(c.quiet);
    let result = match mode {
        Mode::Run => pipeline::run(&pipeline, &options, &*reporter)?,
        Mode::Transient => pipeline::run_transient(&pipeline, &options, &*reporter)?,
    };
    if !c.quiet {
        cli::show_run(&result);
    }
    Ok(())
}

/// `hbcontact check`: a readable list of what was found, or JSON only with `--json`.
fn check(c: &Common, json: bool) -> hbcontact::Result<()> {
    let pipeline = load_pipeline(&c.pipeline, &c.set)?;
    let options = RunOptions { out: c.out.clone() };
    let report = pipeline::check(&pipeline, &options, &*reporter(c.quiet || json))?;
    if json {
        println!("{}", to_json(&report)?);
    } else if !c.quiet {
        cli::show_check(&report);
        println!("ok: {} is valid", c.pipeline.display());
    }
    Ok(())
}

fn to_json<T: serde::Serialize>(value: &T) -> hbcontact::Result<String> {
    serde_json::to_string_pretty(value).map_err(|e| Error::Model(format!("internal: JSON: {e}")))
}

/// `hbcontact schema pipeline|summary`: the JSON Schema of a pipeline YAML or of
/// `summary.json` (the files in docs/).
fn schema(which: SchemaKind) -> hbcontact::Result<()> {
    let schema = match which {
        SchemaKind::Pipeline => hbcontact::config::pipeline_schema(),
        SchemaKind::Summary => pipeline::summary_schema(),
        SchemaKind::Modes => pipeline::modes::modes_schema(),
        SchemaKind::Compare => pipeline::compare::compare_schema(),
    };
    println!("{}", to_json(&schema)?);
    Ok(())
}

/// `hbcontact modes`: the table on stdout, the files in `<output.directory>-modes`.
fn modes(c: &Common, count: usize) -> hbcontact::Result<()> {
    let pipeline = load_pipeline(&c.pipeline, &c.set)?;
    let options = RunOptions { out: c.out.clone() };
    let result = pipeline::modes(&pipeline, &options, count, &*reporter(c.quiet))?;
    if !c.quiet {
        cli::show_modes(&result);
    }
    Ok(())
}

/// `hbcontact compare`: the differences on stdout, compare.json and compare.csv written.
fn compare(
    hb: &std::path::Path,
    transient: &std::path::Path,
    out: Option<&std::path::Path>,
    quiet: bool,
) -> hbcontact::Result<()> {
    let comparison = pipeline::compare::compare(hb, transient)?;
    let dir = out.unwrap_or(hb);
    pipeline::compare::write(&comparison, dir)?;
    if !quiet {
        cli::show_compare(&comparison);
        eprintln!("wrote {}/compare.json and compare.csv", dir.display());
    }
    Ok(())
}

fn accuracy(c: &Common, ladders: &[String]) -> hbcontact::Result<()> {
    use hbcontact::pipeline::accuracy::{study, table, Ladder};
    let pipeline = load_pipeline(&c.pipeline, &c.set)?;
    let mut parsed = Vec::new();
    for l in ladders {
        let Some((key, values)) = l.split_once('=') else {
            return Err(Error::Config {
                path: c.pipeline.clone(),
                message: format!("--ladder {l}: expected KEY=V1,V2,... (e.g. harmonic_balance.harmonics=5,10,20)"),
            });
        };
        parsed.push(Ladder {
            key: key.trim().to_string(),
            values: values
                .split(',')
                .map(|v| v.trim().to_string())
                .filter(|v| !v.is_empty())
                .collect(),
        });
    }
    if parsed.is_empty() {
        let h = pipeline.harmonic_balance.harmonics.max(1);
        if pipeline.contact.is_some() {
            parsed.push(Ladder {
                key: "harmonic_balance.harmonics".into(),
                values: [h / 4, h / 2, h, 2 * h]
                    .iter()
                    .filter(|&&v| v >= 1)
                    .map(|v| v.to_string())
                    .collect(),
            });
        }
        parsed.push(Ladder {
            key: "geometry.order".into(),
            values: vec!["1".into(), "2".into()],
        });
    }
    let out = c.out.clone().unwrap_or_else(|| {
        let mut d = pipeline.output.directory.clone().into_os_string();
        d.push("-accuracy");
        PathBuf::from(d)
    });
    let rungs = study(&c.pipeline, &c.set, &parsed, &out, &*reporter(c.quiet))?;
    if !c.quiet {
        println!("{}", table(&rungs));
        eprintln!("wrote {}/accuracy.csv and accuracy.svg", out.display());
    }
    Ok(())
}
