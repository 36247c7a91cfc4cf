//! Source selection and assignment quality.

mod common;

use common::*;
use glam::DVec2;
use parallax_graph::source::{geometric_median, medoid, weber_cost};
use parallax_graph::*;
use proptest::prelude::*;

/// Brute-force nearest view to a point, lowest index on exact ties.
fn brute_nearest(points: &[DVec2], target: DVec2) -> usize {
    (0..points.len())
        .min_by(|&a, &b| (points[a] - target).length().total_cmp(&(points[b] - target).length()).then(a.cmp(&b)))
        .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, rng_seed: proptest::test_runner::RngSeed::Fixed(PROPTEST_SEED), ..ProptestConfig::default() })]
    /// The median is optimal (no data point and no nearby probe does better), and the medoid is
    /// the brute-force nearest view to it, whose Weber cost is close to the true medoid's.
    #[test]
    fn medoid_matches_brute_force(raw in prop::collection::vec((-100i32..100, -100i32..100), 1..40)) {
        let points: Vec<DVec2> = raw.iter().map(|&(x, y)| DVec2::new(x as f64 * 0.01, y as f64 * 0.01)).collect();
        let m = geometric_median(&points).unwrap();
        prop_assert!(m.point.is_finite() && m.iterations < source::MAX_ITERATIONS);
        let cost = weber_cost(&points, m.point);
        for probe in points.iter().copied().chain([DVec2::X, DVec2::Y, -DVec2::X, -DVec2::Y].map(|d| m.point + d * 1e-4)) {
            prop_assert!(cost <= weber_cost(&points, probe) + 1e-9, "probe {probe} beats median {m:?}");
        }
        let views: Vec<ViewId> = (0..points.len() as u32).map(ViewId).collect();
        let chosen = medoid(&views, |v| points[v.index()]).unwrap();
        let brute = brute_nearest(&points, m.point);
        let d_chosen = (points[chosen.index()] - m.point).length();
        let d_brute = (points[brute] - m.point).length();
        prop_assert!((d_chosen - d_brute).abs() < 1e-9, "chosen {chosen:?} at {d_chosen}, brute {brute} at {d_brute}");
        let true_medoid = points.iter().map(|&p| weber_cost(&points, p)).fold(f64::INFINITY, f64::min);
        // The nearest view to the median is within the median's distance of the optimum per point.
        prop_assert!(weber_cost(&points, points[chosen.index()]) <= true_medoid + d_brute * points.len() as f64 + 1e-9);
    }
}

#[test]
fn medoid_ties_go_to_the_lowest_index() {
    let square = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(0.0, 1.0), DVec2::new(1.0, 1.0)];
    let views: Vec<ViewId> = (0..4).map(ViewId).collect();
    assert_eq!(medoid(&views, |v| square[v.index()]), Some(ViewId(0)));
    let reversed: Vec<ViewId> = views.iter().rev().copied().collect();
    assert_eq!(medoid(&reversed, |v| square[v.index()]), Some(ViewId(0)));
}

/// Mean distance from each target to its set's source.
fn mean_target_distance(lf: &LightField, n: u32, assign: AssignStrategy) -> f64 {
    let plan = Partition::new(lf, &PartitionConfig { devices: n, scheme: Scheme::MultiSource, assign, sources: None })
        .unwrap();
    let t = &plan.topology;
    let (sum, count) = (0..lf.len())
        .filter(|&v| !t.is_source[v])
        .map(|v| (lf.positions[v] - lf.position(t.sources_of[v][0])).length())
        .fold((0.0, 0), |(s, c), d| (s + d, c + 1));
    sum / count.max(1) as f64
}

#[test]
fn compact_assignment_is_never_worse_than_the_paper_strategies() {
    for spec in [LayoutSpec::Multiscopic, LayoutSpec::Nelf] {
        let lf = preset(spec, 8);
        for n in 2..=4 {
            let compact = mean_target_distance(&lf, n, AssignStrategy::Compact);
            let rr = mean_target_distance(&lf, n, AssignStrategy::RoundRobin);
            let contiguous = mean_target_distance(&lf, n, AssignStrategy::Contiguous);
            assert!(
                compact <= rr + 1e-12 && compact <= contiguous + 1e-12,
                "{spec:?} N={n}: compact {compact} rr {rr} contiguous {contiguous}"
            );
        }
    }
}

