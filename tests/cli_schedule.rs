//! `plan` shows the schedule `render` runs: for a grid of settings the plan's JSON summary and
//! DOT equal what `render` reports in render.json and writes with `--dot`, and the main job's
//! schedule is a golden file (`.ci/test.sh` renders every tests/golden/*.dot with Graphviz).
//! Regenerate the golden with `PARALLAX_UPDATE_GOLDEN=1 cargo test --test cli_schedule`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{parallax_in, scratch};

fn run(dir: &Path, args: &[String]) -> Output {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = parallax_in(dir, &args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

fn words(s: &str) -> Vec<String> {
    s.split_whitespace().map(str::to_string).collect()
}

/// Plans `schedule_flags` (with `plan.json`, `plan.dot`) and renders them for one frame (with
/// `--dot render.dot`); returns (plan.json, render.json's plan, plan.dot, render.dot).
fn plan_and_render(dir: &Path, schedule_flags: &[String]) -> (serde_json::Value, serde_json::Value, String, String) {
    let mut plan = words("-q plan --json plan.json --dot plan.dot --dot-detail full");
    plan.extend_from_slice(schedule_flags);
    run(dir, &plan);
    // --max-depth and --frames change no pass, resource or copy: they only keep the run short.
    let mut render =
        words("-q render --spp 1 --max-depth 1 --frames 1 --out-dir out --dot render.dot --dot-detail full");
    render.extend_from_slice(schedule_flags);
    run(dir, &render);
    let json = |p: PathBuf| -> serde_json::Value { serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap() };
    let planned = json(dir.join("plan.json"));
    let rendered = json(dir.join("out/render.json"))["plan"].clone();
    let text = |p: PathBuf| std::fs::read_to_string(p).unwrap();
    (planned, rendered, text(dir.join("plan.dot")), text(dir.join("render.dot")))
}

#[test]
fn plan_reports_the_pass_instances_copies_and_bytes_render_runs() {
    // Every (lf, devices, scheme) cell; the pipeline, denoising and G-buffer source rotate so
    // that each scheme meets both pipelines with and without SVGF, and every G-buffer source.
    let combos = [("reproject", true), ("reproject", false), ("path-trace", true), ("path-trace", false)];
    let schemes = ["multi-source", "fine-sources", "fine-all"];
    let mut met = std::collections::BTreeSet::new();
    let mut i = 0;
    for lf in ["4x2", "3x1"] {
        for devices in 1..=3 {
            for scheme in schemes {
                let (pipeline, denoise) = combos[i % combos.len()];
                let gbuffer = ["first-hits", "raster", "visibility"][(i / 3) % 3];
                let mut flags = words(&format!(
                    "--lf {lf} --resolution 64x48 --fake-devices {devices} --scheme {scheme} --pipeline {pipeline} \
                     --gbuffer {gbuffer}"
                ));
                if !denoise {
                    flags.push("--no-denoise".into());
                }
                if scheme == "multi-source" && lf == "4x2" && devices == 2 {
                    flags.extend(words("--sources-per-set 2"));
                }
                let dir = scratch("schedule", &format!("cell{i}"));
                let (planned, rendered, plan_dot, render_dot) = plan_and_render(&dir, &flags);
                assert_eq!(planned, rendered, "{flags:?}: plan --json and render.json's plan differ");
                for field in ["pass_instances", "cross_device_copies", "gather_copies", "bytes_per_frame"] {
                    assert!(planned[field].as_u64().is_some(), "{flags:?}: no {field} in {planned}");
                }
                assert_eq!(planned["devices"], devices, "{flags:?}");
                // Lavapipe has 64-bit buffer atomics: the G-buffer asked for is the one that ran.
                assert_eq!(planned["gbuffer"], gbuffer, "{flags:?}: plan --json names the G-buffer");
                let render_json: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(dir.join("out/render.json")).unwrap()).unwrap();
                let named =
                    [&render_json["gbuffer"], &render_json["gbuffer_requested"], &render_json["gbuffer_fallback"]];
                let expected = [serde_json::json!(gbuffer), serde_json::json!(gbuffer), serde_json::Value::Null];
                assert_eq!(named, expected.each_ref(), "{flags:?}: render.json's G-buffer");
                assert!(plan_dot == render_dot, "{flags:?}: plan --dot and render --dot differ");
                met.insert((scheme, pipeline, denoise));
                i += 1;
            }
        }
    }
    assert_eq!(met.len(), schemes.len() * combos.len(), "every scheme with every pipeline, SVGF on and off");
}

/// The schedule flags of `render` in .ci/main.sh (the other flags there change no pass,
/// resource or copy).
const MAIN_JOB: &str = "--lf 8x4 --resolution 128x96 --spacing 0.05 --fake-devices 2 --scheme multi-source";

#[test]
fn the_main_jobs_render_dot_is_golden() {
    let main_sh = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(".ci/main.sh")).unwrap();
    for flag in MAIN_JOB.split(" --") {
        assert!(main_sh.contains(flag.trim_start_matches("--")), "{flag} is no longer in .ci/main.sh: update MAIN_JOB");
    }
    let dir = scratch("schedule", "main");
    let (planned, rendered, plan_dot, render_dot) = plan_and_render(&dir, &words(MAIN_JOB));
    assert_eq!(planned, rendered);
    assert!(plan_dot == render_dot, "plan --dot and render --dot differ");
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/render_main_job.dot");
    if std::env::var_os("PARALLAX_UPDATE_GOLDEN").is_some() {
        std::fs::write(&golden, &render_dot).unwrap();
    }
    let expected = std::fs::read_to_string(&golden).unwrap_or_else(|e| panic!("{}: {e}", golden.display()));
    assert!(render_dot == expected, "render --dot of the main job changed; inspect and regenerate if intended");
}

