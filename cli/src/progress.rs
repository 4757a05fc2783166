//! Progress bars for long work (hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `total` steps labelled `what`.
pub fn bar(total: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(total);
    pb.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({elapsed}, eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Runs `work` under a bar of `total` steps; `work` reports the steps done so far.
pub fn with_bar<T>(total: usize, what: &str, work: impl FnOnce(&(dyn Fn(usize) + Sync)) -> T) -> T {
    let pb = bar(total as u64, what);
    let out = work(&|n| pb.set_position(n as u64));
    pb.finish_and_clear();
    out
}
