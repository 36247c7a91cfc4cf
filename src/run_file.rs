//! `render --config FILE`: a run given back. The file is a render.json (its `run` object, which
//! render writes with every setting by its long flag name, typed) or a TOML run file with the
//! same keys (`spp = 4`, `lf = "8x4"`, `still = true`, `camera = [0, 1, 4, 0, 1, 0, 0, 1, 0, 45]`).
//! Each key becomes its flag (`sources_per_set` → `--sources-per-set`; `true` a bare flag,
//! `false` and null none, an array its values joined by commas) and the words are parsed by
//! render's own parser, so a run file is checked exactly as a command line is; flags given on
//! the command line as well come after the file's and win.

use std::ffi::OsString;
use std::path::Path;

use anyhow::{Context as _, Result, bail};
use clap::{Args as _, FromArgMatches as _};
use parallax_graph::LayoutSpec;

use crate::cmd_render::RenderArgs;
use crate::options::UsageError;

/// `--lf` as a person writes it.
pub fn layout_spelling(spec: &LayoutSpec) -> String {
    match spec {
        LayoutSpec::Multiscopic => "multiscopic".into(),
        LayoutSpec::Nelf => "nelf".into(),
        LayoutSpec::Grid { cols, rows } => format!("{cols}x{rows}"),
    }
}

/// The settings table of a run file: render.json's `run`, or a TOML file's top level.
fn table_of(path: &Path) -> Result<serde_json::Map<String, serde_json::Value>> {
    let shown = path.display();
    let text = std::fs::read_to_string(path).with_context(|| format!("--config {shown}: cannot read the file"))?;
    let is_toml = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let value: serde_json::Value = if is_toml {
        toml::from_str(&text).with_context(|| format!("--config {shown}: not TOML"))?
    } else {
        serde_json::from_str(&text)
            .with_context(|| format!("--config {shown}: not JSON (a TOML run file ends in .toml)"))?
    };
    let table = value.get("run").unwrap_or(&value);
    match table.as_object() {
        Some(t) => Ok(t.clone()),
        None => bail!("--config {shown}: expected a table of settings (render.json's `run`, or TOML keys)"),
    }
}

/// The command-line words of a run file's settings; `origin` (`--config FILE`) begins each
/// error message.
pub fn words_of(origin: &str, table: &serde_json::Map<String, serde_json::Value>) -> Result<Vec<String>> {
    let mut words = Vec::new();
    for (key, value) in table {
        if key == "config" {
            bail!("{origin}: a run file cannot name another (`config`)");
        }
        let flag = format!("--{}", key.replace('_', "-"));
        let scalar = |v: &serde_json::Value| match v {
            serde_json::Value::String(s) => Some(s.clone()),
            serde_json::Value::Number(n) => Some(n.to_string()),
            _ => None,
        };
        match value {
            serde_json::Value::Null | serde_json::Value::Bool(false) => {}
            serde_json::Value::Bool(true) => words.push(flag),
            serde_json::Value::Array(items) => {
                let parts: Option<Vec<String>> = items.iter().map(scalar).collect();
                let Some(parts) = parts else {
                    bail!("{origin}: `{key}` must list numbers or strings");
                };
                words.extend([flag, parts.join(",")]);
            }
            serde_json::Value::Object(_) => bail!("{origin}: `{key}` is a table, not a setting"),
            v => words.extend([flag, scalar(v).expect("a string or number")]),
        }
    }
    Ok(words)
}

/// The words after `render` on a command line (`invocation`, the program's name first), less
/// `--config FILE` and the global `-q`/`-v`, which are not render's.
fn command_line_words(invocation: impl IntoIterator<Item = OsString>) -> Vec<OsString> {
    let global = |w: &OsString| {
        let w = w.to_string_lossy();
        w == "--quiet"
            || w == "--verbose"
            || (w.len() > 1 && w.starts_with('-') && w[1..].chars().all(|c| c == 'v' || c == 'q'))
    };
    let mut words: Vec<OsString> =
        invocation.into_iter().skip_while(|a| a != "render").skip(1).filter(|w| !global(w)).collect();
    while let Some(at) = words.iter().position(|w| w == "--config" || w.to_string_lossy().starts_with("--config=")) {
        let with_value = words[at] == "--config";
        words.drain(at..(at + if with_value { 2 } else { 1 }).min(words.len()));
    }
    words
}

/// `render`'s arguments from the run file `path`, then the flags of the command line
/// `invocation` (the program's name first, as `std::env::args_os()` gives it).
pub fn render_args_of(path: &Path, invocation: impl IntoIterator<Item = OsString>) -> Result<RenderArgs> {
    let words = words_of(&format!("--config {}", path.display()), &table_of(path)?)?;
    let command = RenderArgs::augment_args(clap::Command::new("render").no_binary_name(true)).args_override_self(true);
    let all: Vec<OsString> = words.into_iter().map(OsString::from).chain(command_line_words(invocation)).collect();
    let matches = command.try_get_matches_from(&all).map_err(|e| {
        let text = e.to_string();
        let line = text.lines().next().unwrap_or("").trim_start_matches("error: ").to_string();
        UsageError(format!("--config {}: {line}", path.display()))
    })?;
    Ok(RenderArgs::from_arg_matches(&matches)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_become_flags() {
        let table = serde_json::json!({
            "spp": 4, "lf": "8x4", "still": true, "layers": false, "focus": null, "sources_per_set": 2,
            "camera": [0, 1, 4.5, 0, 1, 0, 0, 1, 0, 45],
        });
        let words = words_of("--config r.toml", table.as_object().unwrap()).unwrap();
        assert_eq!(
            words,
            ["--camera", "0,1,4.5,0,1,0,0,1,0,45", "--lf", "8x4", "--sources-per-set", "2", "--spp", "4", "--still"]
        );
        let nested = serde_json::json!({ "plan": { "views": 2 } });
        assert!(
            words_of("--config r", nested.as_object().unwrap()).unwrap_err().to_string().contains("`plan` is a table")
        );
        let again = serde_json::json!({ "config": "other.toml" });
        assert!(words_of("--config r", again.as_object().unwrap()).is_err());
    }

    #[test]
    fn the_command_line_given_wins_not_the_process_s() {
        let invocation = ["parallax", "-q", "render", "--config", "r.toml", "--spp", "4", "-v", "--still"];
        assert_eq!(command_line_words(invocation.map(OsString::from)), ["--spp", "4", "--still"]);
        assert!(command_line_words(["parallax", "plan"].map(OsString::from)).is_empty());
    }

    #[test]
    fn layouts_are_spelt_as_typed() {
        assert_eq!(layout_spelling(&LayoutSpec::Grid { cols: 8, rows: 4 }), "8x4");
    }
}
