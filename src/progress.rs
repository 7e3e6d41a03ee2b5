//! How a long computation reports its progress and learns that it should stop.
//!
//! The caller passes a [`Progress`]; the core calls [`Progress::report`] at every phase change
//! and often within a phase, and returns [`Cancelled`] soon after [`Progress::cancelled`] turns
//! true: the matrix fill checks once per row block, the transforms once per row, the solve once per
//! sweep, so that a cancel takes effect well within a second.

use serde::Serialize;

/// The phases of a job, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    Queued,
    Projection,
    Transform,
    Refinement,
    Solve,
    Reference,
    Metrics,
    Render,
    Done,
}

impl Phase {
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            Phase::Queued => "queued",
            Phase::Projection => "projection",
            Phase::Transform => "transform",
            Phase::Refinement => "refinement",
            Phase::Solve => "solve",
            Phase::Reference => "reference",
            Phase::Metrics => "metrics",
            Phase::Render => "render",
            Phase::Done => "done",
        }
    }
}

/// The job was cancelled through its [`Progress`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

pub trait Progress: Sync {
    /// `fraction` of `phase` is done (0 to 1).
    fn report(&self, phase: Phase, fraction: f64);
    /// Whether the caller asked the computation to stop.
    fn cancelled(&self) -> bool;

    /// `Err(Cancelled)` once cancelled: use with `?` at every check point.
    fn check(&self) -> Result<(), Cancelled> {
        if self.cancelled() {
            Err(Cancelled)
        } else {
            Ok(())
        }
    }
}

/// Reports nowhere and never cancels.
pub struct Silent;

impl Progress for Silent {
    fn report(&self, _: Phase, _: f64) {}
    fn cancelled(&self) -> bool {
        false
    }
}