/// `render --dot` draws the order render submits: byte for byte `plan --dot` with the same
/// flags, here a fine scheme on 3 devices whose small copies are batched at compile time, and
/// its comment per device lists every op of the device's program, in the order submitted, and
/// the barriers compiled between them
/// (the backend submits the schedule's order as it is: backend/src/segments.rs's tests).
#[test]
fn render_dot_is_plan_dot_and_lists_the_batched_order_it_submits() {
    let flags = words("--lf 3x1 --resolution 64x48 --fake-devices 3 --scheme fine-all");
    let dir = scratch("schedule", "fine_all_3");
    let (planned, rendered, plan_dot, render_dot) = plan_and_render(&dir, &flags);
    assert_eq!(planned, rendered);
    assert!(plan_dot == render_dot, "plan --dot and render --dot differ");
    let batched = serde_json::json!({"small_copies": {"chunk_bytes": 8u64 << 20}});
    assert_eq!(planned["op_order"], serde_json::json!({"requested": batched, "applied": batched}));
    assert!(render_dot.contains("label=\"op order: batched (copies of at most 8388608 B)\""), "{render_dot}");
    let mut copy_ops = 0;
    for d in 0..3 {
        let prefix = format!("    // gpu{d} submits: ");
        let ops: Vec<&str> = render_dot
            .lines()
            .find_map(|l| l.strip_prefix(prefix.as_str()))
            .unwrap_or_else(|| panic!("no ops listed for gpu{d}"))
            .split(", ")
            .collect();
        let passes = ops.iter().filter(|op| op.starts_with('p')).count();
        assert_eq!(serde_json::json!(passes), planned["passes_per_device"][d], "gpu{d}: {ops:?}");
        let barriers = ops.iter().filter(|&&op| op == "barrier").count();
        assert_eq!(serde_json::json!(barriers), planned["barriers_per_device"][d], "gpu{d}: {ops:?}");
        copy_ops += ops.len() - passes - barriers;
    }
    // Out, signal, wait and in of every copy, gathers included.
    let copies = planned["cross_device_copies"].as_u64().unwrap() + planned["gather_copies"].as_u64().unwrap();
    assert_eq!(copy_ops as u64, 4 * copies);
}
