//! What a command prints, kept for its report page: `say!` prints a line
//! to stdout and keeps it; [`take`] hands the kept lines to the page.
//! Also a spinner with the elapsed time for steps that take seconds.

use std::sync::Mutex;
use std::time::Duration;

static LINES: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Prints `line` and keeps it for the page.
pub fn keep_line(line: String) {
    println!("{line}");
    LINES.lock().unwrap_or_else(|e| e.into_inner()).push(line);
}

/// The lines kept so far (and forgets them).
pub fn take() -> Vec<String> {
    std::mem::take(&mut *LINES.lock().unwrap_or_else(|e| e.into_inner()))
}

/// `println!` that also keeps the line for the report page.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cmd::transcript::keep_line(format!($($arg)*))
    };
}
pub(crate) use say;

/// Runs `work` under a spinner that says `what` and the seconds elapsed
/// (on stderr, hidden when it is not a terminal).
pub fn with_spinner<T>(what: &str, work: impl FnOnce() -> T) -> T {
    let bar = indicatif::ProgressBar::new_spinner().with_message(what.to_string());
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    bar.enable_steady_tick(Duration::from_millis(200));
    let out = work();
    bar.finish_and_clear();
    tracing::info!("{what}: done in {:.1} s", bar.elapsed().as_secs_f64());
    out
}
