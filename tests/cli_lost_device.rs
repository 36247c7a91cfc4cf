//! The scheme that lost the GPU (issue 21, class 10): fine-all on four logical devices renders
//! three frames of 8×4 views of 64×48, issue 26's size (a wait never signalled would end at the
//! executor's stall timeout), and a lost GPU ends a run with one error naming the likely cause and leaves the output folder as it
//! was (`PARALLAX_FAULT=device-lost:F` makes frame F's submission fail as on a lost device).

mod common;

use common::{parallax_in, scratch, snapshot};

#[test]
fn fine_all_on_four_logical_devices_renders_frames() {
    let dir = scratch("lost", "fine_all");
    let out = parallax_in(
        &dir,
        &[
            "-q",
            "render",
            "--lf",
            "8x4",
            "--resolution",
            "64x48",
            "--scheme",
            "fine-all",
            "--fake-devices",
            "4",
            "--spp",
            "1",
            "--frames",
            "3",
            "--warmup",
            "1",
            "--out-dir",
            "out",
        ],
    );
    // A wait that is never signalled ends the run at the executor's stall timeout (no device
    // making progress for 10 min on lavapipe) with an error, which fails this test; a time
    // bound of its own would measure the machine's load.
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("out/render.json")).unwrap()).unwrap();
    assert_eq!(json["plan"]["devices"], 4);
    assert_eq!(json["timing"]["frames"], 3);
    // Every device sends bands to every other: one link per ordered pair, each carrying chunks
    // every frame; logical devices of lavapipe share device memory (`shared`: lavapipe has no
    // VK_KHR_external_semaphore_fd, so signals go through the host), no host staging.
    let pairs = json["links"]["pairs"].as_array().unwrap();
    let mut ends: Vec<(u64, u64)> =
        pairs.iter().map(|p| (p["from"].as_u64().unwrap(), p["to"].as_u64().unwrap())).collect();
    ends.sort_unstable();
    let every: Vec<(u64, u64)> = (0..4).flat_map(|a| (0..4).filter(move |&b| b != a).map(move |b| (a, b))).collect();
    assert_eq!(ends, every);
    assert!(pairs.iter().all(|p| p["kind"] == "shared" && p["chunks_per_frame"].as_u64().unwrap() > 0), "{pairs:?}");
    assert_eq!(json["links"]["host_staging_bytes"].as_u64(), Some(0));
    assert!(json["links"]["device_staging_bytes"].as_u64().unwrap() > 0);
}

/// The render of a lost GPU: one `error:` line, exit 1, no panic.
fn render_losing_the_gpu(dir: &std::path::Path) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_parallax"))
        .current_dir(dir)
        .env("PARALLAX_FAULT", "device-lost:1")
        .args(["-q", "render", "--lf", "4x2", "--resolution", "16x16", "--scheme", "fine-all", "--fake-devices", "2"])
        .args(["--frames", "3", "--out-dir", "out"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "one message: {stderr}");
    assert!(stderr.starts_with("error: the GPU was lost"), "{stderr}");
    for cause in ["waited too long for a signal", "out of bounds", "PARALLAX_VALIDATION=1"] {
        assert!(stderr.contains(cause), "{cause} in {stderr}");
    }
    stderr
}

#[test]
fn a_lost_gpu_ends_the_run_with_one_message_and_no_output() {
    let dir = scratch("lost", "fault");
    render_losing_the_gpu(&dir);
    assert!(!dir.join("out").exists(), "a failed run created its output folder");

    // Over the outputs of an earlier run: they stay exactly as they were.
    let earlier = parallax_in(
        &dir,
        &["-q", "render", "--lf", "4x2", "--resolution", "16x16", "--frames", "1", "--out-dir", "out"],
    );
    assert!(earlier.status.success(), "{}", String::from_utf8_lossy(&earlier.stderr));
    let before = snapshot(&dir);
    render_losing_the_gpu(&dir);
    assert!(snapshot(&dir) == before, "the failed run changed or left files in {}", dir.display());
}
