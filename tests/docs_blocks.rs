//! Every shell block of README.md and docs/*.md runs as written, in order, in a fresh folder that
//! holds nothing but a link to the clone's `tests/` (its scenes), the way a new user pastes them
//! (issue 40). Only the sizes are cut (tests/docs_shim/docs_shim.py: `--resolution` to 32 pixels
//! a side, `--spp`, `--frames`, …, and `--gpus N` to N lavapipe devices), so a block that names a
//! file nothing made, a flag that does not exist or a value a command refuses fails here.
//!
//! Fences say what they hold: `sh` blocks run here, `python` blocks in python/tests/test_docs.py
//! (they need the module built), `rust` blocks as doctests (src/lib.rs includes README.md, scene/src/lib.rs docs/UPSTREAM.md),
//! `text` is output, a template with placeholders (`BASE/parallax`, `$SP`) or a `cargo test` of the
//! suite itself, and `sh setup` is one of the two set-up
//! commands (`.ci/main.sh`, `.ci/test.sh`) or the Python module's install, which CI runs itself.
//! A block that reads `../shared/` (the scenes beside the clone) runs only where that folder
//! exists, as the `#[ignore]`d Sponza tests do.
//!
//! Built only with `--features mpi` (`.ci/test.sh` runs it so): the MPI block's `mpirun` needs the
//! binary that speaks MPI.
#![cfg(feature = "mpi")]

mod common;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;

/// A block that runs longer than this hangs: every block here renders tiny images.
const BLOCK_GUARD: Duration = Duration::from_secs(600);

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// One fenced block: its info string's words, the line of its opening fence and its text.
struct Block {
    info: Vec<String>,
    line: usize,
    text: String,
}

fn blocks(markdown: &str) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut open: Option<Block> = None;
    for (i, line) in markdown.lines().enumerate() {
        let Some(info) = line.strip_prefix("```") else {
            if let Some(block) = open.as_mut() {
                block.text.push_str(line);
                block.text.push('\n');
            }
            continue;
        };
        match open.take() {
            Some(block) => blocks.push(block),
            None => {
                open = Some(Block {
                    info: info.split_whitespace().map(str::to_string).collect(),
                    line: i + 1,
                    text: String::new(),
                })
            }
        }
    }
    assert!(open.is_none(), "a fence is never closed");
    blocks
}

/// README.md and every docs/*.md.
fn documents() -> Vec<PathBuf> {
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    docs.insert(0, root().join("README.md"));
    docs
}

/// Every fence names what it holds, from the kinds this test knows how to treat.
#[test]
fn every_fence_says_what_it_holds() {
    for doc in documents() {
        for block in blocks(&std::fs::read_to_string(&doc).unwrap()) {
            let kind = block.info.iter().map(String::as_str).collect::<Vec<_>>();
            assert!(
                matches!(
                    kind.as_slice(),
                    ["sh"] | ["sh", "setup"] | ["python"] | ["rust"] | ["rust", "should_panic"] | ["text"]
                ),
                "{}:{}: fence ```{}: use sh, sh setup, python, rust, rust should_panic or text",
                doc.display(),
                block.line,
                kind.join(" ")
            );
        }
    }
}

/// The set-up blocks are the two commands of "Two commands" and the module's install, nothing
/// more: a block marked so to dodge this test would show here.
#[test]
fn only_the_set_up_commands_are_left_to_ci() {
    let mut setup = Vec::new();
    for doc in documents() {
        for block in blocks(&std::fs::read_to_string(&doc).unwrap()) {
            if block.info == ["sh", "setup"] {
                setup.extend(
                    block
                        .text
                        .lines()
                        .filter_map(|l| l.split('#').next())
                        .map(str::trim)
                        .filter(|l| !l.is_empty())
                        .map(str::to_string),
                );
            }
        }
    }
    assert_eq!(
        setup,
        [
            "bash .ci/main.sh",
            "bash .ci/test.sh",
            "python3 -m venv .venv && . .venv/bin/activate",
            "pip install ./python"
        ]
    );
}

