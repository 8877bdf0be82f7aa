//! The `hbcontact` command. `main` is the only place that prints an error and picks the exit
//! code (`Error::exit_code`; `EXIT_CODES`, which `--help` lists: 0 success, 2 bad input, 3 a
//! model that cannot be solved as set up, 4 not converged, 5 writing failed, 6 a study with
//! failed points, 130 interrupted).

use std::path::PathBuf;
use std::process::ExitCode;

#[macro_use]
mod cli;

use clap::{Parser, Subcommand, ValueEnum};
use cli::interrupt::Keeps;
use hbcontact::output::staging::Replace;
use hbcontact::pipeline::load_pipeline;
use hbcontact::pipeline::{self, RunOptions};
use hbcontact::{Error, Reporter, Silent};

/// The exit codes, as `--help` lists them (docs/guide.md#exit-codes says the same, with what
/// to do about each).
const EXIT_CODES: &str = "\
Exit codes:
  0    success
  2    bad input: the pipeline, a study, the geometry, the mesh, gmsh, an output folder that
       is not ours (see --force), an unknown option
  3    a model that cannot be solved as set up (singular, resonant)
  4    the nonlinear solver did not converge (the message says what to change)
  5    writing results failed
  6    a study finished but some of its points failed (their errors are in study.csv)
  130  interrupted (Ctrl-C, SIGTERM, SIGHUP; a sweep first stops after its current point
       and writes the curve so far, `transient` stops its march and writes the whole periods
       marched, marked partial; the message names the stage and what was kept)";

#[derive(Parser)]
#[command(
    name = "hbcontact",
    version,
    about = "Periodic steady-state vibration of 2-D elastic bodies with unilateral contact, by harmonic-balance finite elements",
    after_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The pipeline a subcommand reads and how.
#[derive(clap::Args)]
struct Input {
    /// The pipeline YAML.
    pipeline: PathBuf,
    /// Override a pipeline value, e.g. `--set harmonic_balance.harmonics=20` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
    /// Let gmsh read the `.geo` as it is: without this, a geometry that runs programs
    /// (SystemCall, Shell, …), writes files (Printf > file, Save, …) or includes files outside
    /// its folder is refused (exit 2). Only for a geometry you wrote yourself.
    #[arg(long)]
    trust_geometry: bool,
}

/// A pipeline and the output folder a subcommand writes (each subcommand's help names its
/// default folder: `mut_arg("out", …)` below).
#[derive(clap::Args)]
struct Common {
    #[command(flatten)]
    input: Input,
    /// Write the results into DIR.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// When the output folder exists and holds files hbcontact did not write, move it aside
    /// to `<folder>.moved-<time>` instead of refusing (exit 2). Nothing is ever deleted.
    #[arg(long)]
    force: bool,
}

/// The pipeline the arguments name, with `--set` applied and `--trust-geometry` (which no
/// file can set).
fn load(c: &Input) -> hbcontact::Result<hbcontact::config::Pipeline> {
    let mut pipeline = load_pipeline(&c.pipeline, &c.set)?;
    pipeline.geometry.trusted = c.trust_geometry;
    Ok(pipeline)
}

/// The run options the shared arguments give.
fn run_options(c: &Common) -> RunOptions {
    RunOptions {
        out: c.out.clone(),
        replace: if c.force {
            Replace::MoveAside
        } else {
            Replace::IfOurs
        },
        ..Default::default()
    }
}

