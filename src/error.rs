//! The library's error type: every variant names the file, group, field or value at fault and,
//! where there is one, the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A pipeline file could not be read or does not describe a valid scene.
    #[error("{path}: {message}")]
    Config { path: PathBuf, message: String },

    /// Bad input that is not tied to one file's line: a group or value the pipeline names does
    /// not fit the mesh (the message names the pipeline field). Exit code 2, like `Config`.
    #[error("{0}")]
    Input(String),

    /// gmsh could not be found or failed.
    #[error("gmsh: {0}")]
    Gmsh(String),

    /// A .msh file could not be read or holds something we cannot use.
    #[error("{path}: {message}")]
    Mesh { path: PathBuf, message: String },

    /// The model as set up cannot be solved (singular matrix, missing group, bad parameter).
    #[error("{0}")]
    Model(String),

    /// The nonlinear solver stopped without converging; the message says what to change.
    #[error("{0}")]
    NotConverged(String),

    /// An error from one stage of a pipeline run: says which pipeline and which stage.
    #[error("{} (stage `{stage}`): {source}", pipeline.display())]
    InStage {
        pipeline: PathBuf,
        stage: String,
        #[source]
        source: Box<Error>,
    },

    /// Writing results failed (a full disk says so: `describe_io`).
    #[error("{}", describe_io(path, source))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// The user interrupted a command that stops cleanly (a sweep, which writes the curve so
    /// far). Exit code 130, as for an interrupt that ends the process at once.
    #[error("{0}")]
    Interrupted(String),

    /// A study finished, but some of its points failed (each with its error in the table).
    #[error("{failed} of {total} study points failed; their errors are in {}", table.display())]
    StudyIncomplete {
        failed: usize,
        total: usize,
        table: PathBuf,
    },
}

pub type Result<T> = std::result::Result<T, Error>;

/// Whether an I/O error means the disk (or the user's quota on it) is full: ENOSPC
/// (`StorageFull`) or EDQUOT (`QuotaExceeded`).
pub fn is_disk_full(e: &std::io::Error) -> bool {
    use std::io::ErrorKind;
    matches!(e.kind(), ErrorKind::StorageFull | ErrorKind::QuotaExceeded)
        || matches!(e.raw_os_error(), Some(libc::ENOSPC | libc::EDQUOT))
}

/// `path: error`, or for a full disk what happened and what to do: free space on the disk
/// that holds `path`, or write elsewhere.
pub fn describe_io(path: &std::path::Path, e: &std::io::Error) -> String {
    if is_disk_full(e) {
        format!(
            "{}: the disk is full ({e}): nothing more can be written there; free space on the disk that holds it (or your quota there), or write the results to another disk (--out or output.directory)",
            path.display()
        )
    } else {
        format!("{}: {e}", path.display())
    }
}

impl Error {
    /// The error with the pipeline and stage it came from (an error that already names the
    /// pipeline file is left as it is).
    pub fn in_stage(self, pipeline: &std::path::Path, stage: &str) -> Self {
        match &self {
            Error::InStage { .. } => self,
            Error::Config { path, .. } if path == pipeline => self,
            _ => Error::InStage {
                pipeline: pipeline.to_path_buf(),
                stage: stage.to_string(),
                source: Box::new(self),
            },
        }
    }

    /// The error beneath any stage context: its variant is the error's class.
    pub fn root(&self) -> &Error {
        match self {
            Error::InStage { source, .. } => source.root(),
            e => e,
        }
    }

    /// The process exit code for this error: 2 bad input (pipeline, study, geometry, mesh,
    /// gmsh), 3 a model that cannot be solved, 4 not converged, 5 writing results failed,
    /// 6 a study in which some points failed, 130 interrupted.
    pub fn exit_code(&self) -> u8 {
        match self.root() {
            Error::Config { .. } | Error::Input(_) | Error::Gmsh(_) | Error::Mesh { .. } => 2,
            Error::Model(_) => 3,
            Error::NotConverged(_) => 4,
            Error::Io { .. } => 5,
            Error::StudyIncomplete { .. } => 6,
            Error::Interrupted(_) => 130,
            Error::InStage { .. } => 1,
        }
    }

    /// The error's class as a study table names it (`bad_input`, `model`, `not_converged`,
    /// `io`, `study_incomplete`, `interrupted`), one per exit code.
    pub fn class(&self) -> &'static str {
        match self.exit_code() {
            2 => "bad_input",
            3 => "model",
            4 => "not_converged",
            5 => "io",
            6 => "study_incomplete",
            130 => "interrupted",
            _ => "internal",
        }
    }

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// The longest piece of user input an error message quotes.
pub const EXCERPT_CHARS: usize = 80;

/// At most `EXCERPT_CHARS` characters of `s`, with "… (N characters)" when it is longer: an
/// error names a bad value without echoing all of it.
pub fn excerpt(s: &str) -> String {
    let n = s.chars().count();
    if n <= EXCERPT_CHARS {
        s.to_string()
    } else {
        let head: String = s.chars().take(EXCERPT_CHARS).collect();
        format!("{head}… ({n} characters)")
    }
}

/// `message` with every "…" or `…` quoted part longer than `EXCERPT_CHARS` cut to an excerpt
/// (serde quotes the offending input), and the whole cut to a few thousand characters.
pub fn shorten_quoted(message: &str) -> String {
    let chars: Vec<char> = message.chars().collect();
    let mut out = String::with_capacity(message.len().min(4096));
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        out.push(c);
        i += 1;
        if c == '"' || c == '`' {
            if let Some(len) = chars[i..].iter().position(|&d| d == c) {
                let inner: String = chars[i..i + len].iter().collect();
                // Leave an excerpt (80 characters and its length note) as it is.
                if len > EXCERPT_CHARS + 30 {
                    out.push_str(&excerpt(&inner));
                } else {
                    out.push_str(&inner);
                }
                out.push(c);
                i += len + 1;
            }
        }
    }
    let n = out.chars().count();
    if n > 4000 {
        let head: String = out.chars().take(4000).collect();
        format!("{head}… (message cut, {n} characters)")
    } else {
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// TEST GOAL: a write that fails because the disk is full (ENOSPC, as a raw OS error or as
    /// `StorageFull`, or EDQUOT) says the disk is full, names the path and says what to do,
    /// with exit code 5; any other I/O error reads as before, `path: error`.
    #[test]
    fn a_full_disk_says_so_naming_the_path() {
        let path = std::path::Path::new("out/run/frames/frame_0003.vtu");
        for e in [
            std::io::Error::from_raw_os_error(libc::ENOSPC),
            std::io::Error::from_raw_os_error(libc::EDQUOT),
            std::io::Error::new(std::io::ErrorKind::StorageFull, "no room"),
        ] {
            let error = Error::io(path, e);
            let text = error.to_string();
            assert!(
                text.starts_with("out/run/frames/frame_0003.vtu: the disk is full (")
                    && text.contains("free space on the disk that holds it")
                    && text.contains("--out"),
                "{text}"
            );
            assert_eq!(error.exit_code(), 5);
        }
        let other = Error::io(path, std::io::Error::from_raw_os_error(libc::EACCES));
        assert_eq!(
            other.to_string(),
            format!(
                "out/run/frames/frame_0003.vtu: {}",
                std::io::Error::from_raw_os_error(libc::EACCES)
            )
        );
    }
}