fn shared_scenes() -> PathBuf {
    root().join("../shared")
}

/// Runs `doc`'s shell blocks in order in one fresh folder; panics with the first failure's
/// block, exit status and output.
fn run_shell_blocks(doc: &str) {
    let markdown = std::fs::read_to_string(root().join(doc)).unwrap();
    let scratch = common::scratch("docs", &doc.replace('/', "_"));
    // The clone the blocks run in, with `../shared` beside it as CI has it.
    let clone = scratch.join("clone");
    std::fs::create_dir_all(clone.join("target/release")).unwrap();
    let shim = root().join("tests/docs_shim");
    std::os::unix::fs::symlink(root().join("tests"), clone.join("tests")).unwrap();
    std::os::unix::fs::symlink(shim.join("parallax"), clone.join("target/release/parallax")).unwrap();
    let shared = shared_scenes().is_dir();
    if shared {
        std::os::unix::fs::symlink(shared_scenes().canonicalize().unwrap(), scratch.join("shared")).unwrap();
    }
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_parallax"));
    let examples = bin.parent().unwrap().join("examples");
    let path = format!("{}:{}", shim.display(), std::env::var("PATH").unwrap_or_default());
    let mut ran = 0;
    for block in blocks(&markdown).into_iter().filter(|b| b.info == ["sh"]) {
        if block.text.contains("../shared/") && !shared {
            eprintln!("{doc}:{}: reads ../shared/, which is not beside this clone: not run", block.line);
            continue;
        }
        let (stdout, stderr) = (scratch.join("stdout"), scratch.join("stderr"));
        let mut child = Command::new("bash")
            .args(["-euo", "pipefail", "-c", &block.text])
            .current_dir(&clone)
            .env("PATH", &path)
            .env("PARALLAX_DOCS_BIN", &bin)
            .env("PARALLAX_DOCS_EXAMPLES", &examples)
            // CI runs as root on two cores: mpirun refuses both unless told.
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
            .stdin(Stdio::null())
            // Files, not pipes: a block's output may outgrow a pipe's buffer before it ends.
            .stdout(std::fs::File::create(&stdout).unwrap())
            .stderr(std::fs::File::create(&stderr).unwrap())
            // Its own process group, so that a hung block is stopped with every command it started.
            .process_group(0)
            .spawn()
            .unwrap();
        let start = Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if start.elapsed() > BLOCK_GUARD {
                let _ = killpg(Pid::from_raw(child.id() as i32), Signal::SIGKILL);
                let _ = child.wait();
                panic!("{doc}:{}: the block ran past {BLOCK_GUARD:?}:\n{}", block.line, block.text);
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        assert!(
            status.success(),
            "{doc}:{}: the block failed ({status}):\n{}\n--- stdout\n{}\n--- stderr\n{}",
            block.line,
            block.text,
            std::fs::read_to_string(&stdout).unwrap_or_default(),
            std::fs::read_to_string(&stderr).unwrap_or_default()
        );
        ran += 1;
    }
    eprintln!("{doc}: {ran} shell block(s) ran");
}

#[test]
fn readme_shell_blocks_run_as_written() {
    run_shell_blocks("README.md");
}

#[test]
fn results_shell_blocks_run_as_written() {
    run_shell_blocks("docs/RESULTS.md");
}

/// No document's shell blocks are left out of the two tests above.
#[test]
fn every_document_with_shell_blocks_is_run() {
    for doc in documents() {
        let name = doc.strip_prefix(root()).unwrap().to_string_lossy().into_owned();
        let has_sh = blocks(&std::fs::read_to_string(&doc).unwrap()).iter().any(|b| b.info == ["sh"]);
        assert!(
            !has_sh || ["README.md", "docs/RESULTS.md"].contains(&name.as_str()),
            "{name} has shell blocks no test runs"
        );
    }
}
