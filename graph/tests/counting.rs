//! The paper's dependency counts (DESIGN §2 convention) on the presets and on random grids.

mod common;

use common::*;
use parallax_graph::*;
use proptest::prelude::*;

/// Checks the counts of one configuration; `k` is the number of sources.
fn check_counts(lf: &LightField, n: u32, scheme: Scheme, assign: AssignStrategy) {
    let m = lf.len();
    let (plan, s) = test_schedule(lf, n, scheme, assign, None);
    let k = plan.sources.len();
    let n = n as usize;
    let report = s.validate();
    assert!(report.is_ok(), "{scheme:?} M={m} N={n}: {:?}", &report.errors[..report.errors.len().min(5)]);
    match scheme {
        Scheme::MultiSource => {
            assert_eq!(k, n, "one source per set");
            assert_eq!(s.delta_edges.len(), m - n, "D = M − N");
            assert_eq!(s.dependency_copies().count(), 0, "no copy before the gather");
            let set_of_view = plan.set_of_view().unwrap();
            for e in &s.delta_edges {
                let device = s.instance(e.consumer).device.0;
                assert_eq!(device, set_of_view[e.target.index()], "δ-edge consumer on its set's device");
                assert_eq!(set_of_view[e.source.index()], device, "δ-edge source on the same device");
            }
        }
        Scheme::FineAll => {
            assert_eq!(s.delta_edges.len(), n * k * (m - k), "N·k·(M−k)");
        }
        Scheme::FineSources => {
            assert_eq!(s.delta_edges.len(), k * (m - k), "k·(M−k)");
            assert!(
                s.delta_edges.iter().all(|e| s.instance(e.consumer).device == DeviceId(0)),
                "reprojection on device 0"
            );
            assert_eq!(s.dependency_copies().count(), (n - 1) * k, "(N−1)·k strip copies");
        }
    }
}

#[test]
fn presets_follow_the_paper_counts() {
    // Tiny resolution: counts do not depend on it, and bands need at least N rows.
    for spec in [LayoutSpec::Multiscopic, LayoutSpec::Nelf] {
        let lf = preset(spec, 8);
        for n in 1..=4 {
            for scheme in Scheme::ALL {
                check_counts(&lf, n, scheme, AssignStrategy::RoundRobin);
            }
        }
    }
}

#[test]
fn gather_brings_every_view_home() {
    let lf = preset(LayoutSpec::Nelf, 8);
    let (plan, s) = test_schedule(&lf, 3, Scheme::MultiSource, AssignStrategy::Compact, None);
    let away = plan.set_of_view().unwrap().iter().filter(|&&d| d != 0).count();
    assert_eq!(s.gather_copies().count(), away, "one gather per view finished away from device 0");
    let (_, s) = test_schedule(&lf, 3, Scheme::FineAll, AssignStrategy::Compact, None);
    assert_eq!(s.gather_copies().count(), 72 * 2, "each view's two remote bands");
    let bytes: u64 = s.gather_copies().map(|c| c.bytes).sum();
    assert_eq!(bytes, 72 * (8 - 2) * 8 * 4, "rows of bands 1 and 2 of every 8×8 RGBA8 display image");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(PROPTEST_SEED), ..ProptestConfig::default() })]
    #[test]
    fn random_grids_follow_the_counts(cols in 1u32..9, rows in 1u32..5, n in 1u32..5, scheme in 0usize..3, assign in 0usize..3) {
        let lf = grid(cols, rows, 6);
        prop_assume!(n as usize <= lf.len());
        let assign = [AssignStrategy::RoundRobin, AssignStrategy::Contiguous, AssignStrategy::Compact][assign];
        check_counts(&lf, n, Scheme::ALL[scheme], assign);
    }
}
