//! Diagnostics on stderr through `tracing`, results on stdout. `-q` keeps only errors, `-v`
//! adds debug detail, `-vv` everything. Progress bars are diagnostics too: hidden under `-q`
//! (and by indicatif whenever stderr is not a terminal).
//!
//! Writing never panics (`println!` does on a closed pipe or a full disk):
//! - stdout goes through [`to_stdout`]: a reader that closed the pipe (`| head -1`) wants no
//!   more, so the rest of stdout is dropped quietly and the command goes on (exit 0); any other
//!   write error fails the command with one line (exit 1);
//! - a diagnostic that cannot be written (`2> /dev/full`) is dropped: there is nowhere to say
//!   so, and the exit status still tells how the run ended;
//! - every control character of a message (a line break included) is shown escaped
//!   ([`escape_controls`]), so a message is one line whatever a user put in a path, a URI or a
//!   name: a newline in a file name cannot forge a line of its own.

use std::borrow::Cow;
use std::fmt;

pub use parallax_render::console::{self, bar, result, spinner, stdout_error, to_stdout};
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

/// Installs the stderr logger for the whole process.
pub fn init(v: Verbosity) {
    console::set_quiet(v.quiet);
    // Fails only when a logger is already installed, which the binary never does twice.
    let _ = install(v, Level::INFO);
}

/// The stderr logger at `-q`: errors, `-v`: debug, `-vv`: all, else `default`.
fn install(v: Verbosity, default: Level) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let level = match (v.quiet, v.verbose) {
        (true, _) => Level::ERROR,
        (false, 0) => default,
        (false, 1) => Level::DEBUG,
        (false, _) => Level::TRACE,
    };
    tracing_subscriber::fmt()
        .with_max_level(level)
        .with_writer(std::io::stderr)
        // The default reports a failed write with `eprintln!`, which panics when stderr is the
        // thing that failed.
        .log_internal_errors(false)
        .event_format(Plain)
        .try_init()
}

/// `text` with every control character escaped as Rust writes it (`\n`, `\r`, `\t`,
/// `\u{1b}`): what a user-supplied string (a path, a URI, a name) becomes in a message, so
/// that the message stays one line and no escape sequence reaches the terminal.
pub fn escape_controls(text: &str) -> Cow<'_, str> {
    if !text.chars().any(char::is_control) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// Installs the stderr logger of a program that runs commands in-process
/// ([`crate::run_command`]), once: warnings and errors (`-q`: errors, `-v`: debug, `-vv`: all),
/// as the first call asks; a later call sets only whether progress bars are hidden. Result
/// lines become notes (shown from `-v`).
pub fn init_embedded(v: Verbosity) {
    console::set_quiet(v.quiet);
    console::set_embedded();
    // Fails only when a logger is already installed (by an earlier call, or by the host).
    let _ = install(v, Level::WARN);
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
        let mut message = String::new();
        ctx.field_format().format_fields(Writer::new(&mut message), event)?;
        w.write_str(prefix)?;
        w.write_str(&escape_controls(&message))?;
        writeln!(w)
    }
}
