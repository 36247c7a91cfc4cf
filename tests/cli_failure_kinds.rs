//! The failure kinds of issue 30 that concern reading, writing and reporting: a failed write to
//! stdout or stderr (kind 1), reads that skipped the regular-file and size checks (5), run-file
//! floats that are not finite (6), `compare` scoring overflowed tonemapping (7), charts
//! quadratic in their points (8), exit codes, paths that are not UTF-8 and control characters
//! in messages (12), an output folder moved during a run (13) and `--layers` of a pipeline
//! without a G-buffer (14). Each run has a hang guard (a deadline far above its time) and, where
//! it reads a special file, a memory cap, so a regression fails the test instead of taking the
//! machine down.

mod common;

use common::{HANG_GUARD, capped_command, scratch, wait_or_kill, write_gltf};

use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Address space of a capped run: far less than reading /dev/zero or a 1 GB file would take.
const MEMORY_CAP_KIB: u64 = 4 << 20;

/// The binary with `args` in `dir`, under the memory cap, stdin closed.
fn parallax_cmd<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> Command {
    capped_command(dir, MEMORY_CAP_KIB, args)
}

/// Runs `args` in `dir` to the end, under the memory cap and the deadline.
fn run<S: AsRef<OsStr> + std::fmt::Debug>(dir: &Path, args: &[S]) -> Output {
    wait_or_kill(parallax_cmd(dir, args).spawn().unwrap(), &format!("{args:?}"))
}

/// Asserts exit `code` and that stderr is exactly `line` (one line, no panic).
fn refused_with<S: AsRef<OsStr> + std::fmt::Debug>(dir: &Path, args: &[S], code: i32, line: &str) {
    let out = run(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
    assert_eq!(stderr.lines().next(), Some(line), "{args:?}");
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
}

fn stderr_of(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// Kind 1: a full stdout fails the command with one line (exit 1) after its files are in place,
/// a closed pipe ends stdout quietly (exit 0), and a full stderr loses the diagnostics only.
#[test]
fn write_errors_to_stdout_and_stderr_never_panic() {
    let dir = scratch("failure-kinds", "stdio");
    let full = || Stdio::from(std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap());
    let with_stdout = |args: &[&str], stdout: Stdio| {
        wait_or_kill(parallax_cmd(&dir, args).stdout(stdout).spawn().unwrap(), &format!("{args:?}"))
    };
    let out = with_stdout(&["plan", "--lf", "8x4"], full());
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stderr_of(&out), "error: cannot write the results to stdout: No space left on device (os error 28)\n");
    let out = with_stdout(&["--help"], full());
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stderr_of(&out), "error: cannot write to stdout: No space left on device (os error 28)\n");
    // A reader that has gone: the pipe's read end is closed before the command writes a byte.
    for args in [&["plan", "--lf", "64x64"][..], &["plan", "--lf", "4x1", "--json", "-"], &["devices"]] {
        let mut child = parallax_cmd(&dir, args).spawn().unwrap();
        drop(child.stdout.take());
        let out = wait_or_kill(child, &format!("{args:?}"));
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", stderr_of(&out));
        assert!(!stderr_of(&out).contains("panicked") && !stderr_of(&out).contains("error"), "{}", stderr_of(&out));
    }
    // render: the outputs are written, then the results cannot be: exit 1, everything in place.
    let render = ["render", "--lf", "2x1", "--resolution", "4x4", "--fake-devices", "1", "--out-dir"];
    let out = with_stdout(&[&render[..], &["full"]].concat(), full());
    assert_eq!(out.status.code(), Some(1), "{}", stderr_of(&out));
    assert!(
        stderr_of(&out).ends_with("error: cannot write the results to stdout: No space left on device (os error 28)\n"),
        "{}",
        stderr_of(&out)
    );
    assert!(dir.join("full/render.json").is_file() && dir.join("full/view_001.exr").is_file());
    // Diagnostics that cannot be written are dropped; the run is not disturbed.
    let out = wait_or_kill(
        parallax_cmd(&dir, &[&render[..], &["quiet"]].concat()).stderr(full()).spawn().unwrap(),
        "render 2> /dev/full",
    );
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("wrote 2 views"));
    assert!(dir.join("quiet/render.json").is_file());
}

