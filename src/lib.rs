//! The `parallax` command line as a library: the binary (`src/main.rs`) runs [`cli_main`], and
//! another program runs any command in-process with [`run_command`] (the Python module in
//! `python/`). The commands parse flags, call the libraries and print; renders run in
//! `parallax_render`, which a crate of its own calls directly (`examples/auto_exposure.rs`).

mod bench_matrix;
mod cmd_backend;
mod cmd_bench;
mod cmd_bench_rays;
mod cmd_chart;
mod cmd_compare;
mod cmd_plan;
mod cmd_reference;
mod cmd_render;
mod cmd_trace;
mod logging;
mod options;
mod pipeline_args;
mod run_file;
mod scene_args;

use std::ffi::OsString;

use parallax_render::outputs::pending;
use parallax_render::ranks;
#[cfg(feature = "mpi")]
use parallax_render::ranks::mpi as ranks_mpi;

use clap::{CommandFactory, Parser, Subcommand};

#[derive(Parser)]
#[command(name = "parallax", version, about = "Multi-GPU light-field path tracing as a render graph")]
struct Cli {
    #[command(flatten)]
    verbosity: logging::Verbosity,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Plan a light field over N devices: sources, δ-edges, per-device schedule, copies.
    Plan(cmd_plan::PlanArgs),
    /// Render a light field over N devices through the paper's reconstruction pipeline (G-buffer,
    /// sources path traced, targets reprojected, holes filled, SVGF, tonemap) or with every view
    /// path traced (`--pipeline path-trace`); writes the views (EXR, PNG), a contact sheet,
    /// viewer.html and render.json with per-stage GPU times.
    Render(cmd_render::RenderArgs),
    /// Path trace one view of a scene on the GPU (`--cpu`: the CPU reference) to EXR (+ PNG).
    Trace(cmd_trace::TraceArgs),
    /// List the Vulkan devices a selection would use (name, driver, API version).
    Devices(cmd_backend::DevicesArgs),
    /// Measure cross-device copy bandwidth and executor overhead.
    BenchCopy(cmd_backend::BenchCopyArgs),
    /// Measure GPU traversal: primary and diffuse-bounce rays/s, and the CWBVH build time.
    BenchRays(cmd_bench_rays::BenchRaysArgs),
    /// A matrix of renders (cases × pipelines × schemes × assignments × sources per set × spp ×
    /// denoise × devices; flags or a TOML file): frame times, stage table, busy fractions,
    /// missing pixels, hole filling and accuracy per cell.
    Bench(cmd_bench::BenchArgs),
    /// Path trace a converged reference of a light field's views, progressively and resumably
    /// (the camera is still: compare with `render --still`).
    Reference(cmd_reference::ReferenceArgs),
    /// PSNR, SSIM, FLIP and relMSE of two EXRs or two light-field folders, after checking that
    /// both were rendered with the same settings.
    Compare(cmd_compare::CompareArgs),
    /// Charts (SVG/PNG) of speed against accuracy, scaling, views, holes, or a device timeline.
    Chart(cmd_chart::ChartArgs),
}

/// Parses the command line and runs the command, exiting with its status: what the `parallax`
/// binary does.
pub fn cli_main() {
    let invocation: Vec<OsString> = std::env::args_os().collect();
    let cli = Cli::try_parse_from(&invocation).unwrap_or_else(|e| {
        if e.kind() == clap::error::ErrorKind::InvalidUtf8 {
            let message = options::non_utf8_argument(std::env::args_os());
            Cli::command().error(clap::error::ErrorKind::InvalidUtf8, message).exit();
        }
        if e.use_stderr() {
            e.exit()
        }
        // `--help` and `--version`: clap's own print ignores a failed write. Styled on a terminal
        // only, as clap styles it.
        let text = if std::io::IsTerminal::is_terminal(&std::io::stdout()) {
            e.render().ansi().to_string()
        } else {
            e.render().to_string()
        };
        match logging::to_stdout(text.as_bytes()) {
            Ok(()) => std::process::exit(0),
            Err(err) => {
                let _ = std::io::Write::write_all(
                    &mut std::io::stderr(),
                    format!("error: cannot write to stdout: {err}\n").as_bytes(),
                );
                std::process::exit(1)
            }
        }
    });
    logging::init(cli.verbosity);
    // Under mpirun, a render is one rank of several (a build with `--features mpi`).
    #[cfg(feature = "mpi")]
    if matches!(cli.command, Command::Render(_))
        && let Err(err) = ranks_mpi::join()
    {
        tracing::error!("{err:#}");
        std::process::exit(1);
    }
    // Ctrl-C, SIGTERM and SIGHUP end the process before any destructor runs: remove the
    // temporary files of outputs not yet in place and the folders the run created, so an
    // interrupted run leaves nothing behind.
    if let Err(err) = ctrlc::set_handler(|| {
        // Held until the process ends, so that the main thread creates nothing after this.
        let _pending = pending::remove_all();
        if ranks::speaks_for_run() {
            tracing::error!("interrupted: outputs not yet in place were removed");
        }
        std::process::exit(130);
    }) {
        tracing::debug!("no Ctrl-C handler ({err}): an interrupted run may leave a temporary file");
    }
    // The files are in place; results that could not be shown on stdout fail the command still.
    let result = execute(cli.command, &invocation).and_then(|()| match logging::stdout_error() {
        Some(e) => Err(anyhow::Error::new(e).context("cannot write the results to stdout")),
        None => Ok(()),
    });
    if let Err(err) = result {
        drop(pending::remove_all());
        // A rank whose failure rank 0 reports says nothing itself.
        #[cfg(feature = "mpi")]
        if err.is::<ranks_mpi::Reported>() {
            leave_ranks(1);
            std::process::exit(1);
        }
        // Flags that do not go together, or a value no run could use, are usage errors like
        // clap's own: same form, exit 2.
        if let Some(usage) = options::usage_error(&err) {
            let usage = logging::escape_controls(&usage).into_owned();
            let error = Cli::command().error(clap::error::ErrorKind::ArgumentConflict, usage);
            let _ = error.print();
            leave_ranks(2);
            std::process::exit(2);
        }
        tracing::error!("{err:#}");
        leave_ranks(1);
        std::process::exit(1);
    }
    leave_ranks(0);
}

