//! Every input is a regular file read within a bound (issue 21, class 1): FIFOs, devices and
//! folders are refused by name before any read, and a glTF file cannot make the program read
//! outside its folder. Each run has a memory cap (`ulimit -v`) and a deadline, so a regression
//! that reads /dev/zero or blocks on a FIFO fails the test instead of taking the machine down.

mod common;

use common::{capped_command, scratch, snapshot, wait_or_kill, write_gltf};

use std::path::Path;
use std::process::{Command, Output};

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Address space of a capped run: enough for the CPU tracer, far less than /dev/zero would take.
const MEMORY_CAP_KIB: u64 = 4 << 20;

/// Runs the binary in `dir` under the memory cap, killed at the hang guard.
fn capped(dir: &Path, args: &[&str]) -> Output {
    wait_or_kill(capped_command(dir, MEMORY_CAP_KIB, args).spawn().unwrap(), &format!("{args:?}"))
}

/// Asserts exit 1, every needle in stderr, no panic and nothing written in `dir`.
fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let before = snapshot(dir);
    let out = capped(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: expected '{needle}' in: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    assert!(snapshot(dir) == before, "{args:?} changed {}", dir.display());
}

fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// A copy of `gltf` whose buffer 0 URI is `uri`.
fn with_buffer_uri(dir: &Path, gltf: &Path, name: &str, uri: &str) -> String {
    let text = std::fs::read_to_string(gltf).unwrap();
    let bin = format!("\"uri\":\"{}\"", Path::new(gltf).with_extension("bin").file_name().unwrap().to_str().unwrap());
    assert!(text.contains(&bin));
    std::fs::write(dir.join(name), text.replace(&bin, &format!("\"uri\":\"{uri}\""))).unwrap();
    name.to_string()
}

#[test]
fn scenes_and_what_they_name_must_be_regular_files() {
    let dir = scratch("inputs", "scenes");
    let trace =
        |scene: &str| ["trace", "--cpu", "--resolution", "4x4", "--scene", scene, "--out", "x.exr"].map(String::from);
    let run = |scene: &str, needles: &[&str]| {
        let args = trace(scene);
        refused(&dir, &args.iter().map(String::as_str).collect::<Vec<_>>(), needles)
    };
    run("/dev/zero", &["/dev/zero is a character device, not a regular file"]);
    std::fs::create_dir(dir.join("folder.gltf")).unwrap();
    run("folder.gltf", &["folder.gltf is a folder, not a regular file"]);
    mkfifo(&dir.join("pipe.gltf"));
    run("pipe.gltf", &["pipe.gltf is a FIFO (named pipe), not a regular file"]);
    std::os::unix::fs::symlink("loop.gltf", dir.join("loop.gltf")).unwrap();
    run("loop.gltf", &["loop.gltf is a symlink loop"]);

    let good = write_gltf(&dir, "tri", &TRIANGLE, r#"[{"mesh":0}]"#, "");
    // A buffer or image outside the scene's folder is refused, whatever it is.
    for (name, uri) in [("abs.gltf", "/dev/zero"), ("file.gltf", "file:///dev/zero"), ("up.gltf", "../tri.bin")] {
        let scene = with_buffer_uri(&dir, &good, name, uri);
        run(&scene, &[&format!("{name}: buffer 0 ({uri})"), "outside the scene's folder", "--allow-outside-files"]);
    }
    // Allowed, /dev/zero is still not read: not a regular file.
    let zero = with_buffer_uri(&dir, &good, "zero.gltf", "/dev/zero");
    let mut args = trace(&zero).to_vec();
    args.push("--allow-outside-files".into());
    refused(
        &dir,
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &["zero.gltf: buffer 0 (/dev/zero)", "/dev/zero is a character device"],
    );
    mkfifo(&dir.join("pipe.bin"));
    let piped = with_buffer_uri(&dir, &good, "piped.gltf", "pipe.bin");
    run(&piped, &["piped.gltf: buffer 0 (pipe.bin)", "is a FIFO (named pipe)"]);
    let image = r#","images":[{"uri":"pipe.bin"}]"#;
    let textured = write_gltf(&dir, "textured", &TRIANGLE, r#"[{"mesh":0}]"#, image);
    run(textured.to_str().unwrap(), &["textured.gltf: image 0 (pipe.bin) cannot be read", "is a FIFO"]);
}

#[test]
fn every_other_input_must_be_a_regular_file() {
    let dir = scratch("inputs", "others");
    mkfifo(&dir.join("a.exr"));
    mkfifo(&dir.join("points.json"));
    mkfifo(&dir.join("matrix.toml"));
    refused(&dir, &["compare", "a.exr", "/dev/zero"], &["not a regular file"]);
    refused(&dir, &["chart", "views", "points.json", "--out", "c.svg"], &["points.json is a FIFO"]);
    refused(&dir, &["chart", "views", "/dev/zero", "--out", "c.svg"], &["/dev/zero is a character device"]);
    refused(&dir, &["bench", "--matrix", "matrix.toml"], &["--matrix matrix.toml", "is a FIFO"]);
    std::fs::create_dir(dir.join("ref")).unwrap();
    mkfifo(&dir.join("ref/reference.partial"));
    refused(
        &dir,
        &["reference", "--cpu", "--lf", "2x1", "--resolution", "4x4", "--spp", "16", "--out-dir", "ref"],
        &["reference.partial is a FIFO"],
    );
}
