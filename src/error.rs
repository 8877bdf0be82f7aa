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

    /// Writing results failed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

pub type Result<T> = std::result::Result<T, Error>;

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

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
