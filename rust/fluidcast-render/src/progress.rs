//! How far a render is, and a request to stop it: shared between a render running on one
//! thread and a caller watching from another (the CLI's progress bar, the VTK mapper polling
//! VTK's abort check while a long frame renders).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Work units (bundles of the adaptive renderer, screen tiles of the reference ray caster)
/// done of those started, and whether the caller asked to stop. A renderer adds its units
/// with [`Progress::add_total`] when it starts and counts each with [`Progress::step`]; a
/// cancelled render skips its remaining units and returns [`crate::RenderError::Cancelled`].
#[derive(Debug, Default)]
pub struct Progress {
    done: AtomicU64,
    total: AtomicU64,
    cancel: AtomicBool,
}

impl Progress {
    /// Asks the render to stop as soon as it can (within one work unit per thread).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Whether [`Progress::cancel`] was called.
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// The share of the started work done, 0..=1 (0 before any started).
    pub fn fraction(&self) -> f64 {
        let total = self.total.load(Ordering::Relaxed);
        if total == 0 {
            return 0.0;
        }
        (self.done.load(Ordering::Relaxed) as f64 / total as f64).min(1.0)
    }

    /// A renderer starts `units` more units of work.
    pub fn add_total(&self, units: u64) {
        self.total.fetch_add(units, Ordering::Relaxed);
    }

    /// One unit done.
    pub fn step(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
    }
}

/// `progress`, or none: what a renderer checks between its units.
pub(crate) fn cancelled(progress: Option<&Progress>) -> bool {
    progress.is_some_and(Progress::cancelled)
}

/// A renderer starts `units` units of work watched by `progress` (if any).
pub(crate) fn start(progress: Option<&Progress>, units: usize) {
    if let Some(p) = progress {
        p.add_total(units as u64);
    }
}

/// One unit comes up: counts it, and says whether to do it (false once cancelled).
pub(crate) fn next(progress: Option<&Progress>) -> bool {
    if let Some(p) = progress {
        p.step();
    }
    !cancelled(progress)
}
