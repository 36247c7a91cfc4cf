//! A long `parallax bench` as a person follows it: a line per cell as it ends (the progress bar
//! alone says nothing when stderr is a log file), and `--resume`, which keeps the cells that
//! already ran well from the bench.json of an earlier run into the same folder, so a matrix cut
//! short goes on where it stopped.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{Context as _, Result, bail};
use parallax_scene::input::{InputError, TEXT_FILE_LIMIT, read_bounded};

use crate::bench::case::Case;

/// The cells of `out_dir/bench.json` that ran well, by id, once that file is known to come
/// from the same matrix: the same frames and warm-up, and every case of this run that it also
/// has with the same arguments and reference (`cases`, the matrix's). No bench.json: nothing
/// to keep.
pub fn previous_cells(
    out_dir: &Path,
    cases: &[Case],
    frames: u32,
    warmup: u32,
) -> Result<HashMap<String, serde_json::Value>> {
    let path = out_dir.join("bench.json");
    // Read as every input is: a FIFO named bench.json used to block the run for ever.
    let bytes = match read_bounded(&path, TEXT_FILE_LIMIT, "bench.json") {
        Ok(bytes) => bytes,
        Err(InputError::Io { error, .. }) if error.kind() == std::io::ErrorKind::NotFound => {
            tracing::info!("--resume: no {} yet, every cell runs", path.display());
            return Ok(HashMap::new());
        }
        Err(e) => return Err(e).context("--resume"),
    };
    let json: serde_json::Value =
        serde_json::from_slice(&bytes).with_context(|| format!("--resume: {} is not JSON", path.display()))?;
    let fix = "resume with the same matrix, or give another --out-dir";
    for (key, now) in [("frames", frames), ("warmup", warmup)] {
        if json[key].as_u64() != Some(u64::from(now)) {
            bail!("--resume: {} was measured with {key} = {}, this run asks {now}: {fix}", path.display(), json[key]);
        }
    }
    let stored = json["cases"].as_array().cloned().unwrap_or_default();
    for case in cases {
        let name = serde_json::json!(case.name);
        let Some(old) = stored.iter().find(|c| c["name"] == name) else { continue };
        let (args, reference) = (serde_json::json!(case.args), serde_json::json!(case.reference));
        if old["args"] != args || old["reference"] != reference {
            bail!(
                "--resume: case {} of {} had args {} and reference {}, now {args} and {reference}: {fix}",
                case.name.as_deref().unwrap_or("--common"),
                path.display(),
                old["args"],
                old["reference"]
            );
        }
    }
    let cells = json["cells"].as_array().cloned().unwrap_or_default();
    Ok(cells.into_iter().filter(|c| c["ok"] == true).filter_map(|c| Some((c["id"].as_str()?.to_string(), c))).collect())
}

/// One line on a cell that ended: its number, id and outcome (frame time and accuracy, or the
/// first line of its error).
pub fn cell_line(done: usize, total: usize, entry: &serde_json::Value, kept: bool) -> String {
    let id = entry["id"].as_str().unwrap_or("?");
    let outcome = if entry["ok"] == true {
        let mut s = format!("{:.2} ms per frame", entry["frame_ms"]["mean_ms"].as_f64().unwrap_or(f64::NAN));
        if let Some(flip) = entry["flip"].as_f64() {
            s += &format!(", FLIP {flip:.4}");
        }
        if let Some(e) = entry["accuracy_error"].as_str() {
            s += &format!(", no accuracy: {e}");
        }
        s
    } else {
        let error = entry["error"].as_str().unwrap_or("");
        format!("failed: {}", error.lines().find(|l| !l.trim().is_empty()).unwrap_or("no message"))
    };
    let kept = if kept { " (kept from bench.json)" } else { "" };
    format!("cell {done}/{total} {id}{kept}: {outcome}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(args: &str) -> Vec<Case> {
        vec![Case { name: Some("a".into()), args: args.into(), reference: None }]
    }

    #[test]
    fn resume_keeps_the_good_cells_of_the_same_matrix_only() {
        let dir = tempfile::tempdir().unwrap();
        assert!(previous_cells(dir.path(), &matrix("--lf 2x1"), 2, 1).unwrap().is_empty());
        let json = serde_json::json!({
            "frames": 2, "warmup": 1,
            "cases": [{ "name": "a", "args": "--lf 2x1", "reference": null }],
            "cells": [{ "id": "a/x", "ok": true }, { "id": "a/y", "ok": false, "error": "boom" }],
        });
        std::fs::write(dir.path().join("bench.json"), json.to_string()).unwrap();
        let kept = previous_cells(dir.path(), &matrix("--lf 2x1"), 2, 1).unwrap();
        assert_eq!(kept.keys().collect::<Vec<_>>(), ["a/x"], "a failed cell runs again");
        let e = previous_cells(dir.path(), &matrix("--lf 2x1"), 3, 1).unwrap_err().to_string();
        assert!(e.contains("frames = 2, this run asks 3"), "{e}");
        let e = previous_cells(dir.path(), &matrix("--lf 4x1"), 2, 1).unwrap_err().to_string();
        assert!(e.contains("case a") && e.contains("\"--lf 4x1\""), "{e}");
    }

    #[test]
    fn a_cell_line_says_how_it_went() {
        let ok = serde_json::json!({ "id": "x", "ok": true, "frame_ms": { "mean_ms": 12.345 }, "flip": 0.031249 });
        assert_eq!(cell_line(1, 3, &ok, false), "cell 1/3 x: 12.35 ms per frame, FLIP 0.0312");
        let failed = serde_json::json!({ "id": "y", "ok": false, "error": "\nerror: too many devices\nmore" });
        assert_eq!(
            cell_line(2, 3, &failed, true),
            "cell 2/3 y (kept from bench.json): failed: error: too many devices"
        );
    }
}
