//! `render --config FILE`: a run given back. The file is a render.json (its `run` object, which
//! render writes with every setting by its long flag name, typed) or a TOML run file with the
//! same keys (`spp = 4`, `lf = "8x4"`, `still = true`, `camera = [0, 1, 4, 0, 1, 0, 0, 1, 0, 45]`).
//! Each key becomes its flag (`sources_per_set` → `--sources-per-set`; `true` a bare flag,
//! `false` and null none, an array its values joined by commas) and the words are parsed by
//! render's own parser, so a run file is checked exactly as a command line is; flags given on
//! the command line as well come after the file's and win.
//!
//! The file is read as every input is (a regular file of at most 256 MiB, see
//! `parallax_scene::input`). A TOML float that is not finite (`spp = nan`, `spacing = -inf`)
//! reaches the flag's parser as the word `nan` or `-inf`, which refuses it naming the flag and
//! its range as it refuses `--spp nan`: converted to JSON it would become null, and so no flag
//! at all.

use std::ffi::OsString;
use std::path::Path;

use anyhow::{Context as _, Result, bail};
use parallax_graph::LayoutSpec;

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
    let text = parallax_scene::input::read_text(path, "run file")
        .map_err(|e| crate::options::input_error("--config", path, e))?;
    let is_toml = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let value: serde_json::Value = if is_toml {
        let table: toml::Table =
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("--config {shown}: {}", toml_error_line(&text, &e)))?;
        json_of_toml(toml::Value::Table(table))
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

/// A TOML error in one line, `not TOML (line L, column C): what`: the error's own text spans
/// several lines (the source line and a caret).
fn toml_error_line(text: &str, error: &toml::de::Error) -> String {
    match error.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map_or(0, |at| at + 1) + 1;
            format!("not TOML (line {line}, column {column}): {}", error.message())
        }
        None => format!("not TOML: {}", error.message()),
    }
}

/// `value` as JSON, a float that is not finite as its word (`nan`, `inf`, `-inf`): JSON has no
/// such number, and serde's conversion would make it null, silently dropping the setting.
fn json_of_toml(value: toml::Value) -> serde_json::Value {
    use serde_json::Value as J;
    match value {
        toml::Value::String(s) => J::String(s),
        toml::Value::Integer(i) => J::from(i),
        toml::Value::Float(f) => serde_json::Number::from_f64(f).map_or_else(|| J::String(f.to_string()), J::Number),
        toml::Value::Boolean(b) => J::Bool(b),
        toml::Value::Datetime(d) => J::String(d.to_string()),
        toml::Value::Array(items) => J::Array(items.into_iter().map(json_of_toml).collect()),
        toml::Value::Table(table) => J::Object(table.into_iter().map(|(k, v)| (k, json_of_toml(v))).collect()),
    }
}

/// The command-line words of a run file's settings, `--flag=value` so that a value that starts
/// with `-` (`-inf`, `-1`) is never taken for a flag; `origin` (`--config FILE`) begins each
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
                words.push(format!("{flag}={}", parts.join(",")));
            }
            serde_json::Value::Object(_) => bail!("{origin}: `{key}` is a table, not a setting"),
            v => words.push(format!("{flag}={}", scalar(v).expect("a string or number"))),
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

/// The words `render` parses for the run file `path`: the file's settings as flags, then the
/// flags of the command line `invocation` (the program's name first, as `std::env::args_os()`
/// gives it), so that those win.
pub fn render_words(path: &Path, invocation: impl IntoIterator<Item = OsString>) -> Result<Vec<OsString>> {
    let words = words_of(&format!("--config {}", path.display()), &table_of(path)?)?;
    Ok(words.into_iter().map(OsString::from).chain(command_line_words(invocation)).collect())
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
        assert_eq!(words, ["--camera=0,1,4.5,0,1,0,0,1,0,45", "--lf=8x4", "--sources-per-set=2", "--spp=4", "--still"]);
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
