//! Results on stdout and progress on stderr, for the library and the command line alike: the
//! command line sets `-q` and whether it runs inside another program ([`set_quiet`],
//! [`set_embedded`]); the frame loop, reports and outputs print through these.
//!
//! Writing never panics (`println!` does on a closed pipe or a full disk): stdout goes through
//! [`to_stdout`]: a reader that closed the pipe (`| head -1`) wants no more, so the rest of
//! stdout is dropped quietly and the command goes on (exit 0); any other write error fails the
//! command with one line (exit 1).

use std::io::Write as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

static QUIET: AtomicBool = AtomicBool::new(false);
/// Commands run inside another program ([`init_embedded`]).
static EMBEDDED: AtomicBool = AtomicBool::new(false);

/// `-q`: progress hidden, detail a person reads left out.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// The commands run inside another program: result lines become notes.
pub fn set_embedded() {
    EMBEDDED.store(true, Ordering::Relaxed);
}

/// Set once a reader closed stdout: nothing more is written there.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);
/// The first failed write of a result line (not a closed pipe), reported when the command ends.
static STDOUT_ERROR: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes `bytes` to stdout whole and flushes them. A closed pipe (EPIPE) is not an error: the
/// reader has all it wanted, so this and every later write to stdout is dropped quietly.
pub fn to_stdout(bytes: &[u8]) -> std::io::Result<()> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    match out.write_all(bytes).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            STDOUT_CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        other => other,
    }
}

/// Prints one result (a line, or a table): on stdout, or as a note on stderr when
/// stdout already carries a machine-readable output (`--json -`), which text would corrupt, or
/// when the command runs inside another program (which takes the results as values). A failed
/// write is kept for [`stdout_error`]: the command finishes its files first.
pub fn result(stdout_taken: bool, line: &str) {
    if stdout_taken || EMBEDDED.load(Ordering::Relaxed) {
        // A note per line: a message is one line (a table's line breaks would show escaped).
        line.lines().for_each(|l| tracing::info!("{l}"));
        return;
    }
    if let Err(e) = to_stdout(format!("{line}\n").as_bytes()) {
        let mut first = STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner());
        first.get_or_insert(e);
    }
}

/// The first result line that could not be written (a full disk, /dev/full), if any: the
/// command then ends with that error, exit 1.
pub fn stdout_error() -> Option<std::io::Error> {
    STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner()).take()
}

/// Whether `-q` was given: detail a person reads (the stage table) is left out, the one-line
/// results stay.
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// A spinner for work of unknown length (a GPU frame), ticking on its own.
pub fn spinner(message: String) -> ProgressBar {
    let bar = if QUIET.load(Ordering::Relaxed) {
        ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden())
    } else {
        ProgressBar::new_spinner()
    };
    bar.set_message(message);
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

/// A bar over `total` steps with the time left.
pub fn bar(total: u64) -> ProgressBar {
    if QUIET.load(Ordering::Relaxed) {
        return ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(total);
    if let Ok(style) = ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent}% ({eta} left)") {
        bar.set_style(style);
    }
    bar
}