/// Kind 5: the inputs that used to be read without the checks every input has: a run file, a
/// resumed bench.json and the render.json beside compared views.
#[test]
fn every_read_is_of_a_regular_file_within_its_limit() {
    let dir = scratch("failure-kinds", "reads");
    mkfifo(&dir.join("run.toml"));
    refused_with(
        &dir,
        &["render", "--config", "run.toml"],
        1,
        "error: --config run.toml is a FIFO (named pipe), not a regular file: give the path of a file",
    );
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.json")).unwrap();
    refused_with(
        &dir,
        &["render", "--config", "zero.json"],
        1,
        "error: --config zero.json is a character device, not a regular file: give the path of a file",
    );
    std::fs::create_dir(dir.join("bench")).unwrap();
    mkfifo(&dir.join("bench/bench.json"));
    refused_with(
        &dir,
        &["bench", "--common", "--lf 2x1 --resolution 4x4", "--fake-devices", "1"]
            .into_iter()
            .chain(["--out-dir", "bench", "--resume"])
            .collect::<Vec<_>>(),
        1,
        "error: --resume: bench/bench.json is a FIFO (named pipe), not a regular file: give the path of a file",
    );
    // compare: a 1 GiB render.json beside the test views (sparse: no disk taken) is refused
    // before it is read, and so is a FIFO in its place.
    for side in ["test", "reference"] {
        std::fs::create_dir(dir.join(side)).unwrap();
        exr(&dir.join(side).join("view_000.exr"), [0.5; 3]);
    }
    let huge = std::fs::File::create(dir.join("test/render.json")).unwrap();
    huge.set_len(1 << 30).unwrap();
    refused_with(
        &dir,
        &["compare", "test", "reference"],
        1,
        "error: test/render.json is 1073741824 bytes, more than the 268435456 bytes a JSON file may have",
    );
    std::fs::remove_file(dir.join("test/render.json")).unwrap();
    mkfifo(&dir.join("test/render.json"));
    refused_with(
        &dir,
        &["compare", "test", "reference"],
        1,
        "error: test/render.json is a FIFO (named pipe), not a regular file: give the path of a file",
    );
}

/// A 4x4 EXR of radiance `rgb` everywhere.
fn exr(path: &Path, rgb: [f32; 3]) {
    parallax_accuracy::RgbImage::new(4, 4, vec![rgb; 16]).write_exr(path, &[]).unwrap();
}

/// Kind 6: a float that is not finite in a TOML run file is refused as the flag refuses it,
/// naming the flag and its range (it used to become the default, exit 0).
#[test]
fn run_file_floats_that_are_not_finite_are_refused_like_their_flags() {
    let dir = scratch("failure-kinds", "run-file");
    for (setting, line) in [
        (
            "spp = nan",
            "error: --config run.toml: invalid value 'NaN' for '--spp <SPP>': 'NaN' is not a whole number in 1..=65536",
        ),
        (
            "spp = inf",
            "error: --config run.toml: invalid value 'inf' for '--spp <SPP>': 'inf' is not a whole number in 1..=65536",
        ),
        (
            "focus = nan",
            "error: --config run.toml: invalid value 'NaN' for '--focus <FOCUS>': use a finite distance in metres within 1e-4..=1e9 (e.g. 2.5)",
        ),
        (
            "spacing = -inf",
            "error: --config run.toml: invalid value '-inf' for '--spacing <SPACING>': use a finite distance in metres within 0..=1000 (e.g. 0.001)",
        ),
    ] {
        std::fs::write(dir.join("run.toml"), format!("{setting}\n")).unwrap();
        refused_with(&dir, &["render", "--config", "run.toml"], 2, line);
    }
    refused_with(
        &dir,
        &["render", "--spacing=-inf"],
        2,
        "error: invalid value '-inf' for '--spacing <SPACING>': use a finite distance in metres within 0..=1000 (e.g. 0.001)",
    );
    std::fs::write(dir.join("run.toml"), "spp = [1,\n").unwrap();
    refused_with(
        &dir,
        &["render", "--config", "run.toml"],
        1,
        "error: --config run.toml: not TOML (line 1, column 10): unclosed array, expected `]`",
    );
}

/// Kind 7: the tone curve no longer overflows to NaN (black): 1e30 everywhere against 0.5
/// everywhere is no match; an exposure whose every image is black is refused.
#[test]
fn compare_never_scores_overflowed_tonemapping_as_a_match() {
    let dir = scratch("failure-kinds", "compare");
    exr(&dir.join("bright.exr"), [1e30; 3]);
    exr(&dir.join("grey.exr"), [0.5; 3]);
    for (test, reference) in [("grey.exr", "bright.exr"), ("bright.exr", "grey.exr")] {
        let out = run(&dir, &["compare", test, reference, "--json", "c.json"]);
        assert!(out.status.success(), "{}", stderr_of(&out));
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("c.json")).unwrap()).unwrap();
        let o = &json["comparison"]["overall"];
        assert!(o["psnr_tonemapped_db"].as_f64().is_some_and(|db| db < 10.0), "{test} vs {reference}: {o}");
        assert!(o["ssim"].as_f64().unwrap() < 0.9 && o["flip"].as_f64().unwrap() > 0.5, "{test} vs {reference}: {o}");
    }
    refused_with(
        &dir,
        &["compare", "grey.exr", "bright.exr", "--exposure", "1e-45"],
        2,
        "error: invalid value '1e-45' for '--exposure <EXPOSURE>': 1e-45 is outside 1e-6..=1e6: the tonemapped image \
         would be black or meaningless",
    );
    // Within the range, an exposure at which both sides look the same is said to hide the error.
    exr(&dir.join("dim.exr"), [1e-4; 3]);
    exr(&dir.join("dimmer.exr"), [2e-4; 3]);
    let out = run(&dir, &["compare", "dim.exr", "dimmer.exr", "--exposure", "1e-6"]);
    assert!(out.status.success());
    assert!(
        stderr_of(&out).contains(
            "warning: at exposure 0.000001 (fixed) both sides tonemap to the same 8-bit pixels although their radiance differs"
        ),
        "{}",
        stderr_of(&out)
    );
}

