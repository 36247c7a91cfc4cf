//! DOT export: byte-stable and structurally what it promises, on the test pipeline. The goldens
//! of the renderer's own schedules are checked by the CLI's tests (tests/cli_plan.rs).

mod common;

use common::*;
use parallax_graph::*;

#[test]
fn dot_is_byte_stable_across_compiles() {
    let lf = preset(LayoutSpec::Nelf, 8);
    let a = test_schedule(&lf, 3, Scheme::FineAll, AssignStrategy::Compact, None).1.to_dot();
    let b = test_schedule(&lf, 3, Scheme::FineAll, AssignStrategy::Compact, None).1.to_dot();
    assert_eq!(a, b);
}

#[test]
fn dot_shows_clusters_delta_edges_and_copies() {
    let (_, s) = test_schedule(&grid(3, 1, 4), 2, Scheme::FineSources, AssignStrategy::RoundRobin, None);
    let dot = s.to_dot();
    assert_eq!(dot.matches("subgraph cluster_gpu").count(), 2);
    assert_eq!(dot.matches("shape=cds").count(), s.copies.len(), "one red node per copy");
    assert!(dot.contains("style=dashed, color=\"#1f5fbf\", label=\"δ\""), "same-device δ-edges are dashed blue");
    assert!(dot.contains("style=dashed, color=\"#cc0000\", label=\"δ\""), "δ-edges through a copy are dashed red");
    for i in 0..s.instances.len() {
        assert!(dot.contains(&format!("  p{i} [label=")), "instance p{i} drawn");
    }
}

#[test]
fn multiscopic_on_8_devices_summary_is_one_node_per_pass_and_device() {
    let s = test_schedule(&preset(LayoutSpec::Multiscopic, 8), 8, Scheme::FineAll, AssignStrategy::Compact, None).1;
    let dot = s.to_dot_summary();
    assert!(dot.len() < 64 << 10, "{} bytes", dot.len());
    let passes: std::collections::BTreeSet<(u32, &str)> =
        s.instances.iter().map(|i| (i.device.0, i.name.as_str())).collect();
    let nodes = dot.lines().filter(|l| l.trim_start().starts_with('p') && l.contains("instances")).count();
    assert_eq!(nodes, passes.len());
    // Every instance is counted once.
    let counted: u64 = dot
        .lines()
        .filter_map(|l| l.split_once("\\n")?.1.split_once(" instances").map(|(n, _)| n.parse::<u64>().unwrap()))
        .sum();
    assert_eq!(counted, s.instances.len() as u64);
    assert_eq!(dot, s.to_dot_summary(), "deterministic");
}
