//! Slurm scripts for a study: a job array with one shard per array task
//! (`hbcontact study STUDY --shard $SLURM_ARRAY_TASK_ID/n`), and a merge job that runs after
//! every task has ended, failed or not (`--dependency=afterany`), joining the shards' records
//! into the same table a one-process run writes. `submit.sh` submits both.
//!
//! Paths in the scripts are absolute, so the jobs can start in any directory of a file system
//! the nodes share with the submitting machine.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// What the sbatch scripts ask Slurm for.
#[derive(Clone, Debug)]
pub struct SlurmOptions {
    /// Array tasks (shards).
    pub shards: usize,
    pub partition: Option<String>,
    /// Time limit of each task, e.g. `00:30:00`.
    pub time: Option<String>,
    /// Memory of each task, e.g. `2G`.
    pub mem: Option<String>,
    /// Cores per task (the shard runs that many points at once).
    pub cpus_per_task: usize,
    /// Pass `--trust-geometry` on to every job.
    pub trust_geometry: bool,
}

/// The scripts written.
#[derive(Clone, Debug)]
pub struct SlurmScripts {
    pub array: PathBuf,
    pub merge: PathBuf,
    pub submit: PathBuf,
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).map_err(|e| Error::io(p, e))
}

/// `'text'` for a shell, single quotes escaped.
fn quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', "'\\''"))
}

fn header(name: &str, o: &SlurmOptions, log: &Path) -> String {
    let mut s = format!(
        "#!/bin/bash\n#SBATCH --job-name={name}\n#SBATCH --output={}\n",
        log.display()
    );
    for (flag, value) in [
        ("partition", &o.partition),
        ("time", &o.time),
        ("mem", &o.mem),
    ] {
        if let Some(v) = value {
            let _ = writeln!(s, "#SBATCH --{flag}={v}");
        }
    }
    s
}

/// Write `slurm/array.sbatch`, `slurm/merge.sbatch` and `slurm/submit.sh` under `out`.
/// `set` are the command line's `--set` overrides, passed on to every job.
pub fn write_scripts(
    study_file: &Path,
    name: &str,
    out: &Path,
    set: &[String],
    o: &SlurmOptions,
) -> Result<SlurmScripts> {
    let exe = std::env::current_exe().map_err(|e| Error::io("hbcontact executable", e))?;
    let (study_file, out_abs) = (absolute(study_file)?, absolute(out)?);
    let cwd = std::env::current_dir().map_err(|e| Error::io(".", e))?;
    crate::output::staging::claim_entries(&out_abs, "study", &super::OWNED_ENTRIES)?;
    let dir = out_abs.join("slurm");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut common = format!(
        "{} --out {}",
        quote(&study_file.to_string_lossy()),
        quote(&out_abs.to_string_lossy())
    );
    for s in set {
        let _ = write!(common, " --set {}", quote(s));
    }
    if o.trust_geometry {
        common.push_str(" --trust-geometry");
    }
    let mut array = header(name, o, &dir.join("shard-%a.log"));
    let _ = write!(
        array,
        "#SBATCH --array=0-{}\n#SBATCH --cpus-per-task={}\ncd {}\nexec {} study {common} --quiet --shard \"${{SLURM_ARRAY_TASK_ID}}/{}\" --threads \"${{SLURM_CPUS_PER_TASK:-1}}\"\n",
        o.shards - 1,
        o.cpus_per_task,
        quote(&cwd.to_string_lossy()),
        quote(&exe.to_string_lossy()),
        o.shards
    );
    let mut merge = header(&format!("{name}-merge"), o, &dir.join("merge.log"));
    let _ = write!(
        merge,
        "cd {}\nexec {} study {common} --quiet --merge\n",
        quote(&cwd.to_string_lossy()),
        quote(&exe.to_string_lossy())
    );
    let submit = "#!/bin/bash\n# Submit the study's job array, then its merge job once every array task has ended.\n# Prints the merge job's id.\nset -euo pipefail\ncd \"$(dirname \"$0\")\"\narray=$(sbatch --parsable array.sbatch)\nsbatch --parsable --dependency=afterany:\"${array%%;*}\" merge.sbatch\n".to_string();
    let scripts = SlurmScripts {
        array: dir.join("array.sbatch"),
        merge: dir.join("merge.sbatch"),
        submit: dir.join("submit.sh"),
    };
    for (path, text) in [
        (&scripts.array, array),
        (&scripts.merge, merge),
        (&scripts.submit, submit),
    ] {
        std::fs::write(path, text).map_err(|e| Error::io(path, e))?;
        make_executable(path)?;
    }
    Ok(scripts)
}

fn make_executable(path: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    let perms = std::fs::Permissions::from_mode(0o755);
    std::fs::set_permissions(path, perms).map_err(|e| Error::io(path, e))
}