#[derive(Subcommand)]
enum Command {
    /// Compute the periodic steady state by harmonic balance, check a contact scene's state for
    /// stability (by time marching, or Floquet multipliers: `stability.method`;
    /// `--set stability.check=false` skips it) and write the results to `output.directory`
    /// (default `output/<name>`).
    #[command(mut_arg("out", |a| a.help("Write the results into DIR instead of `output.directory`")))]
    Run(Common),
    /// March in time from rest to the periodic state (the cross-check) and write the results
    /// to `<output.directory>-transient`, beside the harmonic-balance result. Ctrl-C stops the
    /// march and writes the whole periods marched, marked partial (exit 130).
    #[command(mut_arg("out", |a| a.help("Write the results into DIR instead of `<output.directory>-transient`")))]
    Transient(Common),
    /// A frequency-response curve through the folds contact makes (the pipeline's `sweep`
    /// block), written to `<output.directory>-sweep`: sweep.csv, sweep.json, the curve's plots,
    /// frames.pvd along it and full outputs at the folds, the peak and `sweep.write_at`. The
    /// points' stability is checked on both sides of each fold and every `stability.every`
    /// points (`--set stability.check=false` skips it). Ctrl-C stops it after the current
    /// point and writes the curve so far.
    #[command(mut_arg("out", |a| a.help("Write the sweep into DIR instead of `<output.directory>-sweep` (`--resume`: continue the one in DIR)")))]
    Sweep {
        #[command(flatten)]
        common: Common,
        /// Continue the sweep saved in the output folder from its last point (give the same
        /// pipeline, `--set` and `--out` as the sweep it continues).
        #[arg(long)]
        resume: bool,
    },
    /// Validate the pipeline and the geometry's groups without solving (writes nothing but
    /// the mesh cache).
    Check {
        #[command(flatten)]
        input: Input,
        /// Print the findings as JSON only (for scripts).
        #[arg(long)]
        json: bool,
    },
    /// What accuracy costs: run ladders of settings and tabulate error against wall time in
    /// `<output.directory>-accuracy` (accuracy.csv, accuracy.svg).
    #[command(mut_arg("quiet", |a| a.help("Print nothing but errors: not the accuracy table either (--tolerance's answer still prints)")))]
    Accuracy {
        #[command(flatten)]
        input: Input,
        /// Write accuracy.csv, accuracy.svg and the rungs' results into DIR instead of
        /// `<output.directory>-accuracy`.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// A ladder `key=v1,v2,...` (cheapest first; the last value is the reference), e.g.
        /// `harmonic_balance.harmonics=5,10,20,40` or `geometry.mesh_size=0.004,0.002,0.001`
        /// (repeatable). Default: harmonics H/4, H/2, H, 2H for contact scenes and element
        /// order 1, 2.
        #[arg(long = "ladder", value_name = "KEY=V1,V2,...")]
        ladders: Vec<String>,
        /// Compare with a time-marching run instead of each ladder's last rung.
        #[arg(long)]
        transient_reference: bool,
        /// Print the cheapest setting whose relative error is at most this, per measure.
        #[arg(long)]
        tolerance: Option<f64>,
    },
    /// Natural frequencies with the scene's supports (contact open), mode shapes as a VTU
    /// series and effective modal masses, written to `<output.directory>-modes`.
    #[command(mut_arg("out", |a| a.help("Write modes.pvd, the mode shapes and modes.json into DIR instead of `<output.directory>-modes`")))]
    Modes {
        #[command(flatten)]
        common: Common,
        /// How many modes, lowest first.
        #[arg(long, default_value_t = 10)]
        count: usize,
    },
    /// Differences between a harmonic-balance result and a time-marching one of the same
    /// scene (probe amplitudes, contact forces, harmonics), printed and written as
    /// compare.json and compare.csv into HB_DIR, with overlay plots of both in its plots/
    /// (compare_*.svg and .png).
    Compare {
        /// The `hbcontact run` result directory.
        hb_dir: PathBuf,
        /// The `hbcontact transient` result directory (`<dir>-transient`).
        transient_dir: PathBuf,
        /// Write compare.json, compare.csv and plots/compare_* into DIR instead of HB_DIR.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Print nothing but errors and the warnings that the two scenes differ.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Run a parameter study (studies/*.yaml): its points in parallel, or one shard of them,
    /// then study.csv, plots and manifest.json; `--slurm` writes a Slurm job array instead.
    Study(StudyArgs),
    /// Print the JSON Schema of a pipeline YAML (`pipeline`), summary.json (`summary`),
    /// modes.json (`modes`), compare.json (`compare`), a study file (`study`) or
    /// sweep.json (`sweep`).
    Schema {
        #[arg(value_enum)]
        which: SchemaKind,
    },
}

#[derive(clap::Args)]
struct StudyArgs {
    /// The study YAML (studies/*.yaml).
    study: PathBuf,
    /// Override a pipeline value for every point (repeatable), after the study's `set`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Results directory instead of the study's `out` (default output/<name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
    /// Points run at once (default: the study's `threads`, else one per core); more than
    /// the cores is cut to them, with a warning.
    #[arg(long)]
    threads: Option<usize>,
    /// Run one slice `i/n` of the points and write no table (a Slurm array task).
    #[arg(long, value_name = "I/N", conflicts_with = "merge")]
    shard: Option<String>,
    /// Join the shards' points into study.csv, plots and manifest.json (runs nothing).
    #[arg(long)]
    merge: bool,
    /// Write slurm/array.sbatch (one shard per array task), slurm/merge.sbatch and
    /// slurm/submit.sh under the results directory, and run nothing.
    #[arg(long, conflicts_with_all = ["shard", "merge"])]
    slurm: bool,
    /// Array tasks for --slurm.
    #[arg(long, default_value_t = 4)]
    shards: usize,
    /// Slurm partition (--slurm).
    #[arg(long)]
    partition: Option<String>,
    /// Slurm time limit per task, e.g. 00:30:00 (--slurm).
    #[arg(long)]
    time: Option<String>,
    /// Slurm memory per task, e.g. 2G (--slurm).
    #[arg(long)]
    mem: Option<String>,
    /// Cores per array task; each shard runs that many points at once (--slurm).
    #[arg(long, default_value_t = 1)]
    cpus_per_task: usize,
    /// Accuracy studies: print the cheapest setting within this relative error, per measure.
    #[arg(long)]
    tolerance: Option<f64>,
    /// Let gmsh read the points' `.geo` as it is (see `run --help`); only for a geometry you
    /// wrote yourself. Passed on to the jobs `--slurm` writes.
    #[arg(long)]
    trust_geometry: bool,
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
    /// A study YAML (docs/study.schema.json).
    Study,
    /// sweep.json (docs/sweep.schema.json).
    Sweep,
}

fn exit_code(e: &Error) -> u8 {
    e.exit_code()
}

/// Exit code after SIGINT, SIGTERM or SIGHUP (128 + SIGINT, the shell's convention).
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let cli = Cli::parse();
    // gmsh runs in its own process group (so that a timeout can kill all of it), which also
    // keeps a terminal's Ctrl-C from reaching it: kill it here before going. A failure to
    // install the handler leaves the parent-death signal, which still ends gmsh with us.
    let _ = ctrlc::set_handler(|| {
        if hbcontact::sweep::request_stop() {
            eprintln!("interrupted during the sweep: it stops after this point and writes the curve so far (again to quit at once)");
            return;
        }
        if hbcontact::transient::request_stop() {
            eprintln!("interrupted during the `march` stage: the march stops now and writes the whole periods marched as a partial result (again to quit at once)");
            return;
        }
        let gmsh = hbcontact::mesh::gmsh::kill_running();
        eprintln!("{}", cli::interrupt::message(gmsh));
        std::process::exit(INTERRUPTED);
    });
    let result = match &cli.command {
        Command::Run(c) => run(c, Mode::Run),
        Command::Sweep { common, resume } => sweep(common, *resume),
        Command::Transient(c) => run(c, Mode::Transient),
        Command::Check { input, json } => check(input, *json),
        Command::Accuracy {
            input,
            out,
            ladders,
            transient_reference,
            tolerance,
        } => accuracy(
            input,
            out.as_deref(),
            ladders,
            *transient_reference,
            *tolerance,
        ),
        Command::Study(args) => study(args),
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

/// The reporter a subcommand uses: nothing with `--quiet`, bars or lines otherwise; either
/// way the stage under way is noted for the message of an interruption.
fn reporter(quiet: bool) -> Box<dyn Reporter> {
    let shown: Box<dyn Reporter> = if quiet {
        Box::new(Silent)
    } else {
        Box::new(cli::reporter::Cli::new())
    };
    Box::new(cli::interrupt::Tracking(shown))
}

fn run(c: &Common, mode: Mode) -> hbcontact::Result<()> {
    let pipeline = load(&c.input)?;
    let mut options = run_options(c);
    let reporter = reporter(c.input.quiet);
    let result = match mode {
        Mode::Run => {
            let out = pipeline::output_dir(&pipeline, &options);
            cli::interrupt::keeps(Keeps::Folder(out));
            pipeline::run(&pipeline, &options, &*reporter)?
        }
        Mode::Transient => {
            let out = pipeline::transient_output_dir(&pipeline, &options);
            cli::interrupt::keeps(Keeps::Folder(out));
            options.keep_interrupted_march = true;
            pipeline::run_transient(&pipeline, &options, &*reporter)?
        }
    };
    if !c.input.quiet {
        cli::show_run(&result);
    }
    // An interrupted march wrote what it marched: exit 130, saying where.
    match result
        .summary
        .transient
        .as_ref()
        .and_then(|t| t.stopped.as_ref())
    {
        Some(stopped) => Err(Error::Interrupted(format!(
            "{}; the partial result is in {} (summary.json: transient.stopped)",
            stopped.reason,
            result.dir.display()
        ))),
        None => Ok(()),
    }
}

/// `hbcontact sweep [--resume]`: the folds, the end and what was written; a sweep that
/// failed part-way has written the curve so far and exits with its error's class.
fn sweep(c: &Common, resume: bool) -> hbcontact::Result<()> {
    let pipeline = load(&c.input)?;
    let options = run_options(c);
    let out = hbcontact::sweep::output_dir(&pipeline, &options);
    cli::interrupt::keeps(Keeps::Folder(out));
    let reporter = reporter(c.input.quiet);
    let result = if resume {
        hbcontact::sweep::resume(&pipeline, &options, &*reporter)?
    } else {
        hbcontact::sweep::run(&pipeline, &options, &*reporter)?
    };
    if !c.input.quiet {
        cli::show_sweep(&result);
    }
    match result.failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// `hbcontact check`: a readable list of what was found, or JSON only with `--json`.
fn check(c: &Input, json: bool) -> hbcontact::Result<()> {
    let pipeline = load(c)?;
    let report = pipeline::check(
        &pipeline,
        &RunOptions::default(),
        &*reporter(c.quiet || json),
    )?;
    if json {
        outln!("{}", to_json(&report)?);
    } else if !c.quiet {
        cli::show_check(&report);
        outln!("ok: {} is valid", c.pipeline.display());
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
        SchemaKind::Study => hbcontact::study::study_schema(),
        SchemaKind::Sweep => hbcontact::sweep::sweep_schema(),
    };
    outln!("{}", to_json(&schema)?);
    Ok(())
}

/// `hbcontact modes`: the table on stdout, the files in `<output.directory>-modes`.
fn modes(c: &Common, count: usize) -> hbcontact::Result<()> {
    let pipeline = load(&c.input)?;
    let options = run_options(c);
    let out = pipeline::modes::modes_output_dir(&pipeline, &options);
    cli::interrupt::keeps(Keeps::Folder(out));
    let result = pipeline::modes(&pipeline, &options, count, &*reporter(c.input.quiet))?;
    if !c.input.quiet {
        cli::show_modes(&result);
    }
    Ok(())
}

/// `hbcontact compare`: the differences on stdout, compare.json, compare.csv and the overlay
/// plots written.
fn compare(
    hb: &std::path::Path,
    transient: &std::path::Path,
    out: Option<&std::path::Path>,
    quiet: bool,
) -> hbcontact::Result<()> {
    let comparison = pipeline::compare::compare(hb, transient)?;
    // Even with --quiet: a comparison of two different scenes must not pass unnoticed.
    for w in &comparison.warnings {
        eprintln!("warning: {w}");
    }
    let dir = out.unwrap_or(hb);
    pipeline::compare::write(&comparison, dir)?;
    if !quiet {
        cli::show_compare(&comparison);
        eprintln!(
            "wrote {}/compare.json, compare.csv and the overlays plots/compare_*.svg (and .png)",
            dir.display()
        );
    }
    Ok(())
}

/// `hbcontact study`: run (or one shard, or merge, or write Slurm scripts).
fn study(a: &StudyArgs) -> hbcontact::Result<()> {
    use hbcontact::study::{self, Shard, StudyOptions};
    let spec = study::load_study(&a.study, &a.set)?;
    let bad = |message: String| Error::Config {
        path: a.study.clone(),
        message,
    };
    if a.threads == Some(0) {
        return Err(bad("--threads: at least 1".into()));
    }
    let options = StudyOptions {
        out: a.out.clone(),
        threads: a.threads,
        trust_geometry: a.trust_geometry,
        shard: a
            .shard
            .as_deref()
            .map(Shard::parse)
            .transpose()
            .map_err(bad)?,
    };
    if a.slurm {
        return slurm(a, &spec, &options);
    }
    cli::interrupt::keeps(Keeps::Study(study::output_dir(&spec, &options)));
    let report = if a.merge {
        study::merge(&spec, &options)?
    } else {
        study::run(&spec, &options, &*reporter(a.quiet))?
    };
    if !a.quiet {
        if let Some(acc) = &report.accuracy {
            cli::study::show_accuracy(acc);
        }
        cli::study::show_study(&report);
    }
    if let (Some(acc), Some(t)) = (&report.accuracy, a.tolerance) {
        cli::study::show_tolerance(acc, t);
    }
    report.complete().map(|_| ())
}

fn slurm(
    a: &StudyArgs,
    spec: &hbcontact::study::Study,
    options: &hbcontact::study::StudyOptions,
) -> hbcontact::Result<()> {
    use hbcontact::study::slurm::{write_scripts, SlurmOptions};
    if a.shards == 0 || a.cpus_per_task == 0 {
        return Err(Error::Config {
            path: a.study.clone(),
            message: "--shards and --cpus-per-task: at least 1".into(),
        });
    }
    hbcontact::study::plan::plan(spec)?;
    let out = hbcontact::study::output_dir(spec, options);
    let o = SlurmOptions {
        shards: a.shards,
        partition: a.partition.clone(),
        time: a.time.clone(),
        mem: a.mem.clone(),
        cpus_per_task: a.cpus_per_task,
        trust_geometry: a.trust_geometry,
    };
    let scripts = write_scripts(&a.study, &spec.name, &out, &a.set, &o)?;
    if !a.quiet {
        eprintln!(
            "wrote {}, {} and {}; submit with: bash {}",
            scripts.array.display(),
            scripts.merge.display(),
            scripts.submit.display(),
            scripts.submit.display()
        );
    }
    Ok(())
}

/// `--ladder key=v1,v2,...` into a ladder of numbers.
fn ladder(path: &std::path::Path, l: &str) -> hbcontact::Result<hbcontact::study::spec::Ladder> {
    let bad = || {
        Error::Config {
        path: path.to_path_buf(),
        message: format!(
            "--ladder {}: expected KEY=V1,V2,... of numbers (e.g. harmonic_balance.harmonics=5,10,20)",
            hbcontact::error::excerpt(l)
        ),
    }
    };
    let (key, values) = l.split_once('=').ok_or_else(bad)?;
    let values = values
        .split(',')
        .map(str::trim)
        .filter(|v| !v.is_empty())
        .map(|v| v.parse::<f64>().map_err(|_| bad()))
        .collect::<hbcontact::Result<Vec<f64>>>()?;
    Ok(hbcontact::study::spec::Ladder {
        key: key.trim().to_string(),
        values,
    })
}

/// `hbcontact accuracy`: the accuracy study `study::accuracy::from_ladders` builds from the
/// command line, run, and its table shown.
fn accuracy(
    c: &Input,
    out: Option<&std::path::Path>,
    ladders: &[String],
    transient_reference: bool,
    tolerance: Option<f64>,
) -> hbcontact::Result<()> {
    use hbcontact::study::spec::Reference;
    use hbcontact::study::{self, StudyOptions};
    let pipeline = load(c)?;
    let parsed = ladders
        .iter()
        .map(|l| ladder(&c.pipeline, l))
        .collect::<hbcontact::Result<Vec<_>>>()?;
    let reference = if transient_reference {
        Reference::Transient
    } else {
        Reference::Finest
    };
    let spec = study::accuracy::from_ladders(&pipeline, &c.set, parsed, reference, out)?;
    let options = StudyOptions {
        trust_geometry: c.trust_geometry,
        ..StudyOptions::default()
    };
    cli::interrupt::keeps(Keeps::Study(spec.out.clone()));
    let report = study::run(&spec, &options, &*reporter(c.quiet))?;
    if let Some(acc) = &report.accuracy {
        if !c.quiet {
            cli::study::show_accuracy(acc);
            eprintln!("wrote {}/accuracy.csv and accuracy.svg", spec.out.display());
        }
        if let Some(t) = tolerance {
            cli::study::show_tolerance(acc, t);
        }
    }
    report.complete().map(|_| ())
}