#[test]
fn compact_splits_nelf_by_eye() {
    let lf = preset(LayoutSpec::Nelf, 8);
    let a = assign(AssignStrategy::Compact, &lf.positions, 2).unwrap();
    for v in 0..72 {
        assert_eq!(
            a.set_of_view[v],
            u32::from(v % 12 >= 6),
            "view {v}: left eye on one device, right eye on the other"
        );
    }
}

#[test]
fn explicit_sources_are_checked() {
    let lf = grid(4, 1, 8);
    let config = |scheme, sources| PartitionConfig { devices: 2, scheme, assign: AssignStrategy::RoundRobin, sources };
    assert_eq!(
        Partition::new(&lf, &config(Scheme::FineAll, Some(vec![0, 4]))).unwrap_err(),
        PartitionError::SourceOutOfRange { view: 4, views: 4 }
    );
    assert_eq!(
        Partition::new(&lf, &config(Scheme::FineAll, Some(vec![1, 1]))).unwrap_err(),
        PartitionError::DuplicateSource(1)
    );
    assert_eq!(Partition::new(&lf, &config(Scheme::FineAll, Some(vec![]))).unwrap_err(), PartitionError::NoSources);
    assert_eq!(
        Partition::new(&lf, &config(Scheme::FineAll, Some(vec![0, 1, 2, 3]))).unwrap_err(),
        PartitionError::AllViewsSources { sources: 4, views: 4 }
    );
    assert_eq!(
        Partition::new(&lf, &config(Scheme::MultiSource, Some(vec![0]))).unwrap_err(),
        PartitionError::SourcesWithMultiSource
    );
    let plan = Partition::new(&lf, &config(Scheme::FineSources, Some(vec![3, 0]))).unwrap();
    assert_eq!(plan.sources, vec![ViewId(0), ViewId(3)]);
    assert_eq!(parse_source_list("0, 99").unwrap(), vec![0, 99]);
    assert_eq!(parse_source_list("0;99").unwrap_err(), PartitionError::BadSourceList("0;99".into()));
}

#[test]
fn sources_per_set_gives_k_sources_per_set_and_each_target_its_nearest() {
    let lf = grid(8, 4, 8);
    let config =
        PartitionConfig { devices: 2, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::with_sources_per_set(&lf, &config, 2).unwrap();
    assert_eq!(plan.sources.len(), 4, "2 sets × 2 sources");
    let sets = plan.assignment.as_ref().unwrap();
    for v in 0..lf.len() as u32 {
        let set = sets.set_of_view[v as usize];
        let own: Vec<ViewId> = plan.sources.iter().copied().filter(|s| sets.set_of_view[s.index()] == set).collect();
        assert_eq!(own.len(), 2, "set {set} has its two sources");
        let of = &plan.topology.sources_of[v as usize];
        if own.contains(&ViewId(v)) {
            assert!(of.is_empty());
            continue;
        }
        assert_eq!(of.len(), 1, "a target reads one source");
        let d = |s: ViewId| lf.position(ViewId(v)).distance(lf.position(s));
        assert!(own.iter().all(|&s| d(of[0]) <= d(s)), "view {v} reads its nearest source");
    }
    assert_eq!(
        Partition::with_sources_per_set(&lf, &config, 17).err(),
        Some(PartitionError::TooManySourcesPerSet { per_set: 17, smallest: 16 })
    );
    let fine = PartitionConfig { scheme: Scheme::FineAll, ..config.clone() };
    assert_eq!(Partition::with_sources_per_set(&lf, &fine, 2).err(), Some(PartitionError::SourcesPerSetWithFineScheme));
    assert_eq!(Partition::with_sources_per_set(&lf, &config, 0).err(), Some(PartitionError::NoSourcesPerSet));
}

#[test]
fn fine_scheme_targets_read_their_sources_nearest_first() {
    let lf = grid(5, 1, 8);
    let config = PartitionConfig {
        devices: 1,
        scheme: Scheme::FineAll,
        assign: AssignStrategy::Compact,
        sources: Some(vec![0, 4]),
    };
    let plan = Partition::new(&lf, &config).unwrap();
    assert_eq!(plan.topology.sources_of[1], vec![ViewId(0), ViewId(4)]);
    assert_eq!(plan.topology.sources_of[3], vec![ViewId(4), ViewId(0)]);
}
