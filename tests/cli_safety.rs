//! Bad input of every class issue 14 found, each refused the way a user can act on: the exit
//! code (2 for usage errors, 1 for a failed run), stderr naming the input and the fix, no
//! panic, and no file left behind or replaced. Sizes are tiny: lavapipe is slow.

mod common;

use common::{assert_refused, parallax_in, scratch, snapshot, write_gltf};

use std::path::Path;

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Runs `args` in `dir` and asserts the refusal.
fn refused(dir: &Path, args: &[&str], code: i32, needles: &[&str]) {
    let before = snapshot(dir);
    let out = parallax_in(dir, args);
    assert_refused(&args.join(" "), &out, code, needles, dir, &before);
}

#[test]
fn crashes_are_refusals() {
    let dir = scratch("safety", "crash");
    // obvhs panics on a vertex at 1e20 (docs/UPSTREAM.md): the importer refuses it first.
    let positions =
        [[0.0, 0.0, 0.0], [1e20, 1e20, 1e20], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
    let far = write_gltf(&dir, "far", &positions, r#"[{"mesh":0}]"#, "");
    refused(
        &dir,
        &["trace", "--cpu", "--resolution", "4x4", "--scene", far.to_str().unwrap(), "--out", "x.exr"],
        1,
        &["far.gltf", "vertex 1 of accessor 0 (node 0, mesh 0 primitive 0)", "1e20", "rescale the scene"],
    );
    refused(&dir, &["devices", "--fake-devices", "4294967295"], 2, &["--fake-devices", "outside 1..=64"]);
    refused(&dir, &["bench-copy", "--fake-devices", "2", "--size-mib", "100000"], 2, &["--size-mib", "1..=65536"]);
    // Within the flag's range but not within this machine's memory: refused before allocating.
    refused(
        &dir,
        &["bench-copy", "--fake-devices", "2", "--size-mib", "65536", "--frames-in-flight", "16"],
        1,
        &["--size-mib 65536", "of host memory", "lower --size-mib or --frames-in-flight"],
    );
}

#[test]
fn malformed_gltf_images_are_named_and_no_panic_text_is_printed() {
    let dir = scratch("safety", "images");
    let images = r#","images":[{"name":"a"},{"bufferView":0}]"#;
    let scene = write_gltf(&dir, "noimage", &TRIANGLE, r#"[{"mesh":0}]"#, images);
    refused(
        &dir,
        &["trace", "--cpu", "--scene", scene.to_str().unwrap()],
        1,
        &["noimage.gltf: image 0: has neither uri nor bufferView; glTF requires exactly one"],
    );
    let out = parallax_in(&dir, &["trace", "--cpu", "--scene", scene.to_str().unwrap()]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panic"));
}

/// Scene emission beyond what f32 sums hold used to give `inf` pixels with exit 0; a matrix
/// whose every cell failed exited 0.
#[test]
fn silent_nonsense_is_refused() {
    let dir = scratch("safety", "silent");
    let strength = r#","materials":[{"emissiveFactor":[1,1,1],"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":1e38}}}]"#;
    let bright = write_gltf(&dir, "bright", &TRIANGLE, r#"[{"mesh":0}]"#, strength);
    refused(
        &dir,
        &["trace", "--cpu", "--scene", bright.to_str().unwrap()],
        1,
        &["bright.gltf: material 0 (emissive) emits 1e38, more than the 1e6 a scene may", "lower it"],
    );
    let light = r#","extensions":{"KHR_lights_punctual":{"lights":[{"type":"point","intensity":1e38}]}}"#;
    let nodes = r#"[{"mesh":0,"children":[1]},{"extensions":{"KHR_lights_punctual":{"light":0}}}]"#;
    let lamp = write_gltf(&dir, "lamp", &TRIANGLE, nodes, light);
    refused(
        &dir,
        &["trace", "--cpu", "--scene", lamp.to_str().unwrap()],
        1,
        &["lamp.gltf: light 0 (node 1) emits 1e38"],
    );
    refused(&dir, &["plan", "--spacing", "1e30"], 2, &["--spacing", "more than 1000 m between neighbouring views"]);
    refused(&dir, &["render", "--focus", "1e-30"], 2, &["--focus", "outside 1e-4..=1e9 m"]);
    std::fs::write(dir.join("points.json"), r#"{"points":[{"label":"a","frame_ms":-3}]}"#).unwrap();
    refused(
        &dir,
        &["chart", "views", "points.json", "--out", "c.svg"],
        1,
        &["points.json: point 'a': frame_ms -3 is outside 0..=1000000000"],
    );
    std::fs::write(dir.join("huge.json"), r#"{"points":[{"label":"b","frame_ms":1,"flip":1e308}]}"#).unwrap();
    refused(&dir, &["chart", "speed-accuracy", "huge.json", "--out", "c.svg"], 1, &["flip 1e308 is outside 0..=1"]);
    // Every cell fails (5 devices for 2 views): exit 1 after writing bench.json with the errors.
    let out =
        parallax_in(&dir, &["bench", "--common", "--scene default --lf 2x1 --resolution 8x8", "--fake-devices", "5"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cell(s) failed (their errors are in out/bench/bench.json): nothing was measured")
            && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert!(dir.join("out/bench/bench.json").is_file());
}

/// No output may replace an input or another output; compared as canonical paths.
#[test]
fn outputs_never_overwrite_inputs() {
    let dir = scratch("safety", "overwrite");
    let scene = write_gltf(&dir, "s", &TRIANGLE, r#"[{"mesh":0}]"#, r#","images":[{"uri":"tex.png"}]"#);
    image::RgbaImage::new(1, 1).save(dir.join("tex.png")).unwrap();
    std::fs::copy(&scene, dir.join("s.json")).unwrap();
    refused(
        &dir,
        &["render", "--scene", "s.json", "--trace", "./s.json", "--lf", "2x1", "--resolution", "4x4"],
        1,
        &[
            "--trace ./s.json is also read, as --scene",
            "s.json: writing it would destroy an input; give the output another path",
        ],
    );
    // A texture the scene reads is an input too.
    refused(
        &dir,
        &["trace", "--cpu", "--scene", "s.gltf", "--resolution", "4x4", "--out", "x.exr", "--png", "tex.png"],
        1,
        &["--png tex.png is also read, as --scene", "tex.png"],
    );
    refused(&dir, &["trace", "--cpu", "--scene", "s.gltf", "--out", "s.bin"], 1, &["--out s.bin", "must end in .exr"]);
    let out = parallax_in(&dir, &["trace", "--cpu", "--scene", "s.gltf", "--resolution", "4x4", "--out", "a.exr"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::copy(dir.join("a.exr"), dir.join("b.exr")).unwrap();
    refused(&dir, &["compare", "a.exr", "b.exr", "--json", "a.exr"], 1, &["--json a.exr", "must end in .json"]);
    refused(&dir, &["compare", "a.exr", "b.exr", "--markdown", "b.json"], 1, &["--markdown b.json", "must end in .md"]);
    std::fs::copy(dir.join("a.exr"), dir.join("t.json")).unwrap();
    refused(
        &dir,
        &["compare", "t.json", "b.exr", "--json", "t.json"],
        1,
        &["--json t.json is also read, as TEST t.json"],
    );
    std::fs::write(dir.join("a.svg"), "<svg/>").unwrap();
    std::fs::create_dir(dir.join("x")).unwrap();
    refused(
        &dir,
        &["chart", "views", "a.svg", "--out", "x/../a.svg"],
        1,
        &["--out x/../a.svg is also read, as INPUT a.svg"],
    );
    refused(
        &dir,
        &["chart", "views", "t.json", "--out", "c.svg", "--out", "./c.svg"],
        1,
        &["--out and --out both write"],
    );
}

/// A resumed reference trusts nothing: every file the scene reads is hashed, the partial is
/// checksummed, and a change is named.
#[test]
fn resumed_references_verify_the_scene_and_the_partial() {
    let dir = scratch("safety", "resume");
    let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let light = r#","extensions":{"KHR_lights_punctual":{"lights":[{"type":"directional","intensity":2}]}}"#;
    let nodes = r#"[{"mesh":0,"children":[1]},{"extensions":{"KHR_lights_punctual":{"light":0}}}]"#;
    write_gltf(&dir, "tri", &positions, nodes, light);
    let reference = |spp: &str, extra: &[&str]| {
        let mut args =
            vec!["reference", "--cpu", "--scene", "tri.gltf", "--lf", "2x1", "--resolution", "4x4", "--chunk-spp", "4"];
        args.extend_from_slice(&["--spp", spp, "--out-dir", "ref"]);
        args.extend_from_slice(extra);
        parallax_in(&dir, &args)
    };
    let first = reference("4", &[]);
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    // An explicit --spacing equal to the default in effect (the grid's, for this rig) is the
    // same run.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("ref/reference.json")).unwrap()).unwrap();
    let spacing = json["setup"]["spacing_m"].to_string();
    assert_ne!(spacing, "0.001", "a grid's default spacing is its own");
    let same = reference("8", &["--spacing", &spacing]);
    assert!(same.status.success(), "{}", String::from_utf8_lossy(&same.stderr));
    // The .bin changes (same length): refused naming it.
    let mut bin = std::fs::read(dir.join("tri.bin")).unwrap();
    bin[12..16].copy_from_slice(&2.0f32.to_le_bytes());
    std::fs::write(dir.join("tri.bin"), &bin).unwrap();
    refused(
        &dir,
        &[
            "reference",
            "--cpu",
            "--scene",
            "tri.gltf",
            "--lf",
            "2x1",
            "--resolution",
            "4x4",
            "--chunk-spp",
            "4",
            "--spp",
            "12",
            "--out-dir",
            "ref",
        ],
        1,
        &["was made with other settings", "--scene file tri.bin tri.bin (fnv1a"],
    );
    write_gltf(&dir, "tri", &positions, nodes, light);
    // An edited partial is refused by its checksum.
    let partial = dir.join("ref/reference.partial");
    let mut bytes = std::fs::read(&partial).unwrap();
    let last = bytes.len() - 9;
    bytes[last] ^= 0x40;
    std::fs::write(&partial, &bytes).unwrap();
    refused(
        &dir,
        &[
            "reference",
            "--cpu",
            "--scene",
            "tri.gltf",
            "--lf",
            "2x1",
            "--resolution",
            "4x4",
            "--chunk-spp",
            "4",
            "--spp",
            "12",
            "--out-dir",
            "ref",
        ],
        1,
        &["reference.partial: its checksum does not match its contents", "delete it to start over"],
    );
}

#[test]
fn unbounded_work_is_refused_with_the_numbers() {
    let dir = scratch("safety", "unbounded");
    refused(&dir, &["render", "--lf", "100x100", "--resolution", "4096x4096"], 2, &["--lf", "at most 4096"]);
    refused(
        &dir,
        &["render", "--lf", "64x64", "--resolution", "4096x4096", "--out-dir", "lf"],
        1,
        &["4096 view(s) (--lf) × 4096x4096 (--resolution) read back", "of host memory", "lower --lf or --resolution"],
    );
    refused(&dir, &["plan", "--lf", "1000000x1000000"], 2, &["--lf", "1000000000000 views; at most 4096"]);
    refused(
        &dir,
        &["plan", "--lf", "64x64", "--gpus", "64", "--scheme", "fine-all"],
        1,
        &["fine-all over 4096 views (--lf) and 64 devices (--gpus/--fake-devices)", "use fewer devices"],
    );
    refused(&dir, &["devices", "--fake-devices", "100000"], 2, &["--fake-devices", "outside 1..=64"]);
    refused(
        &dir,
        &["trace", "--spp", "4294967295"],
        1,
        &["512x512 (--resolution) × 4294967295 spp (--spp)", "lower --resolution or --spp"],
    );
}

#[test]
fn unclear_errors_name_the_input_and_the_limit() {
    let dir = scratch("safety", "unclear");
    refused(&dir, &["trace", "--resolution", "40000x10"], 2, &["--resolution", "width 40000 is outside 1..=32768"]);
    // Within the flag's range, beyond lavapipe's maxImageDimension2D (16384).
    refused(
        &dir,
        &["trace", "--fake-devices", "1", "--resolution", "32768x1", "--out", "x.exr"],
        1,
        &["--resolution 32768x1 exceeds device 0", "image limit of", "use at most"],
    );
    refused(&dir, &["trace", "--fake-devices", "0"], 2, &["--fake-devices", "outside 1..=64"]);
    refused(&dir, &["trace", "--cpu", "--sky", "-1,0,0"], 2, &["--sky", "radiance -1 is outside 0..=1e6"]);
    std::fs::write(dir.join("cube.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    refused(&dir, &["trace", "--cpu", "--scene", "cube.obj"], 1, &["cube.obj: not a glTF file", "convert"]);
    std::fs::write(dir.join("junk.glb"), [0u8, 1, 2, 3, 4, 5, 6, 7]).unwrap();
    refused(&dir, &["trace", "--cpu", "--scene", "junk.glb"], 1, &["junk.glb: not a glTF file", "magic"]);
    let before = snapshot(&dir);
    let out = parallax_in(&dir, &["trace", "--cpu", "--scene", "missing.gltf"]);
    assert_refused("missing scene", &out, 1, &["missing.gltf", "os error 2"], &dir, &before);
    assert_eq!(String::from_utf8_lossy(&out.stderr).matches("os error").count(), 1, "the OS error once");
    // 300 views used to overflow a per-frame buffer named only by its internal name.
    let out = parallax_in(&dir, &["render", "--lf", "20x15", "--resolution", "2x2", "--fake-devices", "1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.join("out/lightfield/view_299.exr").is_file());
}

#[test]
fn nonsense_values_are_refused_or_warned_about() {
    let dir = scratch("safety", "nonsense");
    for exposure in ["0", "-1", "NaN"] {
        refused(&dir, &["trace", "--cpu", "--exposure", exposure], 2, &["--exposure", "black"]);
    }
    refused(
        &dir,
        &["trace", "--cpu", "--camera", "0,0,5,0,0,0,0,0,1,45"],
        2,
        &["--camera", "not parallel to the view direction"],
    );
    for (name, yfov) in [("yfov0", "0"), ("yfov4", "4")] {
        let nodes = r#"[{"mesh":0,"children":[1]},{"camera":0,"translation":[0,0,3]}]"#;
        let cameras = format!(r#","cameras":[{{"type":"perspective","perspective":{{"yfov":{yfov},"znear":0.1}}}}]"#);
        let scene = write_gltf(&dir, name, &TRIANGLE, nodes, &cameras);
        refused(
            &dir,
            &["trace", "--cpu", "--scene", scene.to_str().unwrap()],
            1,
            &[&format!("{name}.gltf: camera 0 (node 1): yfov {yfov} rad"), "use e.g. 0.8"],
        );
    }
    let flat = write_gltf(&dir, "flat", &TRIANGLE, r#"[{"mesh":0,"scale":[0,0,0]}]"#, "");
    refused(
        &dir,
        &["trace", "--cpu", "--scene", flat.to_str().unwrap()],
        1,
        &["flat.gltf: every triangle has zero area (node 0 has a transform of zero scale)"],
    );
    refused(&dir, &["trace", "--cpu", "--sun", "0,1,0,1e38"], 2, &["--sun", "irradiance 1e38 is outside 0..=1e6"]);
    refused(&dir, &["trace", "--cpu", "--out", "a.png"], 1, &["--out a.png", "must end in .exr"]);
    refused(
        &dir,
        &["bench-copy", "--fake-devices", "2", "--json", "a.json", "--trace", "a.json"],
        1,
        &["--trace and --json both write a.json"],
    );
    refused(&dir, &["render", "--frames", "0"], 2, &["--frames", "0 is not in 1..=100000"]);
    for tolerance in ["-0.1", "NaN", "inf"] {
        refused(
            &dir,
            &["render", "--reprojection-tolerance", tolerance],
            2,
            &["--reprojection-tolerance", "relative error"],
        );
    }
    refused(
        &dir,
        &["plan", "--lf", "4x1", "--gpus", "2", "--scheme", "fine-all", "--assign", "round-robin"],
        2,
        &["--assign applies only to --scheme multi-source", "drop --assign"],
    );
}

#[test]
fn outputs_are_checked_first_and_never_replaced_or_left_half_written() {
    use std::os::unix::fs::FileTypeExt;
    let dir = scratch("safety", "outputs");
    let plan = |extra: &[&str]| {
        let mut args = vec!["plan", "--lf", "4x1", "--gpus", "2"];
        args.extend_from_slice(extra);
        parallax_in(&dir, &args)
    };
    // A device is written through, never replaced by a regular file.
    let out = plan(&["--json", "/dev/full"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot write /dev/full"));
    assert!(std::fs::metadata("/dev/full").unwrap().file_type().is_char_device());
    // A FIFO gets the JSON and stays a FIFO.
    let fifo = dir.join("plan.fifo");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let out = plan(&["--json", fifo.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&reader.join().unwrap()).unwrap();
    assert_eq!(json["views"], 4);
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    std::fs::remove_file(&fifo).unwrap();
    // A symlink stays a symlink; its target gets the new contents.
    std::fs::write(dir.join("real.json"), "old").unwrap();
    std::os::unix::fs::symlink("real.json", dir.join("link.json")).unwrap();
    assert!(plan(&["--json", "link.json"]).status.success());
    assert!(std::fs::symlink_metadata(dir.join("link.json")).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(dir.join("real.json")).unwrap().contains("\"views\": 4"));
    // `-` is stdout, not a file named `-`.
    let out = plan(&["--json", "-"]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["devices"], 2);
    assert!(!dir.join("-").exists());
    // A failed run keeps the previous good output.
    refused(&dir, &["plan", "--lf", "4x1", "--gpus", "5", "--json", "real.json"], 1, &["exceeds the 4 views"]);
    // Output paths are checked before any work.
    refused(&dir, &["trace", "--cpu", "--out", "nowhere/x.exr"], 1, &["--out nowhere/x.exr", "does not exist"]);
    refused(
        &dir,
        &["render", "--lf", "2x1", "--resolution", "4x4", "--fake-devices", "1", "--trace", "bad/path.json"],
        1,
        &["--trace bad/path.json", "folder bad does not exist"],
    );
    // Re-rendering a smaller light field leaves exactly the views render.json lists.
    let render = |lf: &str| {
        let out =
            parallax_in(&dir, &["render", "--lf", lf, "--resolution", "4x4", "--fake-devices", "1", "--out-dir", "lf"]);
        assert!(out.status.success(), "{lf}: {}", String::from_utf8_lossy(&out.stderr));
    };
    render("4x1");
    std::fs::write(dir.join("lf/notes.txt"), "mine").unwrap();
    render("2x1");
    let mut names: Vec<String> =
        std::fs::read_dir(dir.join("lf")).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    let written = ["render.json", "view_000.exr", "view_000.png", "view_001.exr", "view_001.png", "viewer.html"];
    assert_eq!(names, [&["lightfield.png", "notes.txt"][..], &written].concat());
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("lf/render.json")).unwrap()).unwrap();
    assert_eq!(json["plan"]["views"], 2);
}

#[test]
fn ctrl_c_leaves_no_output() {
    let dir = scratch("safety", "ctrl-c");
    // Long enough to be interrupted mid-trace (about a minute on the CPU).
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_parallax"))
        .current_dir(&dir)
        .args(["trace", "--cpu", "--resolution", "256x256", "--spp", "4096", "--out", "x.exr", "--png", "x.png"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    assert!(std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("error: interrupted: outputs not yet in place were removed"), "{stderr}");
    assert!(snapshot(&dir).is_empty(), "files left behind: {:?}", snapshot(&dir).keys());
}

/// Waits until `done` holds, at most `limit`.
fn wait_for(limit: std::time::Duration, done: impl Fn() -> bool) -> bool {
    let start = std::time::Instant::now();
    while !done() {
        if start.elapsed() > limit {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    true
}

/// SIGTERM (or SIGINT, SIGHUP) mid-run removes the temporary files and the folders the run
/// created: nothing is left of a render that saved frames.
#[test]
fn a_terminated_render_leaves_no_temporary_files_or_empty_folders() {
    let dir = scratch("safety", "sigterm");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_parallax"))
        .current_dir(&dir)
        .args(["render", "--lf", "2x1", "--resolution", "8x8", "--fake-devices", "1", "--spp", "1"])
        .args(["--frames", "100000", "--warmup", "0", "--save-every", "1", "--out-dir", "lf"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Frames are being saved: at least one frame folder exists.
    assert!(
        wait_for(std::time::Duration::from_secs(300), || dir.join("lf/frame_00001").exists()),
        "the render never started saving frames"
    );
    assert!(std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted: outputs not yet in place were removed"), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    assert!(left.is_empty(), "left behind: {left:?} {:?}", snapshot(&dir).keys());
}

/// Two `reference` runs into one folder: the second is refused while the first holds the
/// folder's lock, and the first is not disturbed.
#[test]
fn a_second_run_into_a_locked_folder_is_refused() {
    let dir = scratch("safety", "lock");
    let args = ["reference", "--cpu", "--lf", "2x1", "--resolution", "64x64", "--chunk-spp", "4"];
    let first = std::process::Command::new(env!("CARGO_BIN_EXE_parallax"))
        .current_dir(&dir)
        .args(args)
        .args(["--spp", "100000", "--out-dir", "ref"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    assert!(wait_for(std::time::Duration::from_secs(300), || dir.join("ref").exists()), "the first run never started");
    let second = parallax_in(&dir, &[&args[..], &["--spp", "4", "--out-dir", "ref"]].concat());
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--out-dir ref is in use by another parallax run"), "{stderr}");
    assert!(std::process::Command::new("kill").args(["-INT", &first.id().to_string()]).status().unwrap().success());
    let out = first.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", String::from_utf8_lossy(&out.stderr));
    // The lock goes with the process: a new run may use the folder.
    let third = parallax_in(&dir, &[&args[..], &["--spp", "4", "--out-dir", "ref"]].concat());
    assert!(third.status.success(), "{}", String::from_utf8_lossy(&third.stderr));
}

/// What would fail only after the work is found before it.
/// A 4-spp CPU reference of 2 views of 4x4 into `out_dir`: the smallest run that writes views.
fn tiny_reference(out_dir: &str) -> [&str; 12] {
    ["reference", "--cpu", "--lf", "2x1", "--resolution", "4x4", "--spp", "4", "--chunk-spp", "4", "--out-dir", out_dir]
}

#[test]
fn outputs_are_checked_before_the_work() {
    let dir = scratch("safety", "before");
    refused(&dir, &["trace", "--cpu", "--out", "x.exr/"], 1, &["--out x.exr/ ends in '/'", "give a file name"]);
    let long = format!("{}.exr", "a".repeat(300));
    refused(&dir, &["trace", "--cpu", "--out", &long], 1, &["the file name is 304 bytes, more than the 255"]);
    std::fs::create_dir_all(dir.join("lf/view_001.exr")).unwrap();
    refused(
        &dir,
        &["render", "--lf", "2x1", "--resolution", "4x4", "--fake-devices", "1", "--out-dir", "lf"],
        1,
        &["--out-dir lf: view_001.exr there is a folder", "move it"],
    );
    refused(&dir, &tiny_reference("lf"), 1, &["--out-dir lf: view_001.exr there is a folder"]);
    // A bench case's missing scene is found before any cell runs (no out/bench is made).
    refused(
        &dir,
        &["bench", "--common", "--scene missing.gltf --lf 2x1 --resolution 4x4", "--fake-devices", "1"],
        1,
        &["--scene missing.gltf", "No such file or directory"],
    );
    // An immutable folder (where the file system and privileges allow making one).
    std::fs::create_dir(dir.join("frozen")).unwrap();
    if std::process::Command::new("chattr").args(["+i"]).arg(dir.join("frozen")).status().is_ok_and(|s| s.success()) {
        let out = parallax_in(&dir, &tiny_reference("frozen"));
        let _ = std::process::Command::new("chattr").args(["-i"]).arg(dir.join("frozen")).status();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("--out-dir frozen: the folder is not writable"), "{stderr}");
    }
}

/// Bad values and flags that do not go together exit 2 like clap's own errors; messages say
/// what is actually wrong.
#[test]
fn usage_errors_exit_2_and_messages_name_the_real_cause() {
    let dir = scratch("safety", "usage");
    refused(
        &dir,
        &["plan", "--lf", "4x1", "--scheme", "multi-source", "--sources", "0,1"],
        2,
        &["--sources does not apply to multi-source"],
    );
    refused(&dir, &["plan", "--lf", "4x1", "--json", "-", "--dot", "-"], 2, &["both write to stdout"]);
    refused(
        &dir,
        &["reference", "--cpu", "--spp", "20"],
        2,
        &["--spp 20 is not a multiple of --chunk-spp 16", "pick --spp 32"],
    );
    refused(&dir, &["reference", "--cpu", "--views", "a"], 2, &["--views 'a': 'a' is not a view number"]);
    refused(
        &dir,
        &["render", "--lf", "4x1", "--scheme", "fine-all", "--sources-per-set", "2", "--fake-devices", "1"],
        2,
        &["--sources-per-set applies to multi-source only"],
    );
    refused(
        &dir,
        &["plan", "--lf", "4x1", "--sources-per-set", "0"],
        2,
        &["'0' is neither `auto` nor a count of sources from 1 to 64"],
    );
    refused(
        &dir,
        &["trace", "--cpu", "--camera", "0,0,1e20,0,0,0,0,1,0,45"],
        2,
        &["eye coordinate 1e20 is beyond ±1e18"],
    );
    // An EXR that cannot be read says so (it used to say "cannot write image").
    std::fs::write(dir.join("junk.exr"), b"not an exr").unwrap();
    std::fs::write(dir.join("junk2.exr"), b"not an exr").unwrap();
    refused(&dir, &["compare", "junk.exr", "junk2.exr"], 1, &["junk2.exr: cannot read image: not a readable EXR"]);
    std::os::unix::fs::symlink("loop.json", dir.join("loop.json")).unwrap();
    refused(&dir, &["plan", "--lf", "4x1", "--json", "loop.json"], 1, &["--json loop.json is a symlink loop"]);
}
