//! `parallax plan` end to end: the JSON it writes, and bad input giving one clear error, a
//! non-zero exit and no files.

mod common;

use common::scratch;

use std::path::Path;
use std::process::{Command, Output};

fn plan(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_parallax"))
        .arg("plan")
        .args(args)
        .arg("--json")
        .arg(dir.join("plan.json"))
        .arg("--dot")
        .arg(dir.join("plan.dot"))
        .output()
        .unwrap()
}

#[test]
fn json_summary_has_the_documented_fields() {
    let dir = scratch("plan", "json");
    let out = plan(&["--lf", "multiscopic", "--gpus", "4", "--scheme", "multi-source", "--assign", "contiguous"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("plan.json")).unwrap()).unwrap();
    assert_eq!(json["views"], 100);
    assert_eq!(json["devices"], 4);
    assert_eq!(json["scheme"], "multi-source");
    assert_eq!(json["assign"], "contiguous");
    // A fine scheme places row bands: no assignment to report (`--assign` is refused with it).
    let fine = scratch("plan", "json-fine");
    assert!(plan(&["--lf", "4x1", "--gpus", "2", "--scheme", "fine-all"], &fine).status.success());
    let json_fine: serde_json::Value = serde_json::from_slice(&std::fs::read(fine.join("plan.json")).unwrap()).unwrap();
    assert!(json_fine["assign"].is_null(), "{json_fine}");
    assert_eq!(json["sources"].as_array().unwrap().len(), 4);
    let sets = json["set_of_view"].as_array().unwrap();
    assert_eq!(sets.len(), 100);
    assert_eq!((sets[0].as_u64(), sets[99].as_u64()), (Some(0), Some(3)));
    assert_eq!(json["delta_edges"], 96);
    assert_eq!(json["cross_device_copies"], 0);
    assert_eq!(json["gather_copies"], 75);
    // 75 RGBA8 768×432 display images travel to device 0.
    assert_eq!(json["bytes_per_frame"], 75 * 768 * 432 * 4);
    // 100 instances of a pass side by side would not read: `auto` draws the summary.
    assert!(std::fs::read_to_string(dir.join("plan.dot")).unwrap().starts_with("digraph schedule_summary {"));
}

#[test]
fn bad_input_fails_cleanly_and_writes_nothing() {
    // Exit 2: a value clap refuses, naming the flag; exit 1: the plan itself is impossible.
    let cases: &[(&[&str], i32, &str)] = &[
        (&["--lf", "4x1", "--gpus", "5"], 1, "exceeds the 4 views"),
        (&["--lf", "4x1", "--gpus", "0"], 2, "invalid value '0' for '--gpus <GPUS>': 0 is outside 1..=64"),
        (&["--lf", "0x3"], 2, "--lf 0x3 has no views"),
        (&["--lf", "4x1", "--spacing", "NaN"], 2, "invalid value 'NaN' for '--spacing <SPACING>'"),
        (&["--lf", "4x1", "--spacing", "-1"], 2, "invalid value '-1' for '--spacing <SPACING>'"),
        (&["--lf", "4x1", "--spacing", "inf"], 2, "invalid value 'inf' for '--spacing <SPACING>'"),
        (&["--lf", "4x1", "--gpus", "2", "--scheme", "fine-all", "--sources", "0,4"], 1, "view 4 is out of range"),
        (&["--lf", "4x1", "--gpus", "2", "--scheme", "fine-all", "--sources", "1,1"], 1, "view 1 is listed twice"),
        (&["--lf", "4x1", "--scheme", "coarse"], 2, "[possible values: multi-source, fine-sources, fine-all]"),
        (&["--lf", "4x1", "--assign", "random"], 2, "[possible values: round-robin, contiguous, compact]"),
        (&["--lf", "4x1", "--resolution", "0x10"], 2, "width 0 is outside 1..=32768"),
    ];
    for (i, (args, code, message)) in cases.iter().enumerate() {
        let dir = scratch("plan", &format!("bad{i}"));
        let out = plan(args, &dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(*code), "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: expected '{message}' in: {stderr}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        if *code == 1 {
            assert_eq!(stderr.lines().count(), 1, "{args:?}: one clear error line, got: {stderr}");
        }
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "{args:?} left files behind");
    }
}

