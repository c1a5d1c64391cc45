//! The study runner's progress bar in a build without the `cli` feature
//! (no `indicatif`): it draws nothing.

/// A progress bar that draws nothing.
pub(crate) struct ProgressBar;

impl ProgressBar {
    /// Count `n` more finished cases (nothing to draw).
    pub(crate) fn inc(&self, _n: u64) {}
    /// Remove the bar (there is none).
    pub(crate) fn finish_and_clear(&self) {}
}

/// The silent bar, whatever `show` says.
pub(crate) fn progress_bar(_show: bool, _len: u64, _resumed: usize) -> ProgressBar {
    ProgressBar
}