/// Kind 8: charts are linear in their input: 200,000 points of `holes` (each labelled) and a
/// trace of 300,000 events of as many names take seconds (they took many minutes); the
/// deadline is only a hang guard.
#[test]
fn charts_of_large_inputs_finish() {
    let dir = scratch("failure-kinds", "charts");
    let points: Vec<serde_json::Value> = (0..200_000)
        .map(|i| {
            serde_json::json!({
                "label": format!("case/reproject_compact_k{}_spp{i}_d1", i % 4),
                "assignment": if i % 2 == 0 { "compact" } else { "round-robin" },
                "missing": (i % 997) as f64 / 2000.0,
                "hole_fill_ms": (i % 991) as f64 / 100.0,
            })
        })
        .collect();
    std::fs::write(dir.join("points.json"), serde_json::to_vec(&serde_json::json!({ "points": points })).unwrap())
        .unwrap();
    let events: Vec<serde_json::Value> = (0..300_000)
        .map(|i| serde_json::json!({ "ph": "X", "name": format!("pass{i}"), "ts": i * 10, "dur": 5, "tid": i % 7 }))
        .collect();
    std::fs::write(dir.join("trace.json"), serde_json::to_vec(&serde_json::json!({ "traceEvents": events })).unwrap())
        .unwrap();
    for args in
        [["chart", "holes", "points.json", "--out", "holes.svg"], ["chart", "timeline", "trace.json", "--out", "t.svg"]]
    {
        let out = run(&dir, &args);
        assert!(out.status.success(), "{args:?}: {}", stderr_of(&out));
        assert!(std::fs::read_to_string(dir.join(args[4])).unwrap().starts_with("<svg"));
    }
}

