//! How the library tells its caller what it is doing, without ever printing: every long stage
//! takes a `&dyn Reporter` and calls it; the command line draws progress bars from the calls,
//! tests and studies pass `Silent`.

/// Receives progress and warnings from the stages. Every method has an empty default, so a
/// reporter implements only what it shows.
pub trait Reporter: Sync {
    /// A named stage starts (`mesh`, `assemble`, `solve`, `march`, `write`, …).
    fn stage(&self, _name: &str) {}
    /// The stage ended after `seconds`.
    fn stage_done(&self, _name: &str, _seconds: f64) {}
    /// A long task advanced: `done` of `total` steps (`None`: unknown), with a short status
    /// (e.g. task "contact Newton", status "residual 3.1e-4, 212 active samples").
    fn progress(&self, _task: &str, _done: u64, _total: Option<u64>, _status: &str) {}
    /// The task ended (a bar can be cleared).
    fn task_done(&self, _task: &str) {}
    /// Something the user should know although the run goes on.
    fn warning(&self, _message: &str) {}
}

/// Reports nothing.
pub struct Silent;

impl Reporter for Silent {}
