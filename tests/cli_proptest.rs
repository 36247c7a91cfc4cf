//! Random numeric command-line values never make `plan` or `trace` panic: every run either
//! succeeds or is refused with exit code 1 or 2, one `error:` line first, and leaves no file.
//! Sizes stay tiny (trace at most 8×8 px, 1–2 spp) so that the GPU cases run on lavapipe.

mod common;

use common::{PROPTEST_SEED, parallax_in, scratch, snapshot};

use proptest::prelude::*;

/// Numbers a careless user might type: edge cases of every type, plus ordinary ones.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e38".to_string()),
        Just("1e-40".to_string()),
        Just("4294967295".to_string()),
        Just("18446744073709551616".to_string()),
        (-1000.0f64..1000.0).prop_map(|v| format!("{v}")),
        (0u32..20).prop_map(|v| v.to_string()),
    ]
}

fn pair(max: u32) -> impl Strategy<Value = String> {
    prop_oneof![3 => (0..=max, 0..=max).prop_map(|(w, h)| format!("{w}x{h}")), 1 => number()]
}

/// Mostly a valid value from `valid`, sometimes any number: so that most runs get past the
/// parser and exercise planning and tracing, and some do not.
fn mostly<S: Strategy<Value = String> + 'static>(valid: S) -> impl Strategy<Value = String> {
    prop_oneof![3 => valid, 1 => number()]
}

fn real(range: std::ops::Range<f64>) -> impl Strategy<Value = String> {
    mostly(range.prop_map(|v| format!("{v}")))
}

/// Checks one run's outcome; `dir` must not change unless it succeeded.
fn check_outcome(args: &[String], dir: &std::path::Path) -> Result<(), TestCaseError> {
    let before = snapshot(dir);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = parallax_in(dir, &args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    prop_assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    let code = out.status.code();
    prop_assert!(matches!(code, Some(0..=2)), "{args:?}: exit {code:?}: {stderr}");
    if code != Some(0) {
        prop_assert!(stderr.lines().any(|l| l.starts_with("error: ")), "{args:?}: no error line: {stderr}");
        prop_assert!(snapshot(dir) == before, "{args:?} failed but changed {}", dir.display());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, rng_seed: proptest::test_runner::RngSeed::Fixed(PROPTEST_SEED), ..ProptestConfig::default() })]

    #[test]
    fn plan_never_panics(
        lf in pair(12),
        gpus in mostly((1u32..6).prop_map(|v| v.to_string())),
        spacing in real(0.0..1.0),
        resolution in pair(64),
        scheme in prop_oneof![Just("multi-source"), Just("fine-sources"), Just("fine-all")],
        sources in proptest::option::of(number()),
    ) {
        let dir = scratch("proptest", "plan");
        let mut args: Vec<String> = ["plan", "--lf", &lf, "--gpus", &gpus, "--spacing", &spacing]
            .map(String::from).to_vec();
        args.extend(["--resolution".into(), resolution, "--scheme".into(), scheme.into()]);
        if let Some(s) = sources {
            args.extend(["--sources".into(), s]);
        }
        args.extend(["--json".into(), "plan.json".into(), "--dot".into(), "plan.dot".into()]);
        check_outcome(&args, &dir)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, failure_persistence: None, rng_seed: proptest::test_runner::RngSeed::Fixed(PROPTEST_SEED), ..ProptestConfig::default() })]

    #[test]
    fn trace_never_panics(
        resolution in pair(8),
        spp in prop_oneof![1 => Just("0"), 4 => Just("1"), 1 => Just("2"), 1 => Just("-1")],
        max_depth in mostly((0u32..8).prop_map(|v| v.to_string())),
        exposure in real(0.01..100.0),
        sun in proptest::option::of(proptest::collection::vec(real(-10.0..10.0), 3..=6)),
        sky in proptest::option::of(proptest::collection::vec(real(0.0..10.0), 2..=4)),
        device in prop_oneof![Just("--cpu"), Just("--fake-devices=1"), Just("--fake-devices=2")],
    ) {
        // Sizes beyond 8×8 would be slow to trace: only the refusals of larger ones are kept.
        let tiny = resolution.split_once('x')
            .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
            .is_none_or(|(w, h)| w <= 8 && h <= 8);
        prop_assume!(tiny);
        let dir = scratch("proptest", "trace");
        let mut args: Vec<String> = ["trace", device, "--resolution", &resolution, "--spp", spp]
            .map(String::from).to_vec();
        args.extend(["--max-depth".into(), max_depth, "--exposure".into(), exposure]);
        if let Some(sun) = sun {
            args.extend(["--sun".into(), sun.join(",")]);
        }
        if let Some(sky) = sky {
            args.extend(["--sky".into(), sky.join(",")]);
        }
        args.extend(["--out".into(), "t.exr".into(), "--png".into(), "t.png".into()]);
        check_outcome(&args, &dir)?;
    }
}