#[test]
fn dot_detail_summary_stays_small_for_big_schedules() {
    let dir = scratch("plan", "summary");
    let out = plan(&["--lf", "multiscopic", "--gpus", "8", "--scheme", "fine-all"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let dot = std::fs::read_to_string(dir.join("plan.dot")).unwrap();
    // `auto` chose the summary: one node per pass and device, not one per instance.
    assert!(dot.starts_with("digraph schedule_summary {"), "{}", &dot[..80]);
    assert!(dot.len() < 64 << 10, "{} bytes", dot.len());
    // The main job's NELF plan (72 views on 4 devices) drawn in full was 14,800 pt wide.
    let out = plan(&["--lf", "nelf", "--gpus", "4", "--scheme", "multi-source"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let dot = std::fs::read_to_string(dir.join("plan.dot")).unwrap();
    assert!(dot.starts_with("digraph schedule_summary {"), "{}", &dot[..80]);
    // 8x4 views still draw in full (the main job's render --dot, tests/golden).
    let out = plan(&["--lf", "8x4", "--gpus", "2", "--scheme", "multi-source"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(dir.join("plan.dot")).unwrap().starts_with("digraph schedule {"));
}

/// Rows each of `bands` equal row bands of a view `height` rows tall reads beyond its own rows
/// when it reads `reach` rows around them, clamped to the view: what `halo_rows` counts per
/// view and halo read, computed here from the band rule alone (bands of `height * b / bands`).
fn rows_beyond_bands(height: u32, bands: u32, reach: u32) -> u64 {
    (0..bands)
        .map(|b| {
            let (y0, y1) = (height * b / bands, height * (b + 1) / bands);
            u64::from(y0.min(reach) + (height - y1).min(reach))
        })
        .sum()
}

#[test]
fn fine_all_counts_the_rows_svgf_and_firefly_suppression_read_around_each_band() {
    let dir = scratch("plan", "halo");
    let args = ["--lf", "8x4", "--resolution", "64x48", "--gpus", "4", "--scheme", "fine-all"];
    let out = plan(&args, &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("plan.json")).unwrap()).unwrap();
    // Each à-trous iteration (steps 1, 2, 4, 8, 16; 3×3 taps) reads its input (Rgba32f), the
    // guide (Rgba32f) and the albedo (Rgba16f) 1 step around its band, the first one 2 steps.
    let per_read: u64 = [2, 2, 4, 8, 16].into_iter().map(|reach| rows_beyond_bands(48, 4, reach)).sum();
    assert_eq!(per_read, 12 + 12 + 24 + 48 + 88);
    // Firefly suppression reads the radiance and position_depth (firefly_bound) and the shares
    // (firefly_spread), all Rgba32f, 2 rows around its band.
    let firefly = rows_beyond_bands(48, 4, 2);
    // The temporal pass reads the radiance and the G-buffer's position_depth, normal_metallic
    // and albedo_roughness (all Rgba32f) 3 rows around its band (its 7×7 variance estimate).
    let temporal = rows_beyond_bands(48, 4, 3);
    // And the history copies svgf_prev_color and svgf_prev_moments (Rgba32f) through `motion`,
    // HISTORY_REACH (16) rows around its band.
    let history = rows_beyond_bands(48, 4, 16);
    let views = 32;
    assert_eq!(json["halo_rows"], views * (3 * per_read + 3 * firefly + 4 * temporal + 2 * history));
    assert_eq!(
        json["halo_bytes"],
        views
            * (per_read * 64 * (16 + 16 + 8) + firefly * 64 * 3 * 16 + temporal * 64 * 4 * 16 + history * 64 * 2 * 16)
    );
    // One device has one band per view: nothing lies beyond it.
    let one = scratch("plan", "halo_one");
    let out = plan(&["--lf", "8x4", "--resolution", "64x48", "--gpus", "1", "--scheme", "fine-all"], &one);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(one.join("plan.json")).unwrap()).unwrap();
    assert_eq!(json["halo_rows"], 0);
}

/// `plan --dot` of 3 views on 2 devices per scheme, checked byte for byte. Regenerate with
/// `PARALLAX_UPDATE_GOLDEN=1 cargo test --test cli_plan`; `.ci/test.sh` renders every golden
/// with Graphviz and fails on any warning.
fn golden(name: &str, scheme: &str) {
    let dir = scratch("plan", name);
    let mut args = vec!["--lf", "3x1", "--resolution", "4x4", "--gpus", "2", "--scheme", scheme];
    if scheme == "multi-source" {
        args.extend(["--assign", "round-robin"]);
    }
    let out = plan(&args, &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let dot = std::fs::read_to_string(dir.join("plan.dot")).unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden").join(name);
    if std::env::var_os("PARALLAX_UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &dot).unwrap();
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(dot == expected, "DOT for {name} changed; inspect and regenerate if intended");
}

#[test]
fn golden_multi_source() {
    golden("plan_3x1_2gpu_multi_source.dot", "multi-source");
}

#[test]
fn golden_fine_sources() {
    golden("plan_3x1_2gpu_fine_sources.dot", "fine-sources");
}

#[test]
fn golden_fine_all() {
    golden("plan_3x1_2gpu_fine_all.dot", "fine-all");
}

/// `plan` declares the renderer's kernel graph but never opens Vulkan: with no driver to be
/// found it still plans.
#[test]
fn plan_needs_no_gpu() {
    let dir = scratch("plan", "nogpu");
    let out = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["plan", "--lf", "4x2", "--fake-devices", "3", "--scheme", "fine-all", "--json"])
        .arg(dir.join("plan.json"))
        .env("VK_DRIVER_FILES", dir.join("no_driver.json"))
        .env("VK_ICD_FILENAMES", dir.join("no_driver.json"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("plan.json")).unwrap()).unwrap();
    assert_eq!(json["devices"], 3);
    // Without a driver, a command that does need a device says so.
    let render = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["render", "--lf", "2x1", "--resolution", "8x8", "--out-dir"])
        .arg(dir.join("out"))
        .env("VK_DRIVER_FILES", dir.join("no_driver.json"))
        .env("VK_ICD_FILENAMES", dir.join("no_driver.json"))
        .output()
        .unwrap();
    assert!(!render.status.success(), "render found a device with no driver: the check above proves nothing");
}

/// `plan --ranks R` (issue 29): which rank runs which views and what it sends per frame;
/// under multi-source every view on exactly one rank, rank 0 sending nothing; under a fine
/// scheme the bands each rank's devices send other ranks' (what the plan copies between their
/// devices); a rank count that does not divide the devices is refused before any output.
#[test]
fn ranks_share_the_sets_and_say_what_each_sends() {
    let dir = scratch("plan", "ranks");
    let out = plan(&["--lf", "4x2", "--resolution", "32x24", "--fake-devices", "4", "--ranks", "2"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("plan.json")).unwrap()).unwrap();
    let ranks = json["ranks"].as_array().unwrap();
    assert_eq!(ranks.len(), 2);
    assert_eq!(
        (ranks[0]["devices"].clone(), ranks[1]["devices"].clone()),
        (serde_json::json!([0, 1]), serde_json::json!([2, 3]))
    );
    let mut views: Vec<u64> =
        ranks.iter().flat_map(|r| r["views"].as_array().unwrap()).map(|v| v.as_u64().unwrap()).collect();
    views.sort_unstable();
    assert_eq!(views, (0..8).collect::<Vec<u64>>());
    assert_eq!(ranks[0]["display_bytes_per_frame"], 0);
    let remote = ranks[1]["views"].as_array().unwrap().len() as u64;
    assert_eq!(ranks[1]["display_bytes_per_frame"], remote * 32 * 24 * 4);
    assert_eq!(ranks[1]["linear_bytes_per_frame"], remote * 32 * 24 * 16);
    let dot = std::fs::read_to_string(dir.join("plan.dot")).unwrap();
    for (gpu, rank) in [(0, 0), (1, 0), (2, 1), (3, 1)] {
        assert!(dot.contains(&format!("label=\"gpu{gpu} (rank {rank})\";")), "gpu{gpu} in {dot}");
    }

    let text = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["plan", "--lf", "4x2", "--resolution", "32x24", "--fake-devices", "4", "--ranks", "2"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(stdout.lines().any(|l| l.starts_with("rank 1        devices 2..=3, ")), "{stdout}");

    // fine-all over 2 ranks of one device: each rank sends the other what the one-process plan
    // copies from its device to the other's, and no views after the last frame.
    let fine = scratch("plan", "ranks-fine");
    let words = ["--lf", "4x2", "--resolution", "32x24", "--fake-devices", "2", "--scheme", "fine-all"];
    let out = plan(&[&words[..], &["--ranks", "2"]].concat(), &fine);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ranked: serde_json::Value = serde_json::from_slice(&std::fs::read(fine.join("plan.json")).unwrap()).unwrap();
    let ranks = ranked["ranks"].as_array().unwrap();
    for rank in ranks {
        assert_eq!(rank["display_bytes_per_frame"], 0, "{rank}");
        assert_eq!(rank["views"].as_array().unwrap().len(), 8, "bands of every view on every rank: {rank}");
    }
    let (to_1, to_0) =
        (ranks[0]["link_bytes_per_frame"].as_u64().unwrap(), ranks[1]["link_bytes_per_frame"].as_u64().unwrap());
    assert!(to_1 > 0 && to_0 > to_1, "rank 1 also sends rank 0 its finished bands: {to_1} {to_0}");
    let text = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["plan"])
        .args(words)
        .args(["--ranks", "2"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&text.stdout);
    let kib = to_0 as f64 / 1024.0;
    let line = format!(
        "rank 1        devices 1..=1, 8 views [0, 1, 2, 3, 4, 5, 6, 7], sends other ranks {kib:.1} KiB of bands per frame"
    );
    assert!(stdout.lines().any(|l| l == line), "{line} in {stdout}");

    let refused = scratch("plan", "ranks-refused");
    let before = common::snapshot(&refused);
    let out = plan(&["--lf", "4x2", "--fake-devices", "4", "--ranks", "3"], &refused);
    let needle = "--ranks 3 does not divide the 4 device(s) of --gpus/--fake-devices";
    common::assert_refused("plan --ranks", &out, 2, &[needle], &refused, &before);
}

/// `plan --json` and the DOT show the batches the copies travel in: under fine-all fewer
/// batches than copies, summed per device pair to every cross-device copy; none under
/// multi-source, whose copies are all gathers.
#[test]
fn plan_reports_the_copy_batches() {
    let dir = scratch("plan", "batches");
    let out = plan(&["--lf", "8x4", "--resolution", "64x48", "--gpus", "4", "--scheme", "fine-all"], &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("plan.json")).unwrap()).unwrap();
    let (batches, copies) = (json["copy_batches"].as_u64().unwrap(), json["cross_device_copies"].as_u64().unwrap());
    assert!(0 < batches && batches < copies, "{batches} batches for {copies} copies");
    let pairs = json["copy_batches_per_pair"].as_array().unwrap();
    assert_eq!(pairs.iter().map(|p| p["batches"].as_u64().unwrap()).sum::<u64>(), batches);
    assert_eq!(pairs.iter().map(|p| p["copies"].as_u64().unwrap()).sum::<u64>(), copies);
    assert_eq!(pairs.len(), 12, "every ordered pair of 4 devices copies");
    // 32 views on 4 devices draw as a summary: each pair's copy node says its batches.
    let dot = std::fs::read_to_string(dir.join("plan.dot")).unwrap();
    let drawn: u64 =
        dot.split("\\nin ").skip(1).map(|rest| rest.split(' ').next().unwrap().parse::<u64>().unwrap()).sum();
    assert_eq!(drawn, batches);
    // The full drawing (3 views on 2 devices) draws a batch of several copies as a cluster.
    let small = scratch("plan", "batches_full");
    let out = plan(&["--lf", "3x1", "--resolution", "4x4", "--gpus", "2", "--scheme", "fine-all"], &small);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(small.join("plan.dot")).unwrap().contains("subgraph cluster_b0 {"));
    let multi = scratch("plan", "batches_multi");
    let out = plan(&["--lf", "8x4", "--resolution", "64x48", "--gpus", "4", "--scheme", "multi-source"], &multi);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(multi.join("plan.json")).unwrap()).unwrap();
    assert_eq!(json["copy_batches"], 0);
    assert!(json["gather_copies"].as_u64().unwrap() > 0);
}
