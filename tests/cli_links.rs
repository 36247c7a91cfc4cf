//! `render --link`: the kind of every link between two devices is what was asked for and is
//! named in render.json; a kind a pair of devices cannot use is refused before any frame, with
//! one usage error naming the pair and what it lacks, and nothing is written.

mod common;

use common::{parallax_in, scratch, snapshot};

/// A two-device fine-all render of 4×2 views of 16×16 with `--link KIND`.
fn render_linked(dir: &std::path::Path, kind: &str) -> std::process::Output {
    parallax_in(
        dir,
        &[
            "-q",
            "render",
            "--lf",
            "4x2",
            "--resolution",
            "16x16",
            "--scheme",
            "fine-all",
            "--fake-devices",
            "2",
            "--spp",
            "1",
            "--frames",
            "1",
            "--warmup",
            "0",
            "--link",
            kind,
            "--out-dir",
            "out",
        ],
    )
}

#[test]
fn link_relay_moves_every_pair_through_host_staging_and_render_json_says_so() {
    let dir = scratch("links", "relay");
    let out = render_linked(&dir, "relay");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("out/render.json")).unwrap()).unwrap();
    let links = &json["links"];
    let pairs = links["pairs"].as_array().unwrap();
    let mut ends: Vec<(u64, u64)> =
        pairs.iter().map(|p| (p["from"].as_u64().unwrap(), p["to"].as_u64().unwrap())).collect();
    ends.sort_unstable();
    assert_eq!(ends, vec![(0, 1), (1, 0)]);
    assert!(pairs.iter().all(|p| p["kind"] == "relay" && p["bytes_per_frame"].as_u64().unwrap() > 0), "{pairs:?}");
    assert!(links["host_staging_bytes"].as_u64().unwrap() > 0, "{links}");
    assert_eq!(links["host_staging_limit_bytes"].as_u64(), Some(512 << 20), "{links}");
    assert_eq!(links["device_staging_bytes"].as_u64(), Some(0), "{links}");
    // Both devices submit and wait for each other's copies every frame.
    let devices = links["devices"].as_array().unwrap();
    assert_eq!(devices.len(), 2, "{links}");
    assert!(
        devices.iter().all(|d| d["submissions_per_frame"].as_u64().unwrap() > 0
            && d["cross_device_waits_per_frame"].as_u64().unwrap() > 0),
        "{links}"
    );
    assert_eq!(json["run"]["link"], "relay");
}

#[test]
fn link_gpu_on_lavapipe_is_refused_naming_the_pair_and_the_missing_extension() {
    let dir = scratch("links", "gpu");
    let before = snapshot(&dir);
    let out = render_linked(&dir, "gpu");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let first = stderr.lines().next().unwrap_or_default();
    let (head, tail) = (
        "error: --link gpu: link kind `gpu` is unavailable from device 0 to device 1: device 0 (llvmpipe",
        ") lacks VK_KHR_external_semaphore_fd (exportable and importable timeline semaphores); `--link auto` \
         takes the best each pair offers",
    );
    assert!(first.starts_with(head) && first.ends_with(tail), "{stderr}");
    assert_eq!(snapshot(&dir), before, "nothing written");
}
