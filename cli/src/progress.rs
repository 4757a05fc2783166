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

/// Runs `work` under a bar whose length `work` reports with each step, as (done, total).
pub fn with_sized_bar<T>(what: &str, work: impl FnOnce(&dyn Fn(usize, usize)) -> T) -> T {
    let pb = bar(0, what);
    let out = work(&|done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    });
    pb.finish_and_clear();
    out
}

/// Runs `work` under a spinner labelled `what` that shows the time spent, for work whose
/// steps are not counted (timing a bake's sample).
pub fn with_spinner<T>(what: &str, work: impl FnOnce() -> T) -> T {
    let pb = ProgressBar::new_spinner();
    pb.set_style(ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("valid template"));
    pb.set_message(what.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    let out = work();
    pb.finish_and_clear();
    out
}