/// Ends this process's part in a render over several ranks, if it has one, before it exits
/// with `code` ([`ranks_mpi::leave`]).
fn leave_ranks(code: i32) {
    #[cfg(feature = "mpi")]
    ranks_mpi::leave(code);
    let _ = code;
}

/// Runs one command; `invocation` is the whole command line (a `--config` run file's flags
/// give way to its own).
fn execute(command: Command, invocation: &[OsString]) -> anyhow::Result<()> {
    match command {
        Command::Plan(args) => cmd_plan::run(args),
        Command::Render(args) => cmd_render::run(args, invocation),
        Command::Trace(args) => cmd_trace::run(args),
        Command::Devices(args) => cmd_backend::devices(args),
        Command::BenchCopy(args) => cmd_backend::bench_copy(args),
        Command::BenchRays(args) => cmd_bench_rays::run(args),
        Command::Bench(args) => cmd_bench::run(args),
        Command::Reference(args) => cmd_reference::run(args),
        Command::Compare(args) => cmd_compare::run(args),
        Command::Chart(args) => cmd_chart::run(args),
    }
}

/// Why a command run by [`run_command`] failed: the message the binary prints after `error: `
/// and whether it is a usage error (the binary exits with 2) or a failed run (exit 1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    pub message: String,
    pub usage: bool,
}

/// Runs `parallax WORDS…` (the words after the program's name) inside this process, as the
/// binary does but returning its failure instead of printing it and exiting: how another
/// program (the Python module) drives the commands. Diagnostics go to stderr through a logger
/// installed by the first call, at warnings and errors (`-q`: errors only, `-v`: debug, with
/// the result lines a command prints, such as render's stage table), since the caller reads the
/// results from the outputs. No Ctrl-C handler is installed (the host has its own).
pub fn run_command<I, T>(words: I) -> Result<(), Failure>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString>,
{
    let invocation: Vec<OsString> =
        std::iter::once(OsString::from("parallax")).chain(words.into_iter().map(Into::into)).collect();
    let cli = match Cli::try_parse_from(&invocation) {
        Ok(cli) => cli,
        // `--help` and `--version` are answers, not failures.
        Err(e) if e.exit_code() == 0 => {
            print!("{e}");
            return Ok(());
        }
        Err(e) => return Err(Failure { message: clap_message(&e), usage: true }),
    };
    logging::init_embedded(cli.verbosity);
    execute(cli.command, &invocation).map_err(|err| {
        drop(pending::remove_all());
        match options::usage_error(&err) {
            Some(message) => Failure { message, usage: true },
            None => Failure { message: format!("{err:#}"), usage: false },
        }
    })
}

/// The command-line flags of a run file's settings (`{"spp": 4, "still": true}` → `--spp 4
/// --still`), as `render --config` reads them; `origin` begins each error message.
pub fn run_file_flags(
    origin: &str,
    settings: &serde_json::Map<String, serde_json::Value>,
) -> anyhow::Result<Vec<String>> {
    run_file::words_of(origin, settings)
}

/// Loads `--scene SPEC` as the commands do (`default`: the embedded scene), with the scene's own
/// lights, warning when it has none.
pub fn load_scene(spec: &str, allow_outside_files: bool) -> anyhow::Result<parallax_scene::Scene> {
    let args = scene_args::SceneArgs {
        scene: spec.into(),
        camera: None,
        sun: None,
        no_sun: false,
        sky: None,
        allow_outside_files,
    };
    args.load()
}

/// clap's error as one line without its `error: ` prefix, usage and tips: the message proper.
fn clap_message(e: &clap::Error) -> String {
    let text = e.to_string();
    text.split("\n\n").next().unwrap_or("").trim().trim_start_matches("error: ").to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_command_returns_the_cli_message_and_kind() {
        let bad_value = run_command(["render", "--resolution", "0x24"]).unwrap_err();
        assert_eq!(
            bad_value,
            Failure {
                message: "invalid value '0x24' for '--resolution <WxH>': width 0 is outside 1..=32768".into(),
                usage: true
            }
        );
        let conflict = run_command(["plan", "--scheme", "fine-all", "--assign", "compact"]).unwrap_err();
        assert!(conflict.usage && conflict.message.ends_with("drop --assign"), "{conflict:?}");
        let failed = run_command(["plan", "--lf", "4x2", "--fake-devices", "9"]).unwrap_err();
        assert!(
            !failed.usage && failed.message.starts_with("--gpus/--fake-devices 9 exceeds the 8 views"),
            "{failed:?}"
        );
        assert_eq!(run_command(["plan", "--help"]), Ok(()));
    }
}

/// README.md's Rust blocks compile and run as doctests: an example a reader pastes must build.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeExamples;
