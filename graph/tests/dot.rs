//! DOT export: byte-stable, golden for small configurations, structurally what it promises.
//! Regenerate the goldens with `PARALLAX_UPDATE_GOLDEN=1 cargo test -p parallax-graph --test dot`.
//! `.ci/run` renders every golden with Graphviz and fails on any warning.

mod common;

use std::path::PathBuf;

use common::*;
use parallax_graph::*;

fn golden(name: &str, scheme: Scheme) {
    let (_, s) = standard(&grid(3, 1, 4), 2, scheme, AssignStrategy::RoundRobin, None);
    let dot = s.to_dot();
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/golden").join(name);
    if std::env::var_os("PARALLAX_UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &dot).unwrap();
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(dot, expected, "DOT for {name} changed; inspect and regenerate if intended");
}

#[test]
fn golden_multi_source() {
    golden("plan_3x1_2gpu_multi_source.dot", Scheme::MultiSource);
}

#[test]
fn golden_fine_sources() {
    golden("plan_3x1_2gpu_fine_sources.dot", Scheme::FineSources);
}

#[test]
fn golden_fine_all() {
    golden("plan_3x1_2gpu_fine_all.dot", Scheme::FineAll);
}

#[test]
fn dot_is_byte_stable_across_compiles() {
    let lf = preset(LayoutSpec::Nelf, 8);
    let a = standard(&lf, 3, Scheme::FineAll, AssignStrategy::Compact, None).1.to_dot();
    let b = standard(&lf, 3, Scheme::FineAll, AssignStrategy::Compact, None).1.to_dot();
    assert_eq!(a, b);
}

#[test]
fn dot_shows_clusters_delta_edges_and_copies() {
    let (_, s) = standard(&grid(3, 1, 4), 2, Scheme::FineSources, AssignStrategy::RoundRobin, None);
    let dot = s.to_dot();
    assert_eq!(dot.matches("subgraph cluster_gpu").count(), 2);
    assert_eq!(dot.matches("shape=cds").count(), s.copies.len(), "one red node per copy");
    assert!(dot.contains("style=dashed, color=\"#1f5fbf\", label=\"δ\""), "same-device δ-edges are dashed blue");
    assert!(dot.contains("style=dashed, color=\"#cc0000\", label=\"δ\""), "δ-edges through a copy are dashed red");
    for i in 0..s.instances.len() {
        assert!(dot.contains(&format!("  p{i} [label=")), "instance p{i} drawn");
    }
}
