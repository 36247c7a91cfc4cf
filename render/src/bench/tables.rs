//! The markdown of `parallax bench` (bench.md), from bench.json's cells: every cell; per stage
//! and device (the paper's Table 1); frame time per scheme and assignment against the cases
//! (Tables 2 and 5); and scaling over device counts: speed-up, parallel efficiency T₁ / (N·T_N)
//! and the gather's share of the frame (issue 13's figures).

use std::collections::BTreeMap;

/// bench.md: every table, each under its heading.
pub fn markdown(cells: &[serde_json::Value]) -> String {
    format!(
        "{}\n## Per stage, ms per frame\n\n{}\n## Frame ms per scheme and case\n\n{}\n## Scaling over devices\n\n{}",
        table(cells),
        stage_table(cells),
        scheme_table(cells),
        scaling_table(cells)
    )
}

/// A number with `digits` decimals, or a dash where there is none.
fn num(v: &serde_json::Value, digits: usize) -> String {
    v.as_f64().map_or("–".to_string(), |x| format!("{x:.digits$}"))
}

/// The cells as a markdown table.
fn table(cells: &[serde_json::Value]) -> String {
    let mut out = String::from(
        "| case | cell | frame ms (mean / median / p95) | views/s | busy fraction per device | copy MB/frame | \
         missing pixels | hole fill ms | FLIP | PSNR dB |\n",
    );
    out.push_str("|---|---|---|---:|---|---:|---:|---:|---:|---:|\n");
    for c in cells {
        let (case, id) = (c["case"].as_str().unwrap_or("–"), c["id"].as_str().unwrap_or(""));
        if c["ok"] != true {
            // The cell's one-line diagnosis (stderr may hold notes before it).
            let error = c["error"].as_str().unwrap_or("");
            let line = error.lines().find(|l| l.starts_with("error:")).unwrap_or(error);
            out.push_str(&format!("| {case} | {id} | failed: {line} | | | | | | | |\n"));
            continue;
        }
        let f = &c["frame_ms"];
        let busy: Vec<String> =
            c["busy_fraction"].as_array().map_or(Vec::new(), |b| b.iter().map(|v| num(v, 2)).collect());
        out.push_str(&format!(
            "| {case} | {id} | {} / {} / {} | {} | {} | {} | {} | {} | {} | {} |\n",
            num(&f["mean_ms"], 2),
            num(&f["median_ms"], 2),
            num(&f["p95_ms"], 2),
            num(&c["views_per_s"], 1),
            busy.join(" / "),
            c["copy_bytes_per_frame"].as_f64().map_or("–".into(), |b| format!("{:.3}", b / 1e6)),
            // Path tracing leaves no holes to count.
            c["missing_pixels"]["overall"]
                .as_f64()
                .filter(|_| c["pipeline"] == "reproject")
                .map_or("–".into(), |m| format!("{:.2} %", 100.0 * m)),
            num(&c["hole_fill_ms"], 3),
            num(&c["flip"], 4),
            num(&c["psnr_db"], 2),
        ));
    }
    out
}

/// The paper's Table 1 over the cells that ran: one row per stage, one column per cell, each
/// entry the stage's ms per frame on every device of the cell, joined by ` / `.
fn stage_table(cells: &[serde_json::Value]) -> String {
    let ok: Vec<&serde_json::Value> = cells.iter().filter(|c| c["ok"] == true).collect();
    let rows = |c: &serde_json::Value| c["stages"].as_array().cloned().unwrap_or_default();
    let mut stages: Vec<String> = Vec::new();
    for row in ok.iter().flat_map(|c| rows(c)) {
        if let Some(stage) = row["stage"].as_str()
            && !stages.iter().any(|s| s == stage)
        {
            stages.push(stage.to_string());
        }
    }
    let mut out = String::from("| stage |");
    for c in &ok {
        out.push_str(&format!(" {} |", c["id"].as_str().unwrap_or("")));
    }
    out.push_str(&format!("\n|---|{}\n", "---:|".repeat(ok.len())));
    for stage in &stages {
        out.push_str(&format!("| {stage} |"));
        for c in &ok {
            let of_stage: Vec<serde_json::Value> =
                rows(c).into_iter().filter(|r| r["stage"] == stage.as_str()).collect();
            if of_stage.is_empty() {
                out.push_str(" – |");
                continue;
            }
            let devices = c["busy_fraction"].as_array().map_or(0, Vec::len);
            let per_device: Vec<String> = (0..devices)
                .map(|d| of_stage.iter().find(|r| r["device"] == d).map_or("–".into(), |r| num(&r["mean_ms"], 3)))
                .collect();
            out.push_str(&format!(" {} |", per_device.join(" / ")));
        }
        out.push('\n');
    }
    out.push_str("| frame (GPU span, mean) |");
    for c in &ok {
        out.push_str(&format!(" {} |", num(&c["frame_ms"]["mean_ms"], 3)));
    }
    out.push('\n');
    out
}

/// The text of a string field, or `–`.
fn text(v: &serde_json::Value) -> &str {
    v.as_str().unwrap_or("–")
}

