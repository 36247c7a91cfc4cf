//! Diagnostics on stderr through `tracing`, results on stdout. `-q` keeps only errors, `-v`
//! adds debug detail, `-vv` everything. Progress bars are diagnostics too: hidden under `-q`
//! (and by indicatif whenever stderr is not a terminal).

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::registry::LookupSpan;

/// `-q` / `-v`, global to every command.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Verbosity {
    /// More detail on stderr (-v debug, -vv trace).
    #[arg(short, long, global = true, action = clap::ArgAction::Count, display_order = 1000)]
    verbose: u8,
    /// Only errors on stderr: no progress, no notes, no warnings.
    #[arg(short, long, global = true, conflicts_with = "verbose", display_order = 1000)]
    quiet: bool,
}

static QUIET: AtomicBool = AtomicBool::new(false);
/// Commands run inside another program ([`init_embedded`]).
static EMBEDDED: AtomicBool = AtomicBool::new(false);

/// Installs the stderr logger for the whole process.
pub fn init(v: Verbosity) {
    let level = match (v.quiet, v.verbose) {
        (true, _) => Level::ERROR,
        (false, 0) => Level::INFO,
        (false, 1) => Level::DEBUG,
        (false, _) => Level::TRACE,
    };
    QUIET.store(v.quiet, Ordering::Relaxed);
    tracing_subscriber::fmt().with_max_level(level).with_writer(std::io::stderr).event_format(Plain).init();
}

/// Installs the stderr logger of a program that runs commands in-process
/// ([`crate::run_command`]), once: warnings and errors (`-q`: errors, `-v`: debug, `-vv`: all),
/// as the first call asks; a later call sets only whether progress bars are hidden. Result
/// lines become notes (shown from `-v`).
pub fn init_embedded(v: Verbosity) {
    let level = match (v.quiet, v.verbose) {
        (true, _) => Level::ERROR,
        (false, 0) => Level::WARN,
        (false, 1) => Level::DEBUG,
        (false, _) => Level::TRACE,
    };
    QUIET.store(v.quiet, Ordering::Relaxed);
    EMBEDDED.store(true, Ordering::Relaxed);
    // Fails only when a logger is already installed (by an earlier call, or by the host).
    let _ = tracing_subscriber::fmt().with_max_level(level).with_writer(std::io::stderr).event_format(Plain).try_init();
}

/// Messages as a compiler prints them: `error: …`, `warning: …`, notes without a prefix.
struct Plain;

impl<S, N> FormatEvent<S, N> for Plain
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(&self, ctx: &FmtContext<'_, S, N>, mut w: Writer<'_>, event: &Event<'_>) -> fmt::Result {
        let prefix = match *event.metadata().level() {
            Level::ERROR => "error: ",
            Level::WARN => "warning: ",
            Level::INFO => "",
            Level::DEBUG => "debug: ",
            Level::TRACE => "trace: ",
        };
        w.write_str(prefix)?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}

/// Prints one result line: on stdout, or as a note on stderr when stdout already carries a
/// machine-readable output (`--json -`), which text would corrupt, or when the command runs
/// inside another program (which takes the results as values).
pub fn result(stdout_taken: bool, line: &str) {
    if stdout_taken || EMBEDDED.load(Ordering::Relaxed) {
        tracing::info!("{line}");
    } else {
        println!("{line}");
    }
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
