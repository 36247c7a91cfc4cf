//! `render` over three MPI ranks (issue 29; a build with `--features mpi`, run under
//! `mpirun --oversubscribe -n 3`, each rank one logical lavapipe device): the views are those of
//! one process over three logical devices, bit for bit, under multi-source (whole sets per
//! rank) and under the fine schemes (bands exchanged between the ranks every frame); a rank
//! that fails or falls silent ends the run with one message naming it and its host, and leaves
//! no output behind. Without
//! mpirun on the PATH the tests say so and skip; with it they run. A build without the feature
//! refuses to run as one of several ranks.

mod common;

/// Under mpirun, a build without MPI would have every rank render everything into one folder.
#[cfg(not(feature = "mpi"))]
#[test]
fn a_build_without_mpi_refuses_to_run_as_one_of_several_ranks() {
    let dir = common::scratch("ranks", "no-mpi");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args(["render", "--lf", "2x1", "--resolution", "8x8", "--out-dir", "out"])
        .env("OMPI_COMM_WORLD_SIZE", "3")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: started as one of 3 MPI ranks, but this parallax was built without MPI, so each rank would render \
         the whole light field alone: build it with cargo build --release --features mpi\n"
    );
    assert!(!dir.join("out").exists());
}

#[cfg(feature = "mpi")]
mod under_mpirun {
    use std::path::Path;
    use std::process::{Command, Stdio};

    use super::common::{parallax_in, scratch, wait_or_kill};

    /// A tiny light field under the default scheme (multi-source), two measured frames of a dolly
    /// (so every rank must take rank 0's cameras), with the EXR layers and hole masks that ranks
    /// send.
    const RENDER: [&str; 15] = [
        "render",
        "--lf",
        "4x2",
        "--resolution",
        "32x24",
        "--frames",
        "2",
        "--warmup",
        "1",
        "--motion",
        "dolly",
        "--layers",
        "--spp",
        "1",
        "-q",
    ];