/// The paper's Tables 2 and 5: for each setting of the other axes (pipeline, sources per set,
/// spp, denoise, devices), one row per scheme and assignment and one column per case, each
/// entry the mean frame ms.
fn scheme_table(cells: &[serde_json::Value]) -> String {
    let ok: Vec<&serde_json::Value> = cells.iter().filter(|c| c["ok"] == true).collect();
    let mut cases: Vec<&str> = Vec::new();
    for c in &ok {
        if !cases.contains(&text(&c["case"])) {
            cases.push(text(&c["case"]));
        }
    }
    let setting = |c: &serde_json::Value| {
        format!(
            "{}, K = {}, {} spp, SVGF {}, {} device(s)",
            text(&c["pipeline"]),
            c["sources_per_set"],
            c["spp"],
            match c["denoiser"].as_str() {
                Some(name) => name,
                None if c["denoise"] == true => "on",
                None => "off",
            },
            c["devices"]
        )
    };
    let method = |c: &serde_json::Value| match c["assignment"].as_str() {
        Some(a) => format!("{}, {a}", text(&c["scheme"])),
        None => text(&c["scheme"]).to_string(),
    };
    let mut groups: BTreeMap<String, BTreeMap<String, BTreeMap<&str, f64>>> = BTreeMap::new();
    for c in &ok {
        if let Some(ms) = c["frame_ms"]["mean_ms"].as_f64() {
            groups.entry(setting(c)).or_default().entry(method(c)).or_default().insert(text(&c["case"]), ms);
        }
    }
    let mut out = String::new();
    for (setting, methods) in &groups {
        out.push_str(&format!(
            "{setting}:\n\n| scheme, assignment | {} |\n|---|{}\n",
            cases.join(" | "),
            "---:|".repeat(cases.len())
        ));
        for (method, by_case) in methods {
            let row: Vec<String> =
                cases.iter().map(|case| by_case.get(case).map_or("–".into(), |ms| format!("{ms:.2}"))).collect();
            out.push_str(&format!("| {method} | {} |\n", row.join(" | ")));
        }
        out.push('\n');
    }
    out
}

/// One row per cell that has a twin with fewer devices (the same cell but for its device
/// count): frame ms, speed-up and parallel efficiency T₁·N₁ / (N·T_N) against the twin with
/// the fewest devices, and the gather (display images to device 0) as a share of the frame.
fn scaling_table(cells: &[serde_json::Value]) -> String {
    let ok: Vec<&serde_json::Value> = cells.iter().filter(|c| c["ok"] == true).collect();
    // The id without its `_dN` suffix names the cell across device counts.
    let family = |c: &serde_json::Value| {
        let id = text(&c["id"]);
        id.rsplit_once("_d").map_or(id, |(head, _)| head).to_string()
    };
    let mut families: BTreeMap<String, Vec<&serde_json::Value>> = BTreeMap::new();
    for c in &ok {
        families.entry(family(c)).or_default().push(c);
    }
    let mut out = String::from(
        "| cell | devices | frame ms | speed-up | parallel efficiency | gather ms | gather share |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for (name, mut members) in families {
        if members.len() < 2 {
            continue;
        }
        members.sort_by_key(|c| c["devices"].as_u64());
        let (Some(n1), Some(t1)) = (members[0]["devices"].as_f64(), members[0]["frame_ms"]["mean_ms"].as_f64()) else {
            continue;
        };
        for c in members {
            let (Some(n), Some(t)) = (c["devices"].as_f64(), c["frame_ms"]["mean_ms"].as_f64()) else { continue };
            let gather = c["gather_ms"].as_f64();
            out.push_str(&format!(
                "| {name} | {n} | {t:.2} | {:.2}× | {:.3} | {} | {} |\n",
                t1 / t,
                t1 * n1 / (n * t),
                gather.map_or("–".into(), |g| format!("{g:.2}")),
                gather.map_or("–".into(), |g| format!("{:.1} %", 100.0 * g / t)),
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(id: &str, case: &str, scheme: &str, devices: u32, ms: f64, gather: f64) -> serde_json::Value {
        serde_json::json!({ "ok": true, "id": id, "case": case, "pipeline": "reproject", "scheme": scheme,
                            "assignment": null, "sources_per_set": 1, "spp": 1, "denoise": true,
                            "devices": devices, "frame_ms": { "mean_ms": ms }, "gather_ms": gather })
    }

    #[test]
    fn scaling_gives_speed_up_and_efficiency_against_the_fewest_devices() {
        let cells = [
            cell("a/reproject_multi-source_k1_spp1_dnon_d1", "a", "multi-source", 1, 100.0, 0.0),
            cell("a/reproject_multi-source_k1_spp1_dnon_d4", "a", "multi-source", 4, 40.0, 4.0),
            cell("a/reproject_fine-all_k1_spp1_dnon_d4", "a", "fine-all", 4, 60.0, 6.0),
        ];
        let md = scaling_table(&cells);
        assert!(
            md.contains("| a/reproject_multi-source_k1_spp1_dnon | 4 | 40.00 | 2.50× | 0.625 | 4.00 | 10.0 % |"),
            "{md}"
        );
        assert!(md.contains("| 1 | 100.00 | 1.00× | 1.000 |"), "{md}");
        assert!(!md.contains("fine-all"), "a cell without a twin has no row: {md}");
    }

    #[test]
    fn schemes_are_rows_and_cases_columns_per_setting() {
        let cells = [
            cell("a/x_d4", "a", "multi-source", 4, 40.0, 0.0),
            cell("b/x_d4", "b", "multi-source", 4, 80.0, 0.0),
            cell("a/y_d4", "a", "fine-all", 4, 60.0, 0.0),
        ];
        let md = scheme_table(&cells);
        assert!(md.contains("| scheme, assignment | a | b |"), "{md}");
        assert!(md.contains("| multi-source | 40.00 | 80.00 |"), "{md}");
        assert!(md.contains("| fine-all | 60.00 | – |"), "{md}");
    }
}