/// Kind 12: usage errors exit 2 naming the flag and its range; paths may be any bytes the OS
/// takes, text flags say which one is not UTF-8; a message is one line whatever a path or URI
/// holds, and names the scene's path once.
#[test]
fn exit_codes_paths_and_messages_are_consistent() {
    let dir = scratch("failure-kinds", "messages");
    let reference = ["reference", "--cpu", "--lf", "2x1", "--resolution", "4x4", "--spp", "4", "--chunk-spp", "4"];
    refused_with(
        &dir,
        &[&reference[..], &["--checkpoint-secs", "nan"]].concat(),
        2,
        "error: invalid value 'nan' for '--checkpoint-secs <CHECKPOINT_SECS>': NaN is outside 0..=86400 seconds",
    );
    refused_with(
        &dir,
        &[&reference[..], &["--checkpoint-secs", "-1"]].concat(),
        2,
        "error: invalid value '-1' for '--checkpoint-secs <CHECKPOINT_SECS>': -1 is outside 0..=86400 seconds",
    );
    refused_with(
        &dir,
        &[&reference[..], &["--views", "0,5"]].concat(),
        2,
        "error: --views '0,5': '5' is not a range of views 0..=1 of this light field; list views within it",
    );
    // A path that is not UTF-8 is a path like any other.
    let odd = |name: &[u8]| OsStr::from_bytes(name).to_os_string();
    let out = run(
        &dir,
        &[
            OsStr::new("trace"),
            "--cpu".as_ref(),
            "--resolution".as_ref(),
            "4x4".as_ref(),
            "--out".as_ref(),
            &odd(b"v\xff.exr"),
        ],
    );
    assert!(out.status.success(), "{}", stderr_of(&out));
    assert!(dir.join(odd(b"v\xff.exr")).is_file());
    let out = run(&dir, &[OsStr::new("plan"), "--lf".as_ref(), "2x1".as_ref(), "--json".as_ref(), &odd(b"p\xff.json")]);
    assert!(out.status.success(), "{}", stderr_of(&out));
    assert!(dir.join(odd(b"p\xff.json")).is_file());
    refused_with(
        &dir,
        &[OsStr::new("trace"), "--cpu".as_ref(), "--scene".as_ref(), &odd(b"s\xff.gltf")],
        1,
        "error: --scene s\u{fffd}.gltf: cannot read file: No such file or directory (os error 2)",
    );
    refused_with(
        &dir,
        &[OsStr::new("reference"), "--cpu".as_ref(), "--views".as_ref(), &odd(b"1\xff")],
        2,
        "error: --views: the value '1\u{fffd}' is not UTF-8 text; this flag takes text (only paths may be any bytes)",
    );
    // A newline in a URI or a path cannot forge a line ("wrote …") of its own.
    let scene = write_gltf(&dir, "tri", &TRIANGLE, r#"[{"mesh":0}]"#, "");
    let text = std::fs::read_to_string(&scene).unwrap().replace("\"uri\":\"tri.bin\"", "\"uri\":\"x\\nwrote out.exr\"");
    std::fs::write(&scene, text).unwrap();
    let out = run(&dir, &["trace", "--cpu", "--scene", "tri.gltf"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        stderr_of(&out),
        "error: --scene tri.gltf: buffer 0 (x\\nwrote out.exr) cannot be read: x\\nwrote out.exr: No such file or \
         directory (os error 2)\n"
    );
    refused_with(
        &dir,
        &["trace", "--cpu", "--scene", "a\nwrote b.gltf"],
        1,
        "error: --scene a\\nwrote b.gltf: cannot read file: No such file or directory (os error 2)",
    );
}

/// Kind 13: the output folder moved while `render` saves frames: the run stops at the next
/// saved frame naming the cause, makes no new --out-dir, and leaves no staging folder in the
/// folder where it now is.
#[test]
fn an_output_folder_moved_during_a_run_is_named_and_left_clean() {
    let dir = scratch("failure-kinds", "moved");
    let child = parallax_cmd(
        &dir,
        &["render", "--lf", "2x1", "--resolution", "8x8", "--fake-devices", "1", "--spp", "1"]
            .into_iter()
            .chain(["--frames", "100000", "--warmup", "0", "--save-every", "1", "--out-dir", "lf"])
            .collect::<Vec<_>>(),
    )
    .spawn()
    .unwrap();
    let start = Instant::now();
    while !dir.join("lf/frame_00001").exists() {
        assert!(start.elapsed() < HANG_GUARD, "the render never saved a frame");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::fs::rename(dir.join("lf"), dir.join("moved")).unwrap();
    let out = wait_or_kill(child, "render into a moved folder");
    assert_eq!(out.status.code(), Some(1));
    // Found by the next saved frame, or by the one being written when the folder moved: either
    // way the folder is named with the cause, and no temporary path or Debug quoting shows.
    let last = stderr_of(&out).lines().last().unwrap_or_default().to_string();
    assert!(last.starts_with("error: ") && last.contains("folder lf"), "{last}");
    assert!(
        last.ends_with(
            " no longer exists: it was moved or removed while the run went on; leave the output folder in place until \
             the run ends"
        ),
        "{last}"
    );
    assert!(!last.contains("not writable") && !last.contains('"') && !last.contains(".parallax-"), "{last}");
    assert!(!dir.join("lf").exists(), "the run made --out-dir again");
    let mut stack = vec![dir.join("moved")];
    while let Some(folder) = stack.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            assert!(!path.file_name().unwrap().to_string_lossy().starts_with(".parallax-"), "left: {}", path.display());
            if path.is_dir() {
                stack.push(path);
            }
        }
    }
}

/// Kind 14: `--layers` with a pipeline that computes no G-buffer writes the views without those
/// layers, says so before the frames, and names no internal id.
#[test]
fn layers_a_pipeline_does_not_produce_are_left_out() {
    let dir = scratch("failure-kinds", "layers");
    let out = run(
        &dir,
        &["render", "--pipeline", "path-trace", "--no-denoise", "--layers", "--lf", "2x1", "--resolution", "4x4"]
            .into_iter()
            .chain(["--fake-devices", "1", "--out-dir", "lf"])
            .collect::<Vec<_>>(),
    );
    let stderr = stderr_of(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "warning: --layers: this pipeline computes no albedo, normal, depth (no stage needs a G-buffer), so the \
             views' EXRs leave that out; drop --no-denoise or use --pipeline reproject to get every layer"
        ),
        "{stderr}"
    );
    let view = dir.join("lf/view_000.exr");
    assert!(parallax_scene::output::read_exr_channels(&view, &["R", "G", "B"]).is_ok());
    let err = parallax_scene::output::read_exr_channels(&view, &["albedo.R"]).unwrap_err().to_string();
    assert!(err.contains("no channel albedo.R"), "{err}");
}