    /// mpirun, or None after saying why the test skips.
    fn mpirun() -> Option<&'static str> {
        let found = Command::new("mpirun").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status();
        if found.is_ok_and(|s| s.success()) {
            Some("mpirun")
        } else {
            eprintln!("skipped: mpirun is not on the PATH (install openmpi-bin: bash .ci/setup.sh)");
            None
        }
    }

    /// `mpirun -n 3 parallax render …` in `dir`, every rank on one logical device; `fault` goes to
    /// every rank as PARALLAX_FAULT (ranks on this host inherit mpirun's environment).
    fn render_on_three_ranks(mpirun: &str, dir: &Path, extra: &[&str], fault: Option<&str>) -> std::process::Output {
        let mut command = Command::new(mpirun);
        // Each launch gets its own session directory: Open MPI keeps one per host and user under
        // TMPDIR (`/tmp/ompi.<host>.<uid>`), and two tests' mpiruns sharing it collided there
        // (one's clean-up removed what the other was starting in).
        // Beside `dir`, not in it: the tests check what a run leaves in `dir`.
        let session = dir.with_extension("mpi");
        std::fs::create_dir_all(&session).unwrap();
        // CI runs as root, on two cores.
        command
            .env("TMPDIR", &session)
            .args(["--allow-run-as-root", "--oversubscribe", "-n", "3"])
            .arg(env!("CARGO_BIN_EXE_parallax"))
            .args(RENDER)
            .args(["--fake-devices", "1", "--out-dir", "out"])
            .args(extra)
            .env("PARALLAX_VALIDATION", "1")
            .env_remove("PARALLAX_FAULT")
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if let Some(fault) = fault {
            command.env("PARALLAX_FAULT", fault);
        }
        let output = wait_or_kill(command.spawn().unwrap(), "mpirun -n 3 parallax render");
        let _ = std::fs::remove_dir_all(&session);
        output
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    /// Renders `extra` (a scheme) in one process over three logical devices into `one` and over
    /// three ranks into `out`, and checks that every view, the quilt, and render.json's plan and
    /// setup are the same; returns the two render.json.
    fn same_as_one_process(mpirun: &str, dir: &Path, extra: &[&str]) -> (serde_json::Value, serde_json::Value) {
        let one = parallax_in(dir, &[&RENDER[..], extra, &["--fake-devices", "3", "--out-dir", "one"]].concat());
        assert!(one.status.success(), "{}", String::from_utf8_lossy(&one.stderr));
        let ranks = render_on_three_ranks(mpirun, dir, extra, None);
        assert!(ranks.status.success(), "{}", String::from_utf8_lossy(&ranks.stderr));

        let (one, three) = (dir.join("one"), dir.join("out"));
        assert_eq!(files(&one), files(&three));
        let views: Vec<String> = files(&one).into_iter().filter(|f| f.starts_with("view_")).collect();
        assert_eq!(views.iter().filter(|f| f.ends_with(".exr")).count(), 8, "{views:?}");
        for name in views.iter().map(String::as_str).chain(["lightfield.png"]) {
            assert!(
                std::fs::read(one.join(name)).unwrap() == std::fs::read(three.join(name)).unwrap(),
                "{name} differs"
            );
        }
        let json = |d: &Path| -> serde_json::Value {
            serde_json::from_slice(&std::fs::read(d.join("render.json")).unwrap()).unwrap()
        };
        let (one, three) = (json(&one), json(&three));
        for key in ["exposure", "missing_pixels", "plan", "setup", "devices"] {
            assert_eq!(one[key], three[key], "render.json's {key}");
        }
        assert_eq!(one["ranks"], serde_json::Value::Null);
        assert_eq!(three["ranks"]["count"], 3);
        (one, three)
    }

    #[test]
    fn three_ranks_render_the_views_of_one_process_bit_for_bit() {
        let Some(mpirun) = mpirun() else { return };
        let dir = scratch("ranks", "same");
        let (_, three) = same_as_one_process(mpirun, &dir, &[]);
        let per_rank = three["ranks"]["per_rank"].as_array().unwrap();
        let mut views: Vec<u64> =
            per_rank.iter().flat_map(|r| r["views"].as_array().unwrap()).map(|v| v.as_u64().unwrap()).collect();
        views.sort_unstable();
        assert_eq!(views, (0..8).collect::<Vec<u64>>(), "every view on exactly one rank");
        for (r, rank) in per_rank.iter().enumerate() {
            assert_eq!(rank["devices"], serde_json::json!([r]));
            assert_eq!(rank["bytes_sent"].as_u64().unwrap() > 0, r > 0, "{rank}");
        }
        assert_eq!(per_rank[2]["submit_ms_per_frame"].as_array().unwrap().len(), 2, "one report per measured frame");
        assert!(three["links"]["pairs"].as_array().unwrap().is_empty(), "multi-source: no link between ranks");
    }

    /// Under a fine scheme views are cut in bands over the three devices, one per rank: the
    /// bands travel between the ranks every frame, through `remote` links (rank 0's, in its
    /// render.json, receive at least the others' finished bands), and rank 0 holds every view.
    fn a_fine_scheme_renders_across_ranks_as_in_one_process(scheme: &str) {
        let Some(mpirun) = mpirun() else { return };
        let dir = scratch("ranks", scheme);
        let (one, three) = same_as_one_process(mpirun, &dir, &["--scheme", scheme]);
        let pairs = three["links"]["pairs"].as_array().unwrap();
        assert!(pairs.iter().all(|p| p["kind"] == "remote"), "{pairs:?}");
        for (from, to) in [(1, 0), (2, 0)] {
            let link = pairs.iter().find(|p| (p["from"].as_u64(), p["to"].as_u64()) == (Some(from), Some(to)));
            let link = link.unwrap_or_else(|| panic!("no link {from} → {to}: {pairs:?}"));
            assert_eq!(link["kind"], "remote", "{link}");
            assert!(link["bytes_per_frame"].as_u64().unwrap() > 0, "{link}");
        }
        // The bytes rank 0 receives a frame are those its device receives from the others in
        // one process.
        let received = |json: &serde_json::Value| -> u64 {
            let pairs = json["links"]["pairs"].as_array().unwrap();
            pairs.iter().filter(|p| p["to"] == 0).map(|p| p["bytes_per_frame"].as_u64().unwrap()).sum()
        };
        assert_eq!(received(&three), received(&one));
    }

    #[test]
    fn fine_sources_renders_across_ranks_as_in_one_process() {
        a_fine_scheme_renders_across_ranks_as_in_one_process("fine-sources");
    }

    #[test]
    fn fine_all_renders_across_ranks_as_in_one_process() {
        a_fine_scheme_renders_across_ranks_as_in_one_process("fine-all");
    }

    #[test]
    fn a_failing_rank_ends_the_run_naming_it_and_leaves_nothing() {
        let Some(mpirun) = mpirun() else { return };
        let dir = scratch("ranks", "fails");
        let out = render_on_three_ranks(mpirun, &dir, &[], Some("rank-fails:2:1"));
        let stderr = String::from_utf8_lossy(&out.stderr);
        // Rank 0 aborts the run with its exit status, which mpirun returns.
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "one message: {stderr}");
        assert!(errors[0].starts_with("error: rank 2 on host "), "{stderr}");
        assert!(errors[0].ends_with(" failed: injected fault at frame 1 (PARALLAX_FAULT=rank-fails:2:1)"), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(files(&dir), Vec::<String>::new(), "a failed run left files behind");
    }

    /// Rank 2 stops answering after its first frame; the others finish within the timeout (a
    /// generous one: it is a bound on a hang, not a measure). Under a fine scheme the others also
    /// wait for its bands, and those waits end at the same timeout.
    fn a_silent_rank_ends_the_run_at_the_rank_timeout(scheme: &str) {
        let Some(mpirun) = mpirun() else { return };
        let dir = scratch("ranks", &format!("stalls-{scheme}"));
        let extra = ["--scheme", scheme, "--rank-timeout", "60"];
        let out = render_on_three_ranks(mpirun, &dir, &extra, Some("rank-stalls:2:1"));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "one message: {stderr}");
        // Rank 0's own timeout or, under a fine scheme, rank 1's (waiting for rank 2's bands) may
        // fire first: either way the one message names rank 2 as the silent one.
        let silent = errors[0].find("rank 2 on host ").map(|at| &errors[0][at..]);
        assert!(
            silent.is_some_and(|s| s.contains(" sent nothing for 60 s (--rank-timeout): it hangs or died")),
            "{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(files(&dir), Vec::<String>::new(), "a failed run left files behind");
    }

    #[test]
    fn a_silent_rank_ends_the_run_at_the_rank_timeout_under_multi_source() {
        a_silent_rank_ends_the_run_at_the_rank_timeout("multi-source");
    }

    #[test]
    fn a_silent_rank_ends_the_run_at_the_rank_timeout_under_fine_all() {
        a_silent_rank_ends_the_run_at_the_rank_timeout("fine-all");
    }

    /// Under a fine scheme the others wait for the failed rank's bands: the run still ends
    /// with the one message naming it (rank 0 finds it once its link gives up, after
    /// --rank-timeout), and nothing is written.
    #[test]
    fn a_failing_rank_under_a_fine_scheme_ends_the_run_naming_it_and_leaves_nothing() {
        let Some(mpirun) = mpirun() else { return };
        let dir = scratch("ranks", "fine-fails");
        // The healthy ranks wait on the failed rank's bands until the timeout: 60 s bounds a hang
        // with room for 18 ranks of parallel tests sharing CI's two cores.
        let extra = ["--scheme", "fine-all", "--rank-timeout", "60"];
        let out = render_on_three_ranks(mpirun, &dir, &extra, Some("rank-fails:2:1"));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "one message: {stderr}");
        assert!(errors[0].starts_with("error: rank 2 on host "), "{stderr}");
        assert!(errors[0].ends_with(" failed: injected fault at frame 1 (PARALLAX_FAULT=rank-fails:2:1)"), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(files(&dir), Vec::<String>::new(), "a failed run left files behind");
    }
}
